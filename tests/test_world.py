"""The assembled model: what it contains, that it matches the constants, and placement."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent import constants as C
from cyber_rodent.assets import ASSETS_ENV_VAR, AssetNotFoundError, asset_path
from cyber_rodent.robot import RobotParts, cyber_rodent
from cyber_rodent.world import (
    MAX_PACKS,
    MAX_ROBOTS,
    World,
    WorldConfig,
    fits,
    max_counts,
    most_packs,
    most_robots,
    place_discs,
    smallest_field,
)

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()
#: Its range sensors as (name, bearing in degrees, range in metres).
RANGE_ROWS = [(row.name, row.bearing_deg, row.limit) for row in CR.range_sensors]
PARTS = RobotParts()


@pytest.fixture(scope="module")
def world() -> World:
    return World(WorldConfig(), np.random.default_rng(0))


def test_default_world_counts(world: World) -> None:
    m = world.model
    assert world.config.n_robots == 4 and world.config.n_packs == 5
    # 4 free joints + 8 wheel hinges; 8 motors; 4 x 8 rangefinders.
    assert m.njnt == 12 and m.nu == 8 and m.nsensor == 32
    assert sum(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE) == 4


def test_robot_model_reads_the_design_numbers_from_the_mjcf() -> None:
    """docs/design.md §4's numbers, as the robot model reads them from the XML."""
    assert (CR.mass, CR.wheel_radius, CR.half_wheel_base) == (1.75, 0.035, 0.08)
    assert (CR.top_speed, CR.body_length, CR.motor_time_constant) == (1.3, 0.22, 0.05)
    # The teeth's front corners (0.134 m ahead, 3 cm aside) are the farthest point seen from
    # above: sqrt(0.134² + 0.03²) = 0.1373 m, rounded up to the centimetre for placement.
    assert CR.footprint_radius == pytest.approx(math.hypot(0.134, 0.03), abs=1e-6)
    assert CR.body_radius == 0.14


def test_robot_matches_design_numbers(world: World) -> None:
    m = world.model
    root = m.body_rootid[world.chassis_body[0]]
    assert m.body_subtreemass[root] == pytest.approx(CR.mass, abs=1e-9)
    assert world.wheel_radius == pytest.approx(CR.wheel_radius)
    assert world.max_wheel_omega * world.wheel_radius == pytest.approx(CR.top_speed, rel=1e-6)
    chassis = world.chassis_geom[0]
    assert 2 * m.geom_size[chassis, 0] == pytest.approx(CR.body_length)
    # Half wheel base: wheel bodies at ±half_wheel_base from the centre line.
    for name in ("left_wheel_body", "right_wheel_body"):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, C.robot_prefix(0) + name)
        assert abs(m.body_pos[b, 1]) == pytest.approx(CR.half_wheel_base)
    # Centre of mass low: below a quarter of the body's height above the floor.
    mujoco.mj_forward(m, world.data)
    assert world.data.subtree_com[root, 2] < 0.05


def test_every_constant_name_exists(world: World) -> None:
    m = world.model
    p = C.robot_prefix(0)
    for kind, names in [
        (
            mujoco.mjtObj.mjOBJ_GEOM,
            [PARTS.chassis_geom, PARTS.led_geom, PARTS.face_geom, PARTS.teeth_geom],
        ),
        (mujoco.mjtObj.mjOBJ_SITE, [PARTS.ir_port_site, PARTS.camera_site]),
        (mujoco.mjtObj.mjOBJ_JOINT, [PARTS.left_wheel_joint, PARTS.right_wheel_joint]),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, [PARTS.left_motor, PARTS.right_motor]),
        (mujoco.mjtObj.mjOBJ_SENSOR, [n for n, _, _ in RANGE_ROWS]),
        (mujoco.mjtObj.mjOBJ_CAMERA, [C.CHASE_CAMERA, *C.OMNI_CAMERAS]),
    ]:
        for name in names:
            assert mujoco.mj_name2id(m, kind, p + name) >= 0, name
    for name in (C.FLOOR_GEOM, *C.WALL_GEOMS):
        assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name) >= 0
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.pack_prefix(0) + C.PACK_GEOM) >= 0


def test_range_sensor_directions_match_constants(world: World) -> None:
    """Each rangefinder site points along the bearing its constant says."""
    m, d = world.model, world.data
    world.set_robot_pose(0, 0.0, 0.0, 0.0)
    mujoco.mj_forward(m, d)
    for name, bearing_deg, _ in RANGE_ROWS:
        s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, C.robot_prefix(0) + name)
        z_axis = d.site_xmat[s].reshape(3, 3)[:, 2]
        expected = np.array(
            [math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg)), 0.0]
        )
        np.testing.assert_allclose(z_axis, expected, atol=1e-6)


def test_ir_port_front_right_pointing_forward(world: World) -> None:
    m = world.model
    s = world.ir_port_site[0]
    x, y, _ = m.site_pos[s]
    assert x > 0.1 and -0.04 < y < 0  # front, slightly right of centre
    mujoco.mj_forward(m, world.data)


def test_packs_are_static_and_make_no_contacts(world: World) -> None:
    """Packs are welded to the world: no joints, and no pack-floor contacts at rest."""
    m = world.model
    for b in world.pack_body:
        assert m.body_jntnum[b] == 0 and m.body_weldid[b] == 0
    world.reset(np.random.default_rng(3))
    world.step(50)
    pack_geoms = set(world.pack_geom) | set(world.electrode_geom)
    for c in world.data.contact[: world.data.ncon]:
        assert c.geom1 not in pack_geoms and c.geom2 not in pack_geoms


def test_at_rest_each_robot_has_exactly_four_floor_contacts() -> None:
    """Two wheels and the two rear casters; no spurious contacts (front caster, chassis)."""
    w = World(WorldConfig(n_robots=4, n_packs=5), np.random.default_rng(5))
    w.step(100)
    assert w.data.ncon == 4 * 4
    robots = w.geom_robot[w.data.contact.geom[: w.data.ncon]].max(axis=1)
    assert np.bincount(robots, minlength=4).tolist() == [4, 4, 4, 4]


def test_placement_is_seeded_and_non_overlapping() -> None:
    a = World(WorldConfig(), np.random.default_rng(11))
    b = World(WorldConfig(), np.random.default_rng(11))
    c = World(WorldConfig(), np.random.default_rng(12))
    np.testing.assert_array_equal(a.poses(), b.poses())
    np.testing.assert_array_equal(a.pack_positions(), b.pack_positions())
    assert not np.allclose(a.poses(), c.poses())
    pts = np.vstack([a.poses()[:, :2], a.pack_positions()])
    radii = np.array([CR.body_radius] * 4 + [C.PACK_RADIUS] * 5)
    for i in range(len(pts)):
        for j in range(i + 1, len(pts)):
            assert np.hypot(*(pts[i] - pts[j])) >= radii[i] + radii[j]
    assert np.all(np.abs(pts) <= C.FIELD_SIZE / 2 - C.PACK_RADIUS)
    # Packs keep a robot's width from the walls, so nobody gets wedged between pack and wall.
    assert np.all(np.abs(a.pack_positions()) <= C.FIELD_SIZE / 2 - C.PACK_RADIUS - 0.2)


def test_reset_redraws_placement_without_recompiling() -> None:
    w = World(WorldConfig(), np.random.default_rng(0))
    model = w.model
    first = w.poses().copy()
    w.reset(np.random.default_rng(1))
    assert w.model is model
    assert not np.allclose(first, w.poses())


def test_place_discs_hand_case() -> None:
    """Two discs of radius 0.5 in a 1x1 half-size box can only sit in opposite corners."""
    rng = np.random.default_rng(0)
    centres = place_discs(np.array([0.1, 0.1]), 1.0, rng)
    assert np.hypot(*(centres[0] - centres[1])) >= 0.2
    with pytest.raises(ValueError, match="does not fit"):
        place_discs(np.array([1.5]), 1.0, rng)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"n_robots": 0}, "n_robots"),
        ({"n_robots": -2}, "n_robots"),
        ({"n_robots": 10_000}, "n_robots"),
        ({"n_robots": 2.5}, "n_robots"),
        ({"n_packs": -1}, "n_packs"),
        ({"n_packs": 100_000}, "n_packs"),
        ({"timestep": 0.0}, "timestep"),
        ({"timestep": float("nan")}, "timestep"),
        ({"pack_gap": -0.1}, "pack_gap"),
        ({"pack_gap": 1.6}, "pack_gap"),
        ({"pack_gap": float("nan")}, "pack_gap"),
        ({"pack_wall_clearance": -0.1}, "pack_wall_clearance"),
        ({"pack_wall_clearance": 0.9}, "pack_wall_clearance"),
    ],
)
def test_bad_world_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        WorldConfig(**kwargs)


def test_counts_that_fit_alone_but_not_together() -> None:
    max_robots, max_packs = max_counts()
    with pytest.raises(ValueError, match="do not fit"):
        WorldConfig(n_robots=max_robots, n_packs=max_packs)


def test_nan_wheel_command_is_rejected(world: World) -> None:
    with pytest.raises(ValueError, match="finite"):
        world.set_wheel_speeds(np.array([np.nan, 0, 0, 0]), np.zeros(4))


def test_missing_asset_gives_clear_error(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(ASSETS_ENV_VAR, str(tmp_path))
    with pytest.raises(AssetNotFoundError, match="missing asset 'arena.xml'"):
        asset_path(C.ARENA_XML)
    with pytest.raises(AssetNotFoundError):
        World(WorldConfig())


def test_sixteen_robots_pile_up_without_overflow() -> None:
    """The contact arena scales with the robot count: 16 robots driving into each other hold
    more contacts than the 4 per robot at rest, robots against robots among them, and MuJoCo
    raises no warning (a full arena would). The count swings by half from step to step as
    robots press and bounce, so its peak is what is checked, not one step's."""
    w = World(WorldConfig(n_robots=16, n_packs=5), np.random.default_rng(0))
    w.set_wheel_speeds(np.full(16, 1.0), np.full(16, 1.0))
    most, robot_pairs = 0, 0
    for _ in range(1000):
        w.step(1)
        geoms = w.data.contact.geom[: w.data.ncon]
        a, b = w.geom_robot[geoms[:, 0]], w.geom_robot[geoms[:, 1]]
        most = max(most, w.data.ncon)
        robot_pairs = max(robot_pairs, int(((a >= 0) & (b >= 0) & (a != b)).sum()))
    assert most >= 16 * 4 and robot_pairs >= 8
    assert sum(int(w.data.warning[i].number) for i in range(len(w.data.warning))) == 0
    assert np.all(w.uprightness() > 0.9)


def test_packs_leave_room_to_turn_between_them() -> None:
    """No two packs closer than PACK_GAP: a robot never gets jammed between two packs."""
    from cyber_rodent.world import PACK_GAP

    w = World(WorldConfig(n_robots=3, n_packs=6), np.random.default_rng(0))
    for seed in range(50):
        w.reset(np.random.default_rng(seed))
        p = w.pack_positions()
        gaps = [
            np.hypot(*(p[i] - p[j])) - 2 * C.PACK_RADIUS
            for i in range(len(p))
            for j in range(i + 1, len(p))
        ]
        assert min(gaps) >= PACK_GAP - 1e-9


def test_pack_gap_and_wall_clearance_default_to_the_constants() -> None:
    from cyber_rodent.world import PACK_GAP, PACK_WALL_CLEARANCE

    cfg = WorldConfig()
    assert (cfg.pack_gap, cfg.pack_wall_clearance) == (PACK_GAP, PACK_WALL_CLEARANCE) == (0.3, 0.2)
    # The same seed places the same world with the defaults spelled out.
    a = World(WorldConfig(), np.random.default_rng(4))
    b = World(WorldConfig(pack_gap=0.3, pack_wall_clearance=0.2), np.random.default_rng(4))
    np.testing.assert_array_equal(a.pack_positions(), b.pack_positions())
    np.testing.assert_array_equal(a.data.qpos, b.data.qpos)


def pack_gaps(world: World) -> list[float]:
    """Edge-to-edge gap of every pair of packs."""
    p = world.pack_positions()
    return [
        float(np.hypot(*(p[i] - p[j]))) - 2 * C.PACK_RADIUS
        for i in range(len(p))
        for j in range(i + 1, len(p))
    ]


@pytest.mark.parametrize(("gap", "n_packs"), [(0.9, 2), (0.6, 4)])
def test_a_larger_pack_gap_spreads_the_packs(gap: float, n_packs: int) -> None:
    # Every pair of pack centres is at least 2 x PACK_RADIUS + gap apart, over many draws;
    # with the default gap the same draws bring some pair closer than that.
    wide = World(WorldConfig(n_packs=n_packs, pack_gap=gap), np.random.default_rng(0))
    narrow = World(WorldConfig(n_packs=n_packs), np.random.default_rng(0))
    closest_wide, closest_narrow = math.inf, math.inf
    for seed in range(30):
        wide.reset(np.random.default_rng(seed))
        narrow.reset(np.random.default_rng(seed))
        closest_wide = min(closest_wide, *pack_gaps(wide))
        closest_narrow = min(closest_narrow, *pack_gaps(narrow))
    assert closest_wide >= gap - 1e-9
    assert closest_narrow < gap


def test_pack_wall_clearance_keeps_the_packs_off_the_walls() -> None:
    # Pack edges at least 0.6 m from every wall: centres within ±(1.15 - 0.045 - 0.6) m.
    w = World(WorldConfig(n_packs=3, pack_wall_clearance=0.6), np.random.default_rng(0))
    limit = C.FIELD_SIZE / 2 - C.PACK_RADIUS - 0.6
    for seed in range(30):
        w.reset(np.random.default_rng(seed))
        assert np.abs(w.pack_positions()).max() <= limit + 1e-9
    assert min(pack_gaps(w)) >= 0.3 - 1e-9  # the default pack gap still holds


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        # 5 discs of radius 0.045 + 0.45 m cover 3.85 m², more than 40 % of the 5.29 m² field.
        ({"pack_gap": 0.9}, "pack_gap=0.9"),
        # Even alone with one robot, 3 such packs cover 2.31 m² > 2.12 m².
        ({"pack_gap": 0.9, "n_packs": 3, "n_robots": 1}, "pack_gap=0.9"),
        # 2 packs fit, but not with 4 robots: 1.54 + 0.32 m² fit, 1.54 + 8 x 0.08 m² do not.
        ({"pack_gap": 0.9, "n_packs": 2, "n_robots": 8}, "do not fit.*pack_gap=0.9"),
        # A 0.8 m clearance leaves the packs a 1.0 m square: 5 discs of 0.195 m cover 0.60 m²,
        # more than 40 % of 1.0 m².
        ({"pack_wall_clearance": 0.8}, "pack_wall_clearance=0.8"),
    ],
)
def test_a_pack_layout_that_cannot_be_placed_is_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match) as error:
        WorldConfig(**kwargs)
    assert "\n" not in str(error.value)


def test_max_counts_follow_the_pack_gap() -> None:
    assert max_counts(0.9)[1] == 2  # (2.116 - 0.080) m² / 0.770 m² per pack
    assert max_counts(0.9)[0] == max_counts()[0]  # robots do not depend on it
    WorldConfig(n_robots=1, n_packs=2, pack_gap=0.9)  # the largest count fits


# --- the field's size ---------------------------------------------------------------------------
def test_field_size_defaults_to_the_paper_field() -> None:
    assert WorldConfig().field_size == C.FIELD_SIZE == 2.3
    assert WorldConfig().diagonal == pytest.approx(3.2527, abs=1e-4)  # 2.3 m x sqrt(2)


@pytest.mark.parametrize("value", [0.4, 50.5, float("nan"), float("inf"), True, "2.3"])
def test_bad_field_size_names_the_field_and_its_range(value: object) -> None:
    with pytest.raises(ValueError, match=r"field_size must be a number in \[0.5, 50\]"):
        WorldConfig(field_size=value)  # type: ignore[arg-type]


def test_a_hundred_robots_fit_at_the_paper_density_not_in_the_paper_field() -> None:
    # 100 robot discs of 0.16 m cover 8.04 m², 125 pack discs of 0.195 m 14.93 m²: 22.97 m².
    # 40 % of an 11.5 m field is 52.9 m²; of the 2.3 m field, 2.12 m². The smallest field
    # holding them: sqrt(22.97 / 0.4) = 7.58 m.
    WorldConfig(field_size=11.5, n_robots=100, n_packs=125)
    assert fits(100, 125, 11.5) and not fits(100, 125, 2.3)
    assert smallest_field(100, 125) == 7.58
    assert fits(100, 125, 7.58) and not fits(100, 125, 7.57)
    with pytest.raises(ValueError) as error:
        WorldConfig(field_size=2.3, n_robots=100, n_packs=125)
    message = str(error.value)
    assert "\n" not in message
    # 125 pack discs need a 6.11 m square (37.3 m² at 40 %) plus the walls' 0.05 m margins.
    assert "n_packs=125" in message and "field_size=2.3" in message
    assert "at most 16 fit" in message and "field_size >= 7.58 m" in message


def test_robots_and_packs_that_fit_apart_name_what_fits_together() -> None:
    # 5 packs (0.597 m²) leave 2.116 - 0.597 = 1.519 m² of the 2.3 m field: 18 robots of
    # 0.0804 m²; 20 robots (1.608 m²) leave room for 4 packs of 0.1195 m².
    with pytest.raises(ValueError) as error:
        WorldConfig(n_robots=20, n_packs=5)
    message = str(error.value)
    assert message.startswith("n_robots=20 and n_packs=5 do not fit in the field_size=2.3 m")
    assert "20 robots with at most 4 packs" in message
    assert "5 packs with at most 18 robots" in message
    assert most_robots(5) == 18 and most_packs(20) == 4
    WorldConfig(n_robots=18, n_packs=5)
    WorldConfig(n_robots=20, n_packs=4)


def test_counts_are_bounded_whatever_the_field() -> None:
    WorldConfig(field_size=50.0, n_robots=MAX_ROBOTS, n_packs=MAX_PACKS)
    assert (MAX_ROBOTS, MAX_PACKS) == (200, 300)
    with pytest.raises(ValueError, match=r"n_robots must be an integer in \[1, 200\]"):
        WorldConfig(field_size=50.0, n_robots=201)
    with pytest.raises(ValueError, match=r"n_packs must be an integer in \[0, 300\]"):
        WorldConfig(field_size=50.0, n_packs=301)


def test_walls_floor_and_top_camera_follow_the_field() -> None:
    paper = World(WorldConfig())
    wide = World(WorldConfig(field_size=4.6, n_packs=1))
    m = paper.model
    # The paper's field is the arena file's, number for number.
    assert m.geom("wall_north").pos.tolist() == [0.0, 1.2, 0.1]
    assert m.geom("wall_east").size.tolist() == [0.05, 1.25, 0.1]
    assert m.geom("floor").size.tolist()[:2] == [1.25, 1.25]
    assert m.cam("top_down").pos.tolist() == [0.0, 0.0, 3.0]
    # A 4.6 m field: each wall moves out by 1.15 m and grows as much, keeping its thickness.
    w = wide.model
    np.testing.assert_allclose(w.geom("wall_north").pos, [0.0, 2.35, 0.1])
    np.testing.assert_allclose(w.geom("wall_south").pos, [0.0, -2.35, 0.1])
    np.testing.assert_allclose(w.geom("wall_east").pos, [2.35, 0.0, 0.1])
    np.testing.assert_allclose(w.geom("wall_west").size, [0.05, 2.4, 0.1])
    np.testing.assert_allclose(w.geom("wall_north").size, [2.35, 0.05, 0.1])
    np.testing.assert_allclose(w.geom("floor").size[:2], [2.4, 2.4])
    np.testing.assert_allclose(w.cam("top_down").pos, [0.0, 0.0, 6.0])
    # A robot driving east stops at the east wall's inner face, x = 2.3 m.
    wide.set_robot_pose(0, 1.5, 0.0, 0.0)
    mujoco.mj_forward(wide.model, wide.data)
    for _ in range(60):
        wide.set_wheel_speeds(np.full(4, 0.5), np.full(4, 0.5))
        wide.step(24)
    front = wide.data.geom_xpos[wide.teeth_geom[0], 0]
    assert 2.1 < front < 2.3


def test_placement_fills_a_large_field() -> None:
    w = World(WorldConfig(field_size=11.5, n_robots=100, n_packs=125), np.random.default_rng(2))
    robots, packs = w.poses()[:, :2], w.pack_positions()
    assert np.abs(robots).max() <= 5.75 - CR.body_radius
    assert np.abs(packs).max() <= 5.75 - C.PACK_RADIUS - 0.2
    assert np.abs(robots).max() > 4.0  # spread over the field, not the paper's 2.3 m
    pts = np.vstack([robots, packs])
    gaps = np.hypot(*(pts[:, None] - pts[None, :]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= 2 * C.PACK_RADIUS


def test_a_hundred_robots_get_their_arena_without_a_pile_at_construction() -> None:
    w = World(WorldConfig(field_size=11.5, n_robots=100, n_packs=125), np.random.default_rng(0))
    assert w.data.narena == 100 * 2**20  # 1 MB per robot
    assert w.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT == 0
    w.step(100)
    assert w.data.ncon == 4 * 100  # the contacts are on: at rest, four per robot
    w.set_wheel_speeds(np.full(100, 1.0), np.full(100, 0.8))
    w.step(240)
    assert w.data.warning[mujoco.mjtWarning.mjWARN_CNSTRFULL].number == 0
