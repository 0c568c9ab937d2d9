"""Many copies of an arena in one world (``WorldConfig.arenas``, docs/design.md §9.33).

The layout (which robot and pack is in which arena, each arena's walls, placement inside
them), the settings' rules, that no IR exchange and no sight crosses a wall, and that the
paper's one-arena world is the model and placement it was before arenas existed.
"""

from __future__ import annotations

import hashlib
import math

import mujoco
import numpy as np
import pytest

from cyber_rodent import constants as C
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.survival import kernels as survival_kernels
from cyber_rodent.vision.geometric import GeometricVision, culled_rangefinders
from cyber_rodent.vision.types import BATTERY
from cyber_rodent.world import (
    ARENA_GAP,
    MAX_FIELD_SIZE,
    WALL_THICKNESS,
    World,
    WorldConfig,
    arena_centres,
    arena_grid,
    arena_pitch,
    arena_wall_name,
    build_mjcf,
    place_discs,
)

HALF = C.FIELD_SIZE / 2
#: The front of the charging teeth ahead of a robot's centre (m): where it touches a wall.
TEETH_FRONT = 0.134
#: A robot's IR port ahead of its centre, and to its right (m).
PORT_AHEAD, PORT_RIGHT = 0.111, 0.02

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()


def test_grid_of_arenas() -> None:
    """ceil(sqrt(K)) columns, filled row by row from the top left, centred on the origin."""
    assert [arena_grid(k) for k in (1, 2, 3, 4, 5, 9, 10, 25, 26)] == [
        (1, 1), (2, 1), (2, 2), (2, 2), (3, 2), (3, 3), (4, 3), (5, 5), (6, 5),
    ]  # fmt: skip
    pitch = arena_pitch(C.FIELD_SIZE)
    assert pitch == pytest.approx(C.FIELD_SIZE + 2 * WALL_THICKNESS + ARENA_GAP) and pitch == 2.7
    np.testing.assert_array_equal(arena_centres(1, C.FIELD_SIZE), [[0.0, 0.0]])
    centres = arena_centres(25, C.FIELD_SIZE)
    np.testing.assert_allclose(centres[0], [-2 * pitch, 2 * pitch])  # top left
    np.testing.assert_allclose(centres[1], [-pitch, 2 * pitch])  # to its right
    np.testing.assert_allclose(centres[5], [-2 * pitch, pitch])  # the next row, below
    np.testing.assert_allclose(centres[24], [2 * pitch, -2 * pitch])
    np.testing.assert_allclose(centres.mean(axis=0), [0.0, 0.0], atol=1e-12)
    config = WorldConfig(n_robots=100, n_packs=125, arenas=25)
    assert config.robots_per_arena == 4 and config.packs_per_arena == 5
    assert config.extent == pytest.approx(C.FIELD_SIZE + 4 * pitch)
    assert WorldConfig().extent == C.FIELD_SIZE


def _inside(points: np.ndarray, centres: np.ndarray, margin: float) -> np.ndarray:
    """Whether each point lies within its arena's walls with ``margin`` to spare."""
    return np.all(np.abs(points - centres) <= HALF - margin, axis=1)


def test_arena_layout_robots_packs_and_walls() -> None:
    """25 copies of the paper's arena: robots and packs in contiguous blocks, every arena with
    its own four walls around its centre, every robot and pack placed inside its own walls."""
    world = World(WorldConfig(n_robots=100, n_packs=125, arenas=25), np.random.default_rng(5))
    np.testing.assert_array_equal(world.robot_arena, np.arange(100) // 4)
    np.testing.assert_array_equal(world.pack_arena, np.arange(125) // 5)
    assert world.robot_arena.dtype == world.pack_arena.dtype == np.int64
    m = world.model
    assert world.wall_geom.shape == (25, 4)
    d = world.data
    template = d.geom_xpos[world.wall_geom[0]] - np.append(world.arena_centres[0], 0.0)
    for a in range(25):
        for w, name in enumerate(C.WALL_GEOMS):
            geom = world.wall_geom[a, w]
            assert m.geom(geom).name == arena_wall_name(a, name)
            # The same wall, the same size, around this arena's centre.
            np.testing.assert_allclose(m.geom_size[geom], m.geom_size[world.wall_geom[0, w]])
        offset = d.geom_xpos[world.wall_geom[a]] - np.append(world.arena_centres[a], 0.0)
        np.testing.assert_allclose(offset, template, atol=1e-12)
    # The walls' inner faces are the field's edge.
    north = world.wall_geom[0, 0]
    assert m.geom_size[north, 1] * 2 == pytest.approx(WALL_THICKNESS)
    inner = d.geom_xpos[north, 1] - m.geom_size[north, 1] - world.arena_centres[0, 1]
    assert inner == pytest.approx(HALF)
    poses = world.poses()
    assert _inside(poses[:, :2], world.arena_centres[world.robot_arena], CR.body_radius).all()
    packs = world.pack_positions()
    assert _inside(packs, world.arena_centres[world.pack_arena], C.PACK_RADIUS + 0.2).all()
    # Each arena got its share, not a fixed arrangement: the arenas differ.
    relative = packs - world.arena_centres[world.pack_arena]
    assert not np.allclose(relative[:5], relative[5:10])


def test_each_arena_is_placed_like_the_paper_field() -> None:
    """Arena 0's robots and packs are exactly what the one-field placement draws from the same
    generator; the next arena continues the same generator's stream."""
    world = World(WorldConfig(n_robots=8, n_packs=10, arenas=2), np.random.default_rng(3))
    rng = np.random.default_rng(3)
    radii = np.array([CR.body_radius + 0.02] * 4 + [C.PACK_RADIUS + 0.15] * 5)
    margin = np.array([0.0] * 4 + [0.2 + C.PACK_RADIUS - radii[-1]] * 5)
    first = place_discs(radii, HALF, rng, margin)
    second = place_discs(radii, HALF, rng, margin)
    robots = world.poses()[:, :2] - world.arena_centres[world.robot_arena]
    packs = world.pack_positions() - world.arena_centres[world.pack_arena]
    np.testing.assert_allclose(robots[:4], first[:4], atol=1e-15)
    np.testing.assert_allclose(packs[:5], first[4:], atol=1e-15)
    np.testing.assert_allclose(robots[4:], second[:4], atol=1e-15)
    np.testing.assert_allclose(packs[5:], second[4:], atol=1e-15)


def test_placement_is_deterministic() -> None:
    config = WorldConfig(n_robots=8, n_packs=8, arenas=4)
    a = World(config, np.random.default_rng(9))
    b = World(config, np.random.default_rng(9))
    np.testing.assert_array_equal(a.poses(), b.poses())
    np.testing.assert_array_equal(a.pack_positions(), b.pack_positions())
    a.reset(np.random.default_rng(10))
    assert not np.array_equal(a.poses(), b.poses())
    b.reset(np.random.default_rng(10))
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)


def _message(**fields: object) -> str:
    with pytest.raises(ValueError) as caught:
        WorldConfig(**fields)  # type: ignore[arg-type]
    text = str(caught.value)
    assert "\n" not in text
    return text


def test_counts_must_split_evenly_between_the_arenas() -> None:
    text = _message(n_robots=10, n_packs=8, arenas=4)
    assert text == (
        "n_robots must be a multiple of arenas=4 (every arena holds n_robots / arenas of "
        "them), got 10"
    )
    assert _message(n_robots=8, n_packs=10, arenas=4).startswith(
        "n_packs must be a multiple of arenas=4"
    )
    assert WorldConfig(n_robots=8, n_packs=0, arenas=4).packs_per_arena == 0
    assert _message(arenas=0).startswith("arenas must be an integer in [1, 200], got 0")
    assert _message(arenas=True).startswith("arenas must be an integer")


def test_fit_is_checked_per_arena() -> None:
    """The paper's density in 25 arenas fits where one 2.3 m field refuses the same counts;
    one arena's share that does not fit is refused naming the per-arena counts."""
    assert WorldConfig(n_robots=100, n_packs=125, arenas=25).field_size == C.FIELD_SIZE
    assert "need field_size >= 7.58 m" in _message(n_robots=100, n_packs=125)
    text = _message(n_robots=40, n_packs=10, arenas=2)
    assert text.startswith("n_robots / arenas=20 and n_packs / arenas=5 do not fit in the ")
    assert "20 robots and 5 packs need field_size >=" in text
    text = _message(n_robots=100, n_packs=125, arenas=25, field_size=11.5)
    assert f"it must be at most {MAX_FIELD_SIZE:g} m" in text


# --- the paper's world is what it was --------------------------------------------------------
#: Recorded from the code before arenas existed (``git archive`` of the commit before): the
#: default model's sizes, its MJCF text's SHA-256 and the placement of seed 7.
DEFAULT_SIZES = {"ngeom": 67, "nbody": 27, "nsite": 40, "nsensor": 32, "njnt": 12, "nu": 8}
DEFAULT_XML_SHA256 = "ee0fd3e32cc6735a6f85ce9d8e1e88fed0b24d0a30bfe6737d7f840352589991"
SEED7_POSES = [
    [-0.38999579489775915, -0.4387172880404687, 0.7676747392672367],
    [-0.48535821644483323, -0.10874891435235978, 3.0722272157111794],
    [0.009005552736747524, 0.10592475710749516, -1.7887682043279143],
    [0.9810905612000974, 0.5794706000432309, -2.134950756420826],
]
SEED7_PACKS = [
    [0.22642279455444725, 0.7189569797549316],
    [0.49899109934380026, -0.49737498611702863],
    [-0.3616990243106819, 0.6761317361672339],
    [-0.8954697987363096, 0.5814234372728069],
    [0.5376956660412036, -0.05803773535286538],
]


def test_one_arena_is_the_world_before_arenas() -> None:
    """The published contact model is the MJCF text it was, byte for byte; the fixed model
    differs from it in the chassis' and the teeth's collision bits and the docking hold's
    impedance alone."""
    published = build_mjcf(4, 5, 1.0 / 120.0, contacts="published").to_xml_string()
    assert hashlib.sha256(published.encode()).hexdigest() == DEFAULT_XML_SHA256
    xml = build_mjcf(4, 5, 1.0 / 120.0).to_xml_string()
    assert build_mjcf(4, 5, 1.0 / 120.0, C.FIELD_SIZE, 1).to_xml_string() == xml
    assert len(published.splitlines()) == len(xml.splitlines())
    pairs = zip(published.splitlines(), xml.splitlines(), strict=True)
    changed = [(a, b) for a, b in pairs if a != b]
    assert len(changed) == 3 * 4  # chassis, teeth and docking hold of each of the 4 robots
    for before, after in changed:
        if "<weld" in before:
            stiff = 'solimp="0.94999999999999996 0.98999999999999999 0.001"'  # 0.95 0.99 0.001
            assert after == before.replace('active="false"', f'active="false" {stiff}')
            continue
        assert 'contype="2" conaffinity="2"' in before
        assert ('contype="6" conaffinity="4"' in after) != ('contype="2" conaffinity="0"' in after)
    world = World(WorldConfig(arenas=1), np.random.default_rng(7))
    m = world.model
    assert {name: getattr(m, name) for name in DEFAULT_SIZES} == DEFAULT_SIZES
    assert [m.geom(i).name for i in range(5)] == [C.FLOOR_GEOM, *C.WALL_GEOMS]
    np.testing.assert_array_equal(world.poses(), SEED7_POSES)
    np.testing.assert_array_equal(world.pack_positions(), SEED7_PACKS)
    np.testing.assert_array_equal(world.robot_arena, np.zeros(4))
    np.testing.assert_array_equal(world.wall_geom, [[1, 2, 3, 4]])


def test_several_arenas_keep_their_walls_off_the_world_body() -> None:
    """Each arena's walls are on a static body of their own (the broad phase pairs a robot with
    its own arena's walls only); the floor stays on the world body, one for all arenas."""
    world = World(WorldConfig(n_robots=4, n_packs=0, arenas=4), np.random.default_rng(0))
    m = world.model
    bodies = m.geom_bodyid[world.wall_geom]
    assert len(set(bodies[:, 0])) == 4 and (bodies == bodies[:, :1]).all()
    assert (m.body_weldid[bodies] == 0).all() and (bodies != 0).all()  # static, not the world
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.FLOOR_GEOM)
    assert m.geom_bodyid[floor] == 0
    reach = world.arena_centres.max() + HALF + WALL_THICKNESS
    np.testing.assert_allclose(m.geom_size[floor, :2], [reach, reach])


# --- no IR exchange across a wall ---------------------------------------------------------------
def _face(world: World, robot: int, x: float, y: float, east: bool) -> None:
    world.set_robot_pose(robot, x, y, 0.0 if east else math.pi)


def _mate_for(survival: SurvivalWorld, steps: int) -> np.ndarray:
    """Every robot still, LED on, signalling Mate, for ``steps`` steps: the partners found."""
    n = survival.n_robots
    partners = np.full(n, -1)
    for _ in range(steps):
        on = np.ones(n, dtype=bool)
        events = survival.step(np.zeros((n, 2)), on, on, on)
        found = events.mate_partner >= 0
        partners[found] = events.mate_partner[found]
    return partners


def _pair_scene(across: bool, config: SurvivalConfig) -> tuple[SurvivalWorld, float]:
    """Robots 0 (arena 0) and 2 (arena 1) nose to the wall between the two arenas, facing each
    other across it (``across``); else robots 0 and 1 (both arena 0) as far apart, facing each
    other inside arena 0. The others are parked away. Returns the world and the distance
    between the pair's IR ports."""
    world = World(WorldConfig(n_robots=4, n_packs=0, arenas=2), np.random.default_rng(0))
    survival = SurvivalWorld(world, config, np.random.default_rng(1))  # placed at random
    (c0, _), (c1, _) = world.arena_centres
    x0 = c0 + HALF - TEETH_FRONT - 0.005  # teeth 5 mm from arena 0's east wall
    x1 = c1 - HALF + TEETH_FRONT + 0.005  # and from arena 1's west wall
    span = x1 - x0
    # Ports 2 cm right of centre: the westward robot stands 4 cm south, so the ports line up.
    if across:
        pair = (0, 2)
        _face(world, 0, x0, 0.0, east=True)
        _face(world, 2, x1, -2 * PORT_RIGHT, east=False)
        _face(world, 1, c0 - 0.8, 0.8, east=True)
    else:
        pair = (0, 1)
        _face(world, 0, c0 - span / 2, 0.0, east=True)
        _face(world, 1, c0 + span / 2, -2 * PORT_RIGHT, east=False)
        _face(world, 2, c1 + 0.8, 0.8, east=True)
    _face(world, 3, c1 + 0.5, -0.8, east=True)
    mujoco.mj_forward(world.model, world.data)
    port = world.data.site_xpos[world.ir_port_site]
    return survival, float(np.linalg.norm(port[pair[0]] - port[pair[1]]))


def test_no_mating_across_the_wall_between_two_arenas() -> None:
    """Two robots nose to nose across the wall between arena 0 and arena 1, within IR range
    (``mate_distance`` 0.6 m here, so that only the arena rule stands between them) and facing
    each other, both signalling Mate: no exchange. The same pair, as far apart inside one
    arena, exchanges."""
    survival, gap = _pair_scene(True, SurvivalConfig(mate_distance=0.6))
    # Both walls (0.2 m) and the gap between them lie between the ports, yet they are in range.
    assert 2 * WALL_THICKNESS + ARENA_GAP < gap < 0.6
    dist, angle = survival.mating.ir_geometry()
    assert dist[0, 2] < 0.6 and angle[0, 2] < 15 and angle[2, 0] < 15  # they face each other
    assert (_mate_for(survival, 4) < 0).all()
    assert not survival.mating.streak.any()

    inside, gap_inside = _pair_scene(False, SurvivalConfig(mate_distance=0.6))
    assert gap_inside == pytest.approx(gap, abs=0.01)
    partners = _mate_for(inside, 4)
    assert partners[0] == 1 and partners[1] == 0


def test_no_mating_across_a_wall_at_the_default_range() -> None:
    """At the paper's IR range a pair pressed against both sides of the wall is out of range
    as well: the walls and the gap are wider than ``mate_distance``."""
    survival, gap = _pair_scene(True, SurvivalConfig())
    assert gap > survival.config.mate_distance
    assert (_mate_for(survival, 3) < 0).all()


def test_mate_kernel_and_reference_agree_with_arenas() -> None:
    """The compiled mating kernel and its reference on random pairs facing each other, within
    and across arenas (a reach of 0.6 m, wider than the wall between): the same streaks and
    exchanges, and never a pair of two arenas."""
    world = World(WorldConfig(n_robots=8, n_packs=0, arenas=2), np.random.default_rng(0))
    n = 8
    rules = survival_kernels.MatingRules(
        reach2=0.6**2, cos_angle=math.cos(math.radians(15.0)), consecutive_steps=2
    )
    rng = np.random.default_rng(4)
    d = world.data
    east_wall = world.arena_centres[0, 0] + HALF
    crossed = exchanged = 0
    for trial in range(60):
        world.reset(rng)
        # Robot pairs (0, 4) and (1, 5) face each other across the wall; (2, 3) and (6, 7)
        # inside their arena.
        for a, b in ((0, 4), (1, 5)):
            y = rng.uniform(-0.8, 0.8)
            _face(world, a, east_wall - TEETH_FRONT - rng.uniform(0.0, 0.05), y, east=True)
            x = east_wall + 2 * WALL_THICKNESS + ARENA_GAP + TEETH_FRONT + rng.uniform(0, 0.05)
            _face(world, b, x, y - 2 * PORT_RIGHT + rng.normal(0, 0.01), east=False)
        for a, b in ((2, 3), (6, 7)):
            cx = world.arena_centres[world.robot_arena[a], 0]
            y = rng.uniform(-0.8, 0.8)
            _face(world, a, cx - 0.25, y, east=True)
            _face(world, b, cx + 0.25 + rng.uniform(0, 0.1), y - 2 * PORT_RIGHT, east=False)
        mujoco.mj_forward(world.model, d)
        signal = rng.random(n) < 0.9
        streak = rng.integers(0, 3, (n, n)) * (rng.random((n, n)) < 0.5)
        streak = np.triu(streak, 1) + np.triu(streak, 1).T
        split = world.robot_arena[:, None] != world.robot_arena[None, :]
        streak[split] = 0  # no pair of two arenas ever has a streak
        runs = []
        for kernel in (survival_kernels.mate, survival_kernels.mate_reference):
            ports = survival_kernels.IrPorts(
                site=np.asarray(world.ir_port_site, dtype=np.int64),
                site_xpos=d.site_xpos,
                site_xmat=d.site_xmat,
                streak=streak.copy(),
                streak_active=np.array([trial % 3 != 0]),
                pairs=np.zeros((n * n, 3)),
                arena=world.robot_arena,
            )
            out = np.full(n, -1, dtype=np.int64)
            alive, docked = np.ones(n, bool), np.zeros(n, bool)
            runs.append((kernel(signal, alive, docked, ports, rules, out), ports, out))
        (any_c, ports_c, out_c), (any_r, ports_r, out_r) = runs
        assert any_c == any_r
        np.testing.assert_array_equal(out_c, out_r)
        np.testing.assert_array_equal(ports_c.streak, ports_r.streak)
        paired = out_c >= 0
        assert (world.robot_arena[out_c[paired]] == world.robot_arena[paired]).all()
        assert not ports_c.streak[split].any()
        exchanged += int(any_c)
        # Without the arena rule the pairs across the wall would hold the condition.
        ports_one = ports_c._replace(streak=np.zeros((n, n), np.int64), arena=np.zeros(n, np.int64))
        survival_kernels.mate(signal, alive, docked, ports_one, rules, np.full(n, -1))
        crossed += int(ports_one.streak[split].any())
    assert exchanged >= 10 and crossed >= 10, (exchanged, crossed)


# --- no sight across a wall --------------------------------------------------------------------
def _pack_beyond_the_wall() -> World:
    """Robot 0 (arena 0) faces east, 0.4 m from the wall between arena 0 and arena 1; pack 1
    (arena 1) stands 0.35 m beyond that wall, straight ahead; pack 0 (arena 0) far behind the
    robot, in arena 0's west corner; robot 1 (arena 1) parked away from the line of sight."""
    world = World(WorldConfig(n_robots=2, n_packs=2, arenas=2), np.random.default_rng(0))
    east_wall = world.arena_centres[0, 0] + HALF
    world.set_robot_pose(0, east_wall - 0.4, 0.0, 0.0)
    world.set_pack_position(1, east_wall + 2 * WALL_THICKNESS + ARENA_GAP + 0.35, 0.0)
    world.set_pack_position(0, world.arena_centres[0, 0] - HALF + 0.3, -HALF + 0.3)
    world.set_robot_pose(1, world.arena_centres[1, 0] + 0.6, 0.8, 0.0)
    mujoco.mj_forward(world.model, world.data)
    return world


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_no_pack_seen_through_the_wall(backend: str) -> None:
    world = _pack_beyond_the_wall()
    vision = GeometricVision(world, backend=backend)  # type: ignore[arg-type]
    near = vision.nearest_targets()
    # The robot sees a pack: its own arena's, far behind it, not the one 1.1 m ahead.
    assert near.visible[0, BATTERY]
    assert near.distance[0, BATTERY] > 1.5
    assert abs(abs(near.bearing[0, BATTERY]) - math.pi) < 0.5 * math.pi
    seen = vision.measure_targets()
    pack_beyond = 2 * world.config.n_robots + 1
    assert not seen.visible[0, pack_beyond] and not seen.candidate[0, pack_beyond]
    # The walls hide it too: a ray from the camera to that pack stops at arena 0's east wall.
    d = world.data
    camera = d.site_xpos[world.camera_site[0]]
    target = d.geom_xpos[world.pack_geom[1]]
    geom = np.zeros(1, dtype=np.int32)
    x = mujoco.mj_ray(world.model, d, camera, target - camera, None, 1, world.chassis_body[0], geom)
    assert 0 < x < 1 and geom[0] == world.wall_geom[0, C.WALL_GEOMS.index("wall_east")]


def test_the_same_pack_inside_the_arena_is_seen() -> None:
    """The control: a pack of the robot's own arena as far ahead, with no wall between."""
    world = _pack_beyond_the_wall()
    east_wall = world.arena_centres[0, 0] + HALF
    world.set_robot_pose(0, east_wall - 1.5, 0.0, 0.0)
    world.set_pack_position(0, east_wall - 1.5 + 1.15, 0.0)
    mujoco.mj_forward(world.model, world.data)
    near = GeometricVision(world).nearest_targets()
    assert near.visible[0, BATTERY]
    assert near.distance[0, BATTERY] == pytest.approx(1.15, abs=0.05)
    assert abs(near.bearing[0, BATTERY]) < 0.05


def test_vision_backends_agree_in_many_arenas() -> None:
    """Nine arenas, enough geoms that the compiled search's rays test only the geoms near them
    (walls included only where the ray meets them): the same nearest targets as the reference,
    which casts ``mj_ray`` over every geom, on crowded random states."""
    world = World(WorldConfig(n_robots=18, n_packs=18, arenas=9), np.random.default_rng(2))
    fast = GeometricVision(world, backend="numba")
    slow = GeometricVision(world, backend="numpy")
    assert fast.grids.rays.cull  # the culled rays are what is compared
    rng = np.random.default_rng(6)
    seen = 0
    for _ in range(8):
        world.reset(rng)
        for i in range(world.config.n_robots):  # close to the walls, facing any way
            cx, cy = world.arena_centres[world.robot_arena[i]]
            x, y = rng.uniform(-HALF + 0.15, HALF - 0.15, size=2)
            world.set_robot_pose(i, cx + x, cy + y, rng.uniform(-math.pi, math.pi))
        world.set_led(rng.random(world.config.n_robots) < 0.7)
        mujoco.mj_forward(world.model, world.data)
        a = fast.nearest_targets()
        b = slow.nearest_targets()
        # Which targets are seen: bit for bit; where they are: to rounding (the camera
        # geometry's numpy reference rounds its small matrix products differently).
        np.testing.assert_array_equal(a.visible, b.visible)
        np.testing.assert_allclose(a.distance, b.distance, rtol=1e-12)
        np.testing.assert_allclose(a.bearing, b.bearing, rtol=0, atol=1e-12)
        seen += int(a.visible.sum())
    assert seen > 50


# --- rangefinders -------------------------------------------------------------------------------
def test_rangefinders_read_what_mujoco_reads() -> None:
    """In a world of many arenas the survival world reads the rangefinders through the grid of
    geoms after the physics (``vision.kernels.ranges``): bit for bit MuJoCo's own sensor stage
    on the same state, with either backend, over steps of robots driving into walls and each
    other. The paper's world keeps MuJoCo's sensor stage."""
    assert culled_rangefinders(World(WorldConfig(), np.random.default_rng(0))) is None
    config = WorldConfig(n_robots=18, n_packs=18, arenas=9)
    runs = {}
    for backend in ("numba", "numpy"):
        world = World(config, np.random.default_rng(0))
        assert culled_rangefinders(world) is not None
        survival = SurvivalWorld(world, rng=np.random.default_rng(1), backend=backend)
        rng = np.random.default_rng(2)
        n, readings, near = config.n_robots, [], 0
        for _ in range(25):
            wheels = rng.uniform(-0.6, 1.0, (n, 2))
            on = np.ones(n, dtype=bool)
            survival.step(wheels, on, ~on, on)
            ours = world.data.sensordata.copy()
            mujoco.mj_sensorPos(world.model, world.data)  # MuJoCo's own readings, same state
            np.testing.assert_array_equal(ours, world.data.sensordata)
            readings.append(ours)
            near += int(((ours > 0) & (ours < 0.3)).sum())
        assert near > 20  # walls, robots and packs within the short sensors' range
        runs[backend] = (np.array(readings), world.data.qpos.copy())
    np.testing.assert_array_equal(runs["numba"][0], runs["numpy"][0])
    np.testing.assert_array_equal(runs["numba"][1], runs["numpy"][1])


# --- pictures --------------------------------------------------------------------------------
def test_top_down_camera_frames_every_arena() -> None:
    from cyber_rodent.render import FieldRenderer

    world = World(WorldConfig(n_robots=9, n_packs=9, arenas=9), np.random.default_rng(0))
    reach = world.config.extent / 2 + WALL_THICKNESS
    corners = np.array([[sx * reach, sy * reach, 0.2] for sx in (-1, 1) for sy in (-1, 1)])
    with FieldRenderer(world, 160, 160) as renderer:
        pixels = renderer.project_top_down(corners)
        image = renderer.top_down()
    assert (pixels > 0).all() and (pixels < 160).all()
    # Inside the outer walls every pixel is drawn (floor, walls, robots, packs): no black.
    (c0, r0), (c1, r1) = pixels.min(axis=0).astype(int) + 1, pixels.max(axis=0).astype(int) - 1
    assert image[r0:r1, c0:c1].any(axis=2).all()


def test_viewer_opens_on_every_arena() -> None:
    from evolution.lab.viewer import OVERVIEW, overview

    assert overview(World(WorldConfig(), np.random.default_rng(0))) == OVERVIEW
    world = World(WorldConfig(n_robots=4, n_packs=4, arenas=4), np.random.default_rng(0))
    view = overview(world)
    assert view.distance == pytest.approx(OVERVIEW.distance * world.config.extent / C.FIELD_SIZE)
    assert view._replace(distance=OVERVIEW.distance) == OVERVIEW
