"""The geometric vision in a large colony: its grid search and culled rays answer exactly what
the every-target reference answers, and reach only the targets near each robot.

``kernels.nearest`` reaches targets ring of grid cells by ring and tries a candidate only once
nothing farther out can be nearer; its rays test only the geoms near them
(``kernels.first_hit``). Both are exact by construction; here random colonies (spread out,
clustered, tilted robots, all LEDs dark) check it against the numpy reference, which places
and sorts every target and casts ``mj_ray`` over every geom.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent import constants as C
from cyber_rodent.vision import BATTERY, FACE, LED, geometric
from cyber_rodent.vision import kernels as K
from cyber_rodent.vision.geometric import (
    CULL_FROM_GEOMS,
    RAY_CELL,
    SEARCH_CELL,
    VISIBLE_GROUPS,
    GeometricVision,
    uniform_grid,
)
from cyber_rodent.world import World, WorldConfig

#: 50 robots and 63 packs at the paper's density: a 2.3 m x 5 / sqrt(2) = 8.13 m field.
N_ROBOTS, N_PACKS, FIELD = 50, 63, 2.3 * math.sqrt(50 / 4)


@pytest.fixture(scope="module")
def colony() -> World:
    config = WorldConfig(field_size=FIELD, n_robots=N_ROBOTS, n_packs=N_PACKS)
    return World(config, np.random.default_rng(0))


@pytest.fixture(scope="module")
def providers(colony: World) -> tuple[GeometricVision, GeometricVision]:
    return GeometricVision(colony, backend="numba"), GeometricVision(colony, backend="numpy")


@pytest.fixture(scope="module")
def one_cell(colony: World) -> GeometricVision:
    """The compiled provider as before the grids: a search grid of one cell (every target
    placed and sorted before any is tried) and rays cast by ``mj_ray`` over every geom."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(geometric, "SEARCH_CELL", 1000.0)
        patch.setattr(geometric, "CULL_FROM_GEOMS", 10**9)
        vision = GeometricVision(colony, backend="numba")
    assert vision.grids.targets.side == 1 and not vision.grids.rays.cull
    return vision


def _copy(out: K.NearestTargets) -> K.NearestTargets:
    return K.NearestTargets(*(np.copy(a) for a in out))


def tilt_quaternion(yaw: float, roll: float, pitch: float) -> np.ndarray:
    """A chassis turned by ``yaw`` about the vertical, then tipped by ``pitch`` and ``roll``
    (rad)."""
    qz = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    qy = np.array([math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0])
    qx = np.array([math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0])
    zy, quat = np.zeros(4), np.zeros(4)
    mujoco.mju_mulQuat(zy, qz, qy)
    mujoco.mju_mulQuat(quat, zy, qx)
    return quat


def scenes(world: World, rng: np.random.Generator, count: int, kind: str):
    """Colony scenes: ``spread`` (a fresh placement), ``clusters`` (robots in groups of five
    around packs, hiding each other), ``tilted`` (robots tipped by up to 1.2 rad, far more
    than any robot tips, which tests the search's bound for tilted cameras) or ``dark`` (every
    LED off)."""
    n = world.config.n_robots
    for _ in range(count):
        world.reset(rng)
        if kind == "clusters":
            packs = world.pack_positions()
            for i in range(n):
                px, py = packs[(i // 5) % len(packs)]
                a = rng.uniform(-math.pi, math.pi)
                r = rng.uniform(0.2, 0.5)
                world.set_robot_pose(i, px + r * math.cos(a), py + r * math.sin(a), a + math.pi)
        if kind == "tilted":
            for i in range(n):
                adr = int(world.root_qpos_adr[i])
                yaw = 2 * math.atan2(world.data.qpos[adr + 6], world.data.qpos[adr + 3])
                roll, pitch = rng.uniform(-1.2, 1.2, size=2)
                world.data.qpos[adr + 2] = 0.03
                world.data.qpos[adr + 3 : adr + 7] = tilt_quaternion(yaw, roll, pitch)
        world.set_led(np.zeros(n, bool) if kind == "dark" else rng.random(n) < 0.5)
        mujoco.mj_forward(world.model, world.data)
        yield


@pytest.mark.parametrize("kind", ["spread", "clusters", "tilted", "dark"])
def test_grid_search_equals_the_every_target_search(
    colony: World,
    providers: tuple[GeometricVision, GeometricVision],
    one_cell: GeometricVision,
    kind: str,
) -> None:
    """Bit for bit against the same kernel without grids; against the numpy reference with
    its rounding of the camera geometry (``tests/test_kernel_parity.py``)."""
    compiled, reference = providers
    rng = np.random.default_rng(["spread", "clusters", "tilted", "dark"].index(kind))
    n, n_t = N_ROBOTS, len(compiled.target_cls)
    seen = np.zeros(3, dtype=int)
    placed = []
    for _ in scenes(colony, rng, 6, kind):
        compiled.front.distance.fill(np.nan)  # which pairs did the search place?
        out_c = _copy(compiled.nearest_targets())
        out_one = one_cell.nearest_targets()
        out_r = reference.nearest_targets()
        for name in ("visible", "distance", "bearing"):
            np.testing.assert_array_equal(getattr(out_c, name), getattr(out_one, name))
        np.testing.assert_array_equal(out_c.visible, out_r.visible)
        np.testing.assert_allclose(out_c.distance, out_r.distance, rtol=0, atol=1e-12)
        np.testing.assert_allclose(out_c.bearing, out_r.bearing, rtol=0, atol=1e-12)
        # What the search placed, it placed as the search without grids does.
        reached = ~np.isnan(compiled.front.distance)
        np.testing.assert_array_equal(
            compiled.front.distance[reached], one_cell.front.distance[reached]
        )
        assert not np.isnan(one_cell.front.distance).any()
        placed.append(reached.mean())
        seen += out_c.visible.sum(axis=0)
        if kind == "dark":  # no LED to find: the search placed every LED
            assert reached[:, :n].all()
    assert 0.0 < np.mean(placed) < 1.0
    if kind != "dark":
        assert np.mean(placed) < 0.6  # most targets are never placed
        assert (seen > 0).all()  # every class was seen
    else:
        assert seen[LED] == 0 and seen[FACE] > 0 and seen[BATTERY] > 0
    assert n_t == 2 * n + N_PACKS


def test_nearest_equals_the_full_pass_in_a_colony(
    colony: World, providers: tuple[GeometricVision, GeometricVision]
) -> None:
    """The lazy answer is observe()'s nearest target of each class (full pass, mj_multiRay,
    blob merging), and the compiled full pass and merging equal their references."""
    compiled, reference = providers
    rng = np.random.default_rng(9)
    merged = 0
    for kind in ("spread", "clusters"):
        for _ in scenes(colony, rng, 3, kind):
            frame = compiled.observe()
            nearest = compiled.nearest_targets()
            np.testing.assert_array_equal(nearest.visible, frame.visible)
            np.testing.assert_array_equal(nearest.distance, frame.distance)
            mc, mr = compiled.measure_targets(), reference.measure_targets()
            np.testing.assert_array_equal(mc.visible, mr.visible)
            np.testing.assert_array_equal(compiled.merging.merged, reference.merging.merged)
            np.testing.assert_allclose(mc.blob_spread, mr.blob_spread, rtol=0, atol=1e-12)
            merged += int(compiled.merging.merged.sum())
    assert merged > 0  # touching blobs were merged


def test_culled_rays_hit_what_mj_ray_hits(
    colony: World, providers: tuple[GeometricVision, GeometricVision]
) -> None:
    compiled, _ = providers
    assert compiled.grids.rays.cull  # 781 geoms: the search's rays are culled
    rng = np.random.default_rng(4)
    m, d = colony.model, colony.data
    geom = np.zeros(1, dtype=np.int32)
    hit = np.zeros(1, dtype=np.int32)
    agreed = hits_on_segment = 0
    for _ in scenes(colony, rng, 3, "clusters"):
        compiled.nearest_targets()  # bins the geoms of this state
        for _ in range(300):
            i = int(rng.integers(N_ROBOTS))
            p = d.site_xpos[colony.camera_site[i]].copy()
            if rng.random() < 0.5:  # at a target's centre
                target = compiled.target_geom[rng.integers(len(compiled.target_geom))]
                v = d.geom_xpos[target] - p
            else:  # anywhere, up to 4 m away
                v = np.append(rng.uniform(-4.0, 4.0, size=2), rng.uniform(-0.17, 0.1))
            exclude = int(colony.chassis_body[i])
            x = mujoco.mj_ray(m, d, p, v, VISIBLE_GROUPS, 1, exclude, geom, None)
            got = K.first_hit(
                compiled.scene.poses, compiled.grids, VISIBLE_GROUPS, exclude, p, v,
                p.ctypes.data, v.ctypes.data, hit,
            )  # fmt: skip
            assert got == geom[0] == hit[0], (p, v)
            agreed += 1
            hits_on_segment += 0 <= x <= 1
    assert agreed == 900 and hits_on_segment > 300  # many answered by the culled test


def test_the_paper_field_is_one_search_ring() -> None:
    """In the 2.3 m field the search grid is 2 x 2 cells: ring 1 covers it from any cell, so
    every target is placed before any is tried, as before the grid."""
    vision = GeometricVision(World(WorldConfig()))
    assert SEARCH_CELL == C.FIELD_SIZE / 2 and vision.grids.targets.side == 2
    assert vision.grids.geoms.side == math.ceil(2.3 / RAY_CELL) == 5
    # 67 geoms: mj_ray's scan of every geom costs no more than culling; the same answer.
    assert world_geoms(vision) == 67 < CULL_FROM_GEOMS and not vision.grids.rays.cull
    vision.front.distance.fill(np.nan)
    vision.nearest_targets()
    assert not np.isnan(vision.front.distance).any()


def world_geoms(vision: GeometricVision) -> int:
    return int(vision.world.model.ngeom)


def test_uniform_grid_bins_by_hand() -> None:
    # A 3 m field in 1 m cells: origin -1.5; x = -1.2 is column 0, 0.2 column 1, 1.4 column
    # 2; a point beyond the field (x = 9) is binned into the edge column.
    grid = uniform_grid(3.0, 1.0, np.array([0, 1, 2, 3]))
    assert (grid.origin, grid.cell, grid.side) == (-1.5, 1.0, 3)
    positions = np.array([[-1.2, -1.2, 0], [0.2, -1.2, 0], [1.4, 0.3, 0], [9.0, -1.0, 0]])
    K._bin(grid, positions)
    # Cells (column + 3 row): 0, 1, 5, 2.
    counts = np.diff(grid.start)
    np.testing.assert_array_equal(counts, [1, 1, 1, 0, 0, 1, 0, 0, 0])
    np.testing.assert_array_equal(grid.items, [0, 1, 3, 2])


def test_rays_test_the_walls_and_floor_always_and_never_the_wheel_spheres() -> None:
    world = World(WorldConfig())
    grids = GeometricVision(world).grids
    m = world.model
    always = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in grids.rays.always}
    assert always == {C.FLOOR_GEOM, *C.WALL_GEOMS}
    binned = set(grids.geoms.members.tolist())
    hidden = np.flatnonzero(m.geom_group == 3)  # collision-only spheres: not rendered
    assert len(hidden) and not binned & set(hidden.tolist())
    assert set(world.led_geom.tolist()) <= binned and set(world.pack_geom.tolist()) <= binned
    assert grids.rays.reach == pytest.approx(m.geom_rbound[list(binned)].max() + K.CULL_MARGIN)
