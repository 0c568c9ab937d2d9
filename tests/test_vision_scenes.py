"""Both providers on hand-placed scenes, their agreement on random scenes, and the snapshot.

The rendered provider really renders (EGL, off-screen) and segments; the geometric provider
ray-casts. Each scene states what both must see.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import cv2
import mujoco
import numpy as np
import pytest

from cyber_rodent.vision import (
    BATTERY,
    FACE,
    LED,
    CameraConfig,
    VisionFrame,
    make_provider,
    save_omni_png,
)
from cyber_rodent.vision.agreement import compare_scene, random_scene, summarise
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.snapshot import compose_omni_panels, place_strip_labels
from cyber_rodent.vision.targets import target_geometry
from cyber_rodent.world import World, WorldConfig

BEARING_TOL = math.radians(3.0)


def _place(world: World, robots, packs, leds=False) -> None:
    for i, (x, y, yaw) in enumerate(robots):
        world.set_robot_pose(i, x, y, yaw)
    for j, (x, y) in enumerate(packs):
        world.set_pack_position(j, x, y)
    world.set_led(leds)
    mujoco.mj_forward(world.model, world.data)


@pytest.fixture(scope="module")
def world() -> World:
    return World(WorldConfig(n_robots=2, n_packs=2))


@pytest.fixture(scope="module")
def providers(world: World) -> Iterator[tuple[GeometricVision, RenderedVision]]:
    geo = make_provider("geometric", world)
    ren = make_provider("rendered", world)
    yield geo, ren
    ren.close()


def _blobs_near(frame: VisionFrame, robot: int, cls: int, bearing: float, tol: float):
    return [
        b
        for b in frame.blobs[robot]
        if b.cls == cls and abs(math.remainder(b.bearing - bearing, 2 * math.pi)) <= tol
    ]


def test_pack_straight_ahead_at_half_a_metre(world, providers) -> None:
    # Robot 0 at (-0.5, 0) facing +x; pack 0 at the origin. Robot 1 and pack 1 far to the side.
    _place(world, [(-0.5, 0.0, 0.0), (-0.9, 0.9, math.pi)], [(0.0, 0.0), (0.9, -0.9)])
    for provider in providers:
        f = provider.observe()
        assert f.visible[0, BATTERY], type(provider).__name__
        assert abs(f.bearing[0, BATTERY]) <= BEARING_TOL, type(provider).__name__
        assert f.distance[0, BATTERY] == pytest.approx(0.5, rel=0.1), type(provider).__name__


def test_pack_straight_ahead_at_every_heading_of_the_strip(world, providers) -> None:
    # The same pack seen through each view and across view seams: heading -180°..165°.
    geo, ren = providers
    for deg in range(-180, 180, 15):
        yaw = math.radians(deg)
        x, y = -0.5 * math.cos(yaw), -0.5 * math.sin(yaw)  # pack at the origin, 0.5 m ahead
        # Pack 1 0.5 m behind the robot, so it never lines up with pack 0.
        _place(world, [(x, y, yaw), (-0.9, 0.9, 0.0)], [(0.0, 0.0), (2 * x, 2 * y)])
        for provider in (geo, ren):
            near = _blobs_near(provider.observe(), 0, BATTERY, 0.0, BEARING_TOL)
            assert len(near) == 1, (deg, type(provider).__name__)
            assert near[0].distance == pytest.approx(0.5, rel=0.1), deg


def test_pack_hidden_behind_another_robot_is_not_seen(world, providers) -> None:
    # Observer at (-1, 0) facing +x; robot 1 0.3 m ahead, side-on; pack 0 1.95 m ahead, on the
    # same line. Every line of sight to the pack passes robot 1's camera column (post, LED
    # ring, mirror: 2.4-4.4 cm wide, up to 18.3 cm high) at 14-16 cm height, where the pack
    # (8 cm wide at 1.95 m) looks narrower than the column: it is completely hidden.
    pack1_away = (-0.9, 1.0)
    _place(world, [(-1.0, 0.0, 0.0), (-0.7, 0.0, math.pi / 2)], [(0.95, 0.0), pack1_away])
    for provider in providers:
        f = provider.observe()
        assert not _blobs_near(f, 0, BATTERY, 0.0, math.radians(10)), type(provider).__name__
    # Control: robot 1 steps aside, and both see the pack straight ahead at 1.95 m.
    _place(world, [(-1.0, 0.0, 0.0), (-0.7, 0.4, math.pi / 2)], [(0.95, 0.0), pack1_away])
    for provider in providers:
        near = _blobs_near(provider.observe(), 0, BATTERY, 0.0, BEARING_TOL)
        assert len(near) == 1, type(provider).__name__
        assert near[0].distance == pytest.approx(1.95, rel=0.1)


def test_toggling_another_robots_led_makes_green_appear_and_disappear(world, providers) -> None:
    # Robot 1 0.6 m ahead of robot 0, facing it.
    robots = [(-0.3, 0.0, 0.0), (0.3, 0.0, math.pi)]
    packs = [(0.9, 0.9), (0.9, -0.9)]
    for leds, seen in (
        ([False, False], False),
        ([False, True], True),
        ([False, False], False),
        ([True, True], True),
    ):
        _place(world, robots, packs, np.array(leds))
        for provider in providers:
            f = provider.observe()
            name = type(provider).__name__
            assert f.visible[0, LED] == seen, (leds, name)
            assert f.visible[1, LED] == leds[0], (leds, name)
            if seen:
                assert abs(f.bearing[0, LED]) <= BEARING_TOL, name
                assert f.distance[0, LED] == pytest.approx(0.6, rel=0.1), name
            # The face is always lit.
            assert f.visible[0, FACE] and f.visible[1, FACE], name


def test_a_robot_never_sees_its_own_led_or_face() -> None:
    # Alone in the field with its LED on: no green, no red anywhere in its 360° image.
    world = World(WorldConfig(n_robots=1, n_packs=0))
    geo = make_provider("geometric", world)
    with RenderedVision(world) as ren:
        for deg in (0, 37, 90, 200):
            _place(world, [(0.1, -0.2, math.radians(deg))], [], leds=True)
            for provider in (geo, ren):
                f = provider.observe()
                assert not f.visible[0, LED] and not f.visible[0, FACE]
                assert not f.blobs[0]
            assert not ren.last_masks[LED].any() and not ren.last_masks[FACE].any()
            # The robot itself is there (rendered for others): its LED geom is lit green.
            assert world.led_on[0]


def test_own_led_hidden_but_other_robots_led_seen_from_close(world, providers) -> None:
    # Side by side, 0.3 m apart, both LEDs on: each sees exactly one green blob, the other's.
    _place(world, [(0.0, -0.15, 0.0), (0.0, 0.15, 0.0)], [(0.9, 0.9), (0.9, -0.9)], True)
    for provider in providers:
        f = provider.observe()
        for me, bearing in ((0, math.pi / 2), (1, -math.pi / 2)):
            greens = [b for b in f.blobs[me] if b.cls == LED]
            assert len(greens) == 1, type(provider).__name__
            assert abs(math.remainder(greens[0].bearing - bearing, 2 * math.pi)) <= BEARING_TOL
            assert greens[0].distance == pytest.approx(0.3, rel=0.1)


def test_elevation_band_limits_what_is_seen_close_by() -> None:
    # A pack 0.2 m from the camera axis: its top is 16° below the horizon. A camera that sees
    # only down to -10° misses it; the default (-45°) sees it.
    world = World(WorldConfig(n_robots=1, n_packs=1))
    _place(
        world,
        [(0.0, 0.0, math.radians(45.0))],
        [(0.2 * math.cos(math.radians(90.0)), 0.2 * math.sin(math.radians(90.0)))],
    )
    narrow = CameraConfig(elevation_min_deg=-10.0)
    for config, seen in ((narrow, False), (CameraConfig(), True)):
        geo = make_provider("geometric", world, config)
        with RenderedVision(world, config) as ren:
            for provider in (geo, ren):
                assert provider.observe().visible[0, BATTERY] == seen, (config, provider)


def test_both_providers_are_deterministic(world, providers) -> None:
    random_scene(world, np.random.default_rng(4))
    for provider in providers:
        a, b = provider.observe(), provider.observe()
        np.testing.assert_array_equal(a.visible, b.visible)
        np.testing.assert_array_equal(a.bearing, b.bearing)
        np.testing.assert_array_equal(a.distance, b.distance)
        assert a.blobs == b.blobs


def test_providers_agree_on_random_scenes() -> None:
    """Looser versions of the benchmark's targets (benchmarks/vision_agreement.py)."""
    world = World(WorldConfig(n_robots=4, n_packs=5))
    geo = GeometricVision(world)
    rows = []
    with RenderedVision(world) as ren:
        for s in range(8):
            random_scene(world, np.random.default_rng([99, s]))
            scene = compare_scene(geo, ren)
            f_geo, f_ren = scene.geometric, scene.rendered
            rows += scene.targets
            # The nearest pack is what Forage reads: both must see one, within 10 %.
            both = f_geo.visible[:, BATTERY] & f_ren.visible[:, BATTERY]
            assert both.sum() >= 3
            np.testing.assert_allclose(
                f_ren.distance[both, BATTERY], f_geo.distance[both, BATTERY], rtol=0.15
            )
    stats = {s.name: s for s in summarise(rows, within=1.5)}
    assert stats["all"].targets >= 150
    assert stats["all"].agreement >= 0.92
    for name in ("led", "face", "battery"):
        if stats[name].targets >= 20:
            assert stats[name].agreement >= 0.9, name
    assert stats["all"].bearing_error_median_deg <= 3.0
    assert stats["all"].distance_error_median <= 0.15


def test_compiled_and_opencv_segmentation_identical_on_rendered_scenes() -> None:
    """The default (compiled) segmentation finds exactly the OpenCV reference's blobs."""
    world = World(WorldConfig(n_robots=4, n_packs=5))
    with RenderedVision(world) as ren:
        assert ren.segmenter.backend == "numba"
        reference = OmniSegmenter(ren.config, target_geometry(world), backend="numpy")
        for s in range(6):
            random_scene(world, np.random.default_rng([7, s]))
            strips = ren.renderer.render()
            fast, ref = ren.segmenter.detect(strips), reference.detect(strips)
            assert len(ref[0]) > 0
            for a, b in zip(fast, ref, strict=True):
                np.testing.assert_array_equal(a, b)


def test_snapshot_png_has_image_and_overlay(world, tmp_path) -> None:
    _place(world, [(-0.3, 0.0, 0.0), (0.3, 0.0, math.pi)], [(0.9, 0.9), (0.9, -0.9)], True)
    out = save_omni_png(world, 0, tmp_path / "sub" / "omni.png")
    img = cv2.imread(str(out))
    assert img is not None and img.shape[1] >= 1024
    # Two panels: the overlay paints the segmented classes in pure colours.
    bgr = img.reshape(-1, 3)
    assert np.any(np.all(bgr == (40, 255, 40), axis=1))  # LED of robot 1
    assert np.any(np.all(bgr == (40, 40, 255), axis=1))  # its face (BGR of red)
    with pytest.raises(ValueError, match="robot"):
        save_omni_png(world, 2, tmp_path / "bad.png")


def test_snapshot_overlay_ends_with_its_content_and_labels_hang_below(world) -> None:
    """The segmentation panel stops a little below its lowest class pixel; every segmented
    pixel is shown there, none covered by a label or leader; the labels hang below it."""
    _place(world, [(-0.3, 0.0, 0.0), (0.3, 0.0, math.pi)], [(0.9, 0.9), (0.9, -0.9)], True)
    with RenderedVision(world) as vision:
        frame = vision.observe()
        assert vision.last_strips is not None and vision.last_masks is not None
        strip, masks = vision.last_strips[0], vision.last_masks[:, 0]
        image = compose_omni_panels(strip, masks, frame, 0, vision)
    config = vision.config
    assert len(frame.blobs[0]) >= 3  # robot 1's LED and face, a pack
    # Header (20 rows), image panel, white gap (4 rows), overlay, label band.
    gap = int(np.flatnonzero((image == 255).all(axis=(1, 2)))[0])
    scale_y = (gap - 20) // config.height
    scale_x = image.shape[1] // config.strip_width
    assert (gap - 20) % config.height == 0 and image.shape[1] % config.strip_width == 0
    below = image[gap + 4 :]
    dark = (below == 0).all(axis=2).mean(axis=1) > 0.5  # the band: mostly black rows
    band_top = int(np.flatnonzero(~dark)[-1]) + 1  # the dimmed floor ends the overlay
    overlay, band = below[:band_top], below[band_top:]
    lowest = int(np.flatnonzero(masks.any(axis=(0, 2)))[-1])
    assert (lowest + 1) * scale_y <= overlay.shape[0] < config.height * scale_y
    assert overlay.shape[0] <= (lowest + 1 + config.height // 24) * scale_y
    for c, rgb in enumerate(((40, 255, 40), (255, 40, 40), (60, 120, 255))):
        shown = int((overlay == rgb).all(axis=2).sum())
        assert shown == int((masks[c] > 0).sum()) * scale_x * scale_y, c
    # One label per blob in the band: its text in the class colour.
    assert band.shape[0] >= 8 + 16
    for c, rgb in enumerate(((40, 255, 40), (255, 40, 40), (60, 120, 255))):
        if any(b.cls == c for b in frame.blobs[0]):
            assert (band == rgb).all(axis=2).sum() >= 10, c


def _crossings(xs, widths, places) -> int:
    return sum(
        1
        for i, (row, _) in enumerate(places)
        for j, (r, left) in enumerate(places)
        if r < row and left - 1 <= xs[i] <= left + widths[j] + 1
    )


@pytest.mark.parametrize("seed", range(30))
def test_strip_labels_inside_apart_and_uncrossed(seed: int) -> None:
    rng = np.random.default_rng(seed)
    width = 1024
    n = int(rng.integers(1, 13))
    if seed % 2:  # a cluster, e.g. robots gathered on a pack
        centre = rng.integers(0, width)
        xs = np.clip(centre + rng.normal(0, 60, n), 0, width - 1).astype(int).tolist()
    else:
        xs = rng.integers(0, width, n).tolist()
    widths = rng.integers(90, 150, n).tolist()
    places = place_strip_labels(xs, widths, width)
    assert len(places) == n
    for (row, left), w in zip(places, widths, strict=True):
        assert row >= 0 and 1 <= left and left + w <= width - 1
    for i, j in itertools.combinations(range(n), 2):
        (ri, li), (rj, lj) = places[i], places[j]
        if ri == rj:
            assert li + widths[i] < lj or lj + widths[j] < li, (i, j)
    assert _crossings(xs, widths, places) == 0
    # Each label beside its own leader, or at least over it.
    for x, w, (_, left) in zip(xs, widths, places, strict=True):
        assert left == x + 3 or left + w == x - 3 or left <= x <= left + w


def test_strip_labels_of_many_blobs_in_one_column_stay_apart() -> None:
    xs, widths = [500] * 6 + [1020, 3], [120] * 8
    places = place_strip_labels(xs, widths, 1024)
    for i, j in itertools.combinations(range(len(xs)), 2):
        (ri, li), (rj, lj) = places[i], places[j]
        assert ri != rj or li + widths[i] < lj or lj + widths[j] < li
    assert all(1 <= left and left + w <= 1023 for (_, left), w in zip(places, widths, strict=True))
