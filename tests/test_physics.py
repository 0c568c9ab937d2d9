"""Physics of the robot, each quantity measured in simulation (not computed from formulas)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent import constants as C
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.world import World, WorldConfig

INNER_WALL = C.FIELD_SIZE / 2  # x of the east wall's inner face

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()
#: Its range sensors as (name, bearing in degrees, range in metres).
RANGE_ROWS = [(row.name, row.bearing_deg, row.limit) for row in CR.range_sensors]


def lone_robot(x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> World:
    w = World(WorldConfig(n_robots=1, n_packs=0), np.random.default_rng(0))
    w.set_robot_pose(0, x, y, yaw)
    mujoco.mj_forward(w.model, w.data)
    w.step(20)  # settle on the contacts
    return w


def drive(w: World, left: float, right: float, seconds: float) -> None:
    w.set_wheel_speeds(np.array([left]), np.array([right]))
    w.step(round(seconds / w.model.opt.timestep))


@pytest.mark.parametrize("v", [0.2, 0.6, 1.0, -0.5])
def test_straight_drive_speed_within_5_percent(v: float) -> None:
    w = lone_robot(x=-0.8 * math.copysign(1, v))
    drive(w, v, v, 0.5)  # accelerate
    start = w.poses()[0].copy()
    drive(w, v, v, 0.5)
    end = w.poses()[0]
    speed = np.hypot(*(end[:2] - start[:2])) / 0.5
    assert speed == pytest.approx(abs(v), rel=0.05)
    assert abs(end[1]) < 0.01  # and straight: no sideways drift
    assert abs(math.remainder(end[2], math.tau)) < 0.02


@pytest.mark.parametrize("v", [0.1, 0.4])
def test_spin_in_place_yaw_rate(v: float) -> None:
    w = lone_robot()
    drive(w, -v, v, 0.5)
    yaw0 = w.poses()[0, 2]
    drive(w, -v, v, 0.25)
    yaw1 = w.poses()[0, 2]
    rate = math.remainder(yaw1 - yaw0, math.tau) / 0.25
    assert rate == pytest.approx(v / CR.half_wheel_base, rel=0.05)
    assert np.hypot(*w.poses()[0, :2]) < 0.01  # in place


def test_top_speed_is_capped() -> None:
    w = lone_robot(x=-1.0)
    drive(w, 5.0, 5.0, 0.5)
    start = w.poses()[0].copy()
    drive(w, 5.0, 5.0, 0.5)
    speed = np.hypot(*(w.poses()[0, :2] - start[:2])) / 0.5
    assert speed <= CR.top_speed
    assert speed > 0.95 * CR.top_speed  # capped, not crippled


def test_no_tipping_over_ten_minutes_of_random_driving_with_pileups() -> None:
    """4 robots, 10 simulated minutes: random driving, charges at each other and the walls."""
    w = World(WorldConfig(n_robots=4, n_packs=5), np.random.default_rng(7))
    rng = np.random.default_rng(123)
    dt = w.model.opt.timestep
    steps_per_command = round(0.5 / dt)
    min_up = 1.0
    robot_robot = robot_wall = 0
    walls = {mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in C.WALL_GEOMS}
    for k in range(int(600 / 0.5)):
        if k % 8 < 4:  # random driving, full speed range, forwards and backwards
            left, right = rng.uniform(-CR.top_speed, CR.top_speed, size=(2, 4))
        else:  # everyone charges at the centre at top speed: pile-ups
            pose = w.poses()
            err = np.arctan2(-pose[:, 1], -pose[:, 0]) - pose[:, 2]
            turn = np.clip(2.0 * np.arctan2(np.sin(err), np.cos(err)), -1, 1)
            left, right = CR.top_speed * (1 - turn), CR.top_speed * (1 + turn)
        w.set_wheel_speeds(left, right)
        for _ in range(steps_per_command // 5):
            w.step(5)
            min_up = min(min_up, float(w.uprightness().min()))
            g = w.data.contact.geom
            owner = w.geom_robot[g]
            robot_robot += int(
                np.sum((owner[:, 0] >= 0) & (owner[:, 1] >= 0) & (owner[:, 0] != owner[:, 1]))
            )
            robot_wall += int(sum(1 for a, b in g if a in walls or b in walls))
    assert min_up > 0.9
    assert robot_robot > 0 and robot_wall > 0  # the test really contained collisions
    assert np.all(np.abs(w.poses()[:, :2]) < INNER_WALL)  # nobody left the field


@pytest.mark.parametrize("k", range(CR.n_range))
def test_rangefinder_reads_true_wall_distance(k: int) -> None:
    """Sensor k, turned to face the east wall at a known distance, reads it within 1 cm."""
    name, bearing_deg, max_range = RANGE_ROWS[k]
    w = lone_robot(yaw=-math.radians(bearing_deg))
    site = mujoco.mj_name2id(w.model, mujoco.mjtObj.mjOBJ_SITE, C.robot_prefix(0) + name)
    for true_distance in (0.5 * max_range, 0.9 * max_range):
        # Move the robot so that the sensor sits at the wanted distance from the wall.
        sx = w.data.site_xpos[site, 0]
        pose = w.poses()[0]
        w.set_robot_pose(0, pose[0] + (INNER_WALL - true_distance) - sx, 0.0, pose[2])
        mujoco.mj_forward(w.model, w.data)
        # The true distance, from the sensor's pose in the simulation (the ray is horizontal
        # and along +x up to the robot's settled sub-millimetre pitch).
        axis = w.data.site_xmat[site].reshape(3, 3)[:, 2]
        truth = (INNER_WALL - w.data.site_xpos[site, 0]) / axis[0]
        assert truth == pytest.approx(true_distance, abs=0.005)
        assert w.range_readings()[0, k] == pytest.approx(truth, abs=0.01)
    # Beyond its range the sensor reads its "nothing in range" value: its range.
    pose = w.poses()[0]
    shift = (INNER_WALL - (max_range + 0.1)) - w.data.site_xpos[site, 0]
    w.set_robot_pose(0, pose[0] + shift, 0.0, pose[2])
    mujoco.mj_forward(w.model, w.data)
    assert w.range_readings()[0, k] == max_range


def test_rangefinder_sees_other_robots_but_not_itself() -> None:
    w = World(WorldConfig(n_robots=2, n_packs=0), np.random.default_rng(0))
    w.set_robot_pose(0, 0.0, 0.0, 0.0)
    w.set_robot_pose(1, 0.5, 0.0, math.pi)  # robot 1 faces robot 0, 0.5 m centre to centre
    mujoco.mj_forward(w.model, w.data)
    r = w.range_readings()
    # Front sensor of robot 0 sits at x=0.111; robot 1's face (its front) is at 0.5-0.134 (teeth).
    assert 0.2 < r[0, 0] < 0.3
    # The side and back sensors see nothing of the robot's own body or wheels.
    assert r[0, 5] == RANGE_ROWS[5][2] and r[0, 6] == RANGE_ROWS[6][2]


# --- knocks between two robots (design §9.35) --------------------------------------------------
#: m/s: below this striker speed no knock can tip the robot over a side edge (its kinetic energy
#: is less than the 0.72 J the lift over the edge needs, design §9.35).
NO_FLIP_SPEED = 0.91
HEAD_ON = ("head0", "head4", "head8", "head12", "still0")


def test_no_flip_in_knocks_below_what_the_body_allows() -> None:
    """Two robots driven into each other: no knock below 0.91 m/s may tip one past 60 deg,
    whatever the angle, and no head-on knock at any speed up to the top speed (1.3 m/s each:
    the robots ride up or stop). 400 random head-on encounters as well. The published model
    (teeth that touch robots) flips in two of those encounters, so the scene can see a flip."""
    from benchmarks.flip_scene import CASES, VARIANTS, encounter, make_world, run_case, sweep

    config = WorldConfig(field_size=6.0, n_robots=2, n_packs=0)
    world = make_world(VARIANTS["base"], config)
    speeds = (0.3, 0.6, 0.9, 1.1, 1.3)
    worst = {
        (case.name, v): run_case(world, case, v).min_up
        for case in CASES
        for v in speeds
        if v < NO_FLIP_SPEED or case.name in HEAD_ON
    }
    assert min(worst.values()) > 0.5, {k: round(u, 2) for k, u in worst.items() if u <= 0.5}
    assert sweep(VARIANTS["base"], 400)["past_60"] == 0

    published = make_world(VARIANTS["published"], config)
    flipped = sweep(VARIANTS["published"], 400)["flips"]
    assert len(flipped) == 2
    for f in flipped:  # replayed one by one: each tips the published model, not the shipped one
        knock = (f["offset_m"], f["phi_deg"], f["speed"], f["shift_m"])
        assert encounter(published, *knock)[0] < 0.5
        assert encounter(world, *knock)[0] > 0.5
