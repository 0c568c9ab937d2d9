"""The batched omni renderer against MuJoCo's: same pixels (nearly), same segmentation, same
detections; own body hidden; LED colour followed; errors as ``OmniRenderer``'s. (Its views
kernel against the numpy reference, and the images of either backend: ``test_kernel_parity.py``.)

Both renderers really render (EGL, off-screen) the same world states, one after the other in one
process (two GL contexts), which also checks that each makes its own context current.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import mujoco
import numpy as np
import pytest

from cyber_rodent.render import FieldRenderer
from cyber_rodent.vision import FACE, LED, CameraConfig
from cyber_rodent.vision.agreement import random_scene
from cyber_rodent.vision.batch_rendering import BatchOmniRenderer, build_geometry, geom_mesh
from cyber_rodent.vision.rendering import OmniRenderer
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import target_geometry
from cyber_rodent.world import World, WorldConfig

SEEDS = [0, 1, 2, 3, 4, 5]
MIN_MASK_PX = 50  # masks compared by IoU when either renderer has at least this many pixels
MIN_IOU = 0.9
BEARING_TOL_DEG = 1.0
# Distances come from a blob's top and bottom rows: where an edge passes through a pixel centre
# the two renderers may round it to different rows (float rounding), which moves a small distant
# blob's distance by several per cent (one row of a face at 0.85 m: ~5 %). So: within 3 % for
# blobs of DISTANCE_MIN_AREA pixels or more and for most blobs, within 15 % for every blob.
DISTANCE_RTOL = 0.03
DISTANCE_MIN_AREA = 100
DISTANCE_RTOL_ANY = 0.15
MIN_FRACTION_WITHIN_RTOL = 0.9


@pytest.fixture(scope="module")
def world() -> World:
    return World(WorldConfig(n_robots=4, n_packs=5), np.random.default_rng(0))


@pytest.fixture(scope="module")
def renderers(world: World) -> Iterator[tuple[OmniRenderer, BatchOmniRenderer]]:
    config = CameraConfig()
    with OmniRenderer(world, config) as mj, BatchOmniRenderer(world, config) as batch:
        yield mj, batch


@pytest.fixture(scope="module")
def segmenter(world: World) -> OmniSegmenter:
    return OmniSegmenter(CameraConfig(), target_geometry(world))


def _scene(world: World, seed: int) -> None:
    """Random placement and headings, each LED on with probability 1/2."""
    random_scene(world, np.random.default_rng([7, seed]))
    mujoco.mj_forward(world.model, world.data)


def _both(renderers) -> tuple[np.ndarray, np.ndarray]:
    mj, batch = renderers
    return mj.render().copy(), batch.render().copy()


def _match(a: np.ndarray, b: np.ndarray) -> list[tuple[int, int]]:
    """Greedy one-to-one matching of two lists of bearings, nearest (circularly) first."""
    pairs = sorted(
        (abs(math.remainder(x - y, 2 * math.pi)), i, j)
        for i, x in enumerate(a)
        for j, y in enumerate(b)
    )
    used_a, used_b, out = set(), set(), []
    for _, i, j in pairs:
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            out.append((i, j))
    return out


def _assert_detections_agree(segmenter: OmniSegmenter, ref: np.ndarray, new: np.ndarray) -> None:
    robot_a, cls_a, bearing_a, dist_a, area_a, masks_a = segmenter.detect(ref)
    robot_b, cls_b, bearing_b, dist_b, _, masks_b = segmenter.detect(new)
    n_robots = ref.shape[0]
    errors = []
    for c in range(masks_a.shape[0]):
        for i in range(n_robots):
            x, y = masks_a[c, i] > 0, masks_b[c, i] > 0
            if max(x.sum(), y.sum()) >= MIN_MASK_PX:
                iou = (x & y).sum() / (x | y).sum()
                assert iou >= MIN_IOU, (c, i, iou)
            a = (robot_a == i) & (cls_a == c)
            b = (robot_b == i) & (cls_b == c)
            assert a.sum() == b.sum(), (c, i, area_a[a])
            for p, q in _match(bearing_a[a], bearing_b[b]):
                turn = math.remainder(bearing_a[a][p] - bearing_b[b][q], 2 * math.pi)
                assert abs(math.degrees(turn)) <= BEARING_TOL_DEG, (c, i, turn)
                err = abs(dist_b[b][q] - dist_a[a][p]) / dist_a[a][p]
                assert err <= DISTANCE_RTOL_ANY, (c, i, err)
                if area_a[a][p] >= DISTANCE_MIN_AREA:
                    assert err <= DISTANCE_RTOL, (c, i, err, area_a[a][p])
                errors.append(err)
    if errors:
        assert np.mean(np.array(errors) <= DISTANCE_RTOL) >= MIN_FRACTION_WITHIN_RTOL


# --- output and agreement with MuJoCo's renderer ----------------------------------------------
def test_output_has_omni_renderers_shape_and_layout(world, renderers) -> None:
    _scene(world, 0)
    mj, batch = renderers
    out = batch.render()
    assert out.shape == (4, 192, 512, 3) and out.dtype == np.uint8
    assert out.flags.c_contiguous
    assert batch.projection.config == mj.projection.config
    # Row 0 is the top of each strip: the sky (black) above the walls, the floor at the bottom.
    ref = mj.render()
    np.testing.assert_array_equal(out[:, 0], ref[:, 0])
    np.testing.assert_array_equal(out[:, -1], ref[:, -1])


@pytest.mark.parametrize("seed", SEEDS)
def test_pixels_match_mujocos_renderer(world, renderers, seed: int) -> None:
    # Same geometry, cameras and lighting: nearly every pixel is identical; the rest are single
    # pixels on outlines (rasterisation ties, coarser meshes of small distant geoms).
    _scene(world, seed)
    ref, new = _both(renderers)
    diff = np.abs(ref.astype(int) - new).max(axis=-1)
    assert (diff == 0).mean() >= 0.995
    assert (diff > 8).mean() <= 0.001


@pytest.mark.parametrize("seed", SEEDS)
def test_colour_masks_and_detections_match_mujocos_renderer(
    world, renderers, segmenter, seed: int
) -> None:
    _scene(world, seed)
    ref, new = _both(renderers)
    _assert_detections_agree(segmenter, ref, new)


def test_close_range_scene_matches(world, renderers, segmenter) -> None:
    # Nose to nose, side by side, a pack touching a robot: the nearest, finest geometry.
    robots = [(-0.2, 0.0, 0.0), (0.2, 0.0, math.pi), (-0.2, 0.3, 0.0), (0.45, 0.35, 2.0)]
    packs = [(-0.2, -0.17), (0.9, 0.9), (-0.9, 0.9), (0.9, -0.9), (-0.9, -0.9)]
    for i, (x, y, yaw) in enumerate(robots):
        world.set_robot_pose(i, x, y, yaw)
    for j, (x, y) in enumerate(packs):
        world.set_pack_position(j, x, y)
    world.set_led(np.array([True, True, False, True]))
    mujoco.mj_forward(world.model, world.data)
    ref, new = _both(renderers)
    assert (np.abs(ref.astype(int) - new).max(axis=-1) > 8).mean() <= 0.001
    _assert_detections_agree(segmenter, ref, new)


def test_tilted_robots_match(world, renderers) -> None:
    # The views follow the camera site's frame (up = its z axis) and the headlight each view,
    # so the floor's shade changes from view to view; both renderers agree.
    _scene(world, 1)
    world.set_led(True)
    for i, (roll, pitch) in enumerate([(0.35, 0.0), (0.0, -0.3), (0.2, 0.25), (1.2, 0.0)]):
        a = int(world.root_qpos_adr[i])
        tilt = np.zeros(4)
        mujoco.mju_euler2Quat(tilt, np.array([roll, pitch, 0.0]), "xyz")
        quat = np.zeros(4)
        mujoco.mju_mulQuat(quat, world.data.qpos[a + 3 : a + 7].copy(), tilt)
        world.data.qpos[a + 3 : a + 7] = quat
        world.data.qpos[a + 2] = 0.1
    mujoco.mj_forward(world.model, world.data)
    ref, new = _both(renderers)
    diff = np.abs(ref.astype(int) - new).max(axis=-1)
    assert (diff == 0).mean() >= 0.995
    assert (diff > 8).mean() <= 0.001


# --- own body, LED, other renderers in the process ----------------------------------------------
@pytest.fixture(scope="module")
def pair() -> Iterator[tuple[World, BatchOmniRenderer, OmniSegmenter]]:
    world = World(WorldConfig(n_robots=2, n_packs=0), np.random.default_rng(0))
    config = CameraConfig()
    with BatchOmniRenderer(world, config) as batch:
        yield world, batch, OmniSegmenter(config, target_geometry(world))


def _place_pair(world: World, led0: bool) -> None:
    # Robot 0 (LED led0) faces robot 1, 0.6 m ahead; robot 1 (LED off) faces away: robot 0
    # sees neither red (robot 1's face is on its far side) nor green.
    world.set_robot_pose(0, -0.3, 0.0, 0.0)
    world.set_robot_pose(1, 0.3, 0.0, 0.0)
    world.set_led(np.array([led0, False]))
    mujoco.mj_forward(world.model, world.data)


def test_a_robot_never_sees_its_own_face_or_led(pair) -> None:
    world, batch, segmenter = pair
    _place_pair(world, led0=True)
    masks = segmenter.masks(batch.render().reshape(-1, 512, 3)).reshape(3, 2, 192, 512)
    # Robot 0's face and lit LED are rendered: robot 1 sees them behind it ...
    assert masks[LED, 1].any() and masks[FACE, 1].any()
    # ... but robot 0, whose own body is all around and below its camera, does not.
    assert not masks[LED, 0].any() and not masks[FACE, 0].any()


def test_a_robot_never_sees_any_of_its_own_geoms(pair) -> None:
    # Its own face is below its chassis' top edge and its LED below the field of view anyway;
    # the chassis edge, wheels and camera post would be in view. Paint all of robot 0 face-red.
    world, batch, segmenter = pair
    _place_pair(world, led0=False)
    m = world.model
    own = world.geom_robot == 0
    saved = m.geom_rgba[own].copy()
    m.geom_rgba[own] = (0.9, 0.05, 0.05, 1.0)
    try:
        masks = segmenter.masks(batch.render().reshape(-1, 512, 3)).reshape(3, 2, 192, 512)
    finally:
        m.geom_rgba[own] = saved
    assert np.count_nonzero(masks[FACE, 1]) > 200  # robot 1 sees a red robot behind it
    assert not masks[FACE, 0].any()


def test_a_robot_alone_sees_no_red_or_green() -> None:
    world = World(WorldConfig(n_robots=1, n_packs=0), np.random.default_rng(0))
    config = CameraConfig()
    segmenter = OmniSegmenter(config, target_geometry(world))
    world.set_led(True)
    with BatchOmniRenderer(world, config) as batch:
        for deg in (0, 37, 90, 200):
            world.set_robot_pose(0, 0.1, -0.2, math.radians(deg))
            mujoco.mj_forward(world.model, world.data)
            strip = batch.render()
            masks = segmenter.masks(strip[0])
            assert not masks[LED].any() and not masks[FACE].any()
            assert strip.std() > 5  # the field is there


def test_led_toggle_changes_the_green_mask(pair) -> None:
    world, batch, segmenter = pair
    seen = []
    for on in (False, True, False, True):
        _place_pair(world, led0=on)
        masks = segmenter.masks(batch.render()[1])
        seen.append(int(np.count_nonzero(masks[LED])))
    assert seen[0] == seen[2] == 0
    assert seen[1] == seen[3] >= 8  # a 4.4 x 1.4 cm ring 0.6 m away: ~5 x 3 px


def test_other_renderers_in_the_process_do_not_disturb_it(pair) -> None:
    world, batch, _ = pair
    _place_pair(world, led0=True)
    first = batch.render().copy()
    video = FieldRenderer(world, 160, 120)
    try:
        video.top_down()
        np.testing.assert_array_equal(batch.render(), first)
        video.top_down()
    finally:
        video.close()
    np.testing.assert_array_equal(batch.render(), first)


# --- errors ------------------------------------------------------------------------------------
def test_closed_renderer_raises() -> None:
    world = World(WorldConfig(n_robots=1, n_packs=1), np.random.default_rng(0))
    with BatchOmniRenderer(world, CameraConfig()) as batch:
        batch.render()
    with pytest.raises(RuntimeError, match="closed"):
        batch.render()
    batch.close()  # idempotent


def test_too_large_a_buffer_raises_value_error() -> None:
    world = World(WorldConfig(n_robots=5, n_packs=0), np.random.default_rng(0))
    with pytest.raises(ValueError, match="exceed"):
        BatchOmniRenderer(world, CameraConfig(height=4096))


def test_unsupported_geom_types_raise() -> None:
    for gtype in (mujoco.mjtGeom.mjGEOM_MESH, mujoco.mjtGeom.mjGEOM_HFIELD):
        with pytest.raises(ValueError, match="cannot draw"):
            geom_mesh(int(gtype), np.array([0.1, 0.1, 0.1]), 16, 4)


# --- meshes and backends -----------------------------------------------------------------------
SHAPES_XML = """
<mujoco>
  <worldbody>
    <geom name="plane" type="plane" size="1 2 0.1"/>
    <geom name="sphere" type="sphere" size="0.1" pos="0 0 1"/>
    <geom name="capsule" type="capsule" size="0.05 0.2" pos="1 0 1"/>
    <geom name="ellipsoid" type="ellipsoid" size="0.1 0.2 0.3" pos="0 1 1"/>
    <geom name="cylinder" type="cylinder" size="0.1 0.3" pos="1 1 1"/>
    <geom name="box" type="box" size="0.1 0.2 0.3" pos="2 1 1"/>
    <geom name="hidden" type="sphere" size="0.1" group="3"/>
  </worldbody>
</mujoco>
"""


def test_meshes_are_closed_outward_and_of_the_right_volume() -> None:
    model = mujoco.MjModel.from_xml_string(SHAPES_XML)
    geo = build_geometry(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) for g in geo.geoms]
    assert sorted(names) == ["box", "capsule", "cylinder", "ellipsoid", "plane", "sphere"]
    volume = {
        "sphere": 4 / 3 * math.pi * 0.1**3,
        "capsule": math.pi * 0.05**2 * 0.4 + 4 / 3 * math.pi * 0.05**3,
        "ellipsoid": 4 / 3 * math.pi * 0.1 * 0.2 * 0.3,
        "cylinder": math.pi * 0.1**2 * 0.6,
        "box": 0.2 * 0.4 * 0.6,
    }
    pos = geo.vertices[:, :3].astype(float)
    for j, name in enumerate(names):
        assert np.all(
            geo.vertices[geo.indices[geo.index_start[0, j] : geo.index_start[0, j + 1]], 3]
            == geo.geoms[j]
        )
        assert geo.same_at_all_levels[j] == (name in ("box", "plane"))
        for level in range(geo.index_start.shape[0]):
            tri = pos[geo.indices[geo.index_start[level, j] : geo.index_start[level, j + 1]]]
            tri = tri.reshape(-1, 3, 3)
            if name == "plane":  # rbound 0 (MuJoCo's "infinite"); one quad facing +z
                normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
                assert len(tri) == 2 and normal[:, 2].min() > 0
                continue
            # Inside the bounding sphere; signed volume (divergence theorem) positive.
            assert np.linalg.norm(tri, axis=-1).max() <= model.geom_rbound[geo.geoms[j]] + 1e-6
            signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
            # Inscribed polyhedra: smaller, coarser levels more (an octahedron: 0.32 of a sphere).
            assert 0.3 * volume[name] < signed <= volume[name] * (1 + 1e-6), (name, level)
            if level == 0:
                assert signed >= 0.75 * volume[name], name


def test_unknown_backend_is_refused(world) -> None:
    with pytest.raises(ValueError, match="backend must be one of numba, numpy"):
        BatchOmniRenderer(world, CameraConfig(), backend="gpu")  # type: ignore[arg-type]


def test_rendered_vision_picks_its_renderer() -> None:
    """RenderedVision renders with the batch renderer under EGL (the default), with MuJoCo's on
    request, passes its backend to the renderer and the segmenter, and names the allowed
    renderers for anything else."""
    from cyber_rodent.vision.rendered import RenderedVision

    world = World(WorldConfig(n_robots=2, n_packs=1))
    with RenderedVision(world) as vision:
        assert isinstance(vision.renderer, BatchOmniRenderer)
    with RenderedVision(world, renderer="mujoco") as vision:
        assert isinstance(vision.renderer, OmniRenderer)
    with RenderedVision(world, backend="numpy") as vision:
        assert isinstance(vision.renderer, BatchOmniRenderer)
        assert vision.renderer.backend == vision.segmenter.backend == "numpy"
    with pytest.raises(ValueError, match="renderer must be one of auto, batch, mujoco"):
        RenderedVision(world, renderer="vulkan")
