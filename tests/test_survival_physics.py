"""Docking and mating as physical events: scripted robots in the MuJoCo world."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.world import WorldConfig

NO1 = np.zeros(1, dtype=bool)
YES1 = np.ones(1, dtype=bool)


def pack_scene(x: float, y: float, yaw: float) -> SurvivalWorld:
    """One robot at (x, y, yaw) and one pack at the origin."""
    sw = SurvivalWorld(WorldConfig(n_robots=1, n_packs=1))
    sw.world.set_pack_position(0, 0.0, 0.0)
    sw.refresh_pack_positions()
    sw.world.set_robot_pose(0, x, y, yaw)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    return sw


def drive(sw: SurvivalWorld, left: float, right: float, steps: int) -> list[int]:
    """Drive with a fixed command; the steps (0-based) at which the robot docked."""
    dockings = []
    for k in range(steps):
        ev = sw.step(np.array([[left, right]]), NO1, NO1, YES1)
        if ev.docked[0]:
            dockings.append(k)
    return dockings


def test_teeth_into_pack_docks_recharges_and_holds_the_robot():
    sw = pack_scene(-0.5, 0.0, 0.0)
    assert len(drive(sw, 0.4, 0.4, 12)) == 1
    assert sw.docked[0] and sw.dock_pack[0] == 0
    e0 = sw.energy[0]
    pose0 = sw.world.poses()[0].copy()
    # While recharging the weld holds the robot even if the caller commands full speed.
    for _ in range(10):
        sw.step(np.array([[-1.3, 1.3]]), NO1, NO1, YES1)
    assert sw.docked[0]
    assert sw.energy[0] == e0 + 50
    assert np.linalg.norm(sw.world.poses()[0, :2] - pose0[:2]) < 5e-3
    assert abs(sw.world.poses()[0, 2] - pose0[2]) < 0.02
    # The pack stays where it is.
    assert np.allclose(sw.world.pack_positions()[0], [0.0, 0.0])


def test_after_recharging_the_robot_can_leave_and_the_pack_stays_available():
    sw = pack_scene(-0.5, 0.0, 0.0)
    drive(sw, 0.4, 0.4, 12)
    sw.step(np.zeros((1, 2)), NO1, NO1, NO1)  # stop recharging
    while sw.reflex_steps_left[0]:
        sw.step(np.zeros((1, 2)), NO1, NO1, YES1)
    # The reflex turned the teeth away from the pack: driving on leads away from it.
    gap = np.linalg.norm(sw.world.poses()[0, :2])
    assert drive(sw, 0.4, 0.4, 5) == []
    assert np.linalg.norm(sw.world.poses()[0, :2]) > gap + 0.1
    # Come back head-on to the same pack: it can be captured again.
    sw.world.set_robot_pose(0, 0.5, 0.0, math.pi)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    assert len(drive(sw, 0.4, 0.4, 12)) == 1


@pytest.mark.parametrize("approach_deg", [0, 45, 90, 135, 180, 270])
def test_docking_works_from_any_direction(approach_deg):
    a = math.radians(approach_deg)
    sw = pack_scene(-0.45 * math.cos(a), -0.45 * math.sin(a), a)
    assert len(drive(sw, 0.4, 0.4, 12)) == 1


def teeth_touch_electrode(sw: SurvivalWorld) -> bool:
    geom = sw.world.data.contact.geom
    pair = {int(sw.world.teeth_geom[0]), int(sw.world.electrode_geom[0])}
    return any({int(a), int(b)} == pair for a, b in geom)


@pytest.mark.parametrize("offset", [0.115, 0.13, -0.115, -0.15])
def test_driving_past_a_pack_does_not_dock(offset):
    # The flank passes the electrode ring (4.5 cm radius) within 0 to 3.5 cm.
    sw = pack_scene(-0.5, offset, 0.0)
    assert drive(sw, 0.4, 0.4, 25) == []
    assert sw.world.poses()[0, 0] > 0.2  # it really went past


def pack_bearing_deg(sw: SurvivalWorld) -> float:
    x, y, yaw = sw.world.poses()[0]
    return math.degrees((math.atan2(-y, -x) - yaw + math.pi) % (2 * math.pi) - math.pi)


@pytest.mark.parametrize("offset", [0.0, 0.03, -0.03])
def test_head_on_contact_is_a_capture_at_once(offset):
    sw = pack_scene(-0.5, offset, 0.0)
    for _ in range(15):
        ev = sw.step(np.array([[0.4, 0.4]]), NO1, NO1, YES1)
        if teeth_touch_electrode(sw) or ev.docked[0]:
            assert ev.docked[0]  # the first step with contact is the capture
            return
    raise AssertionError("no contact")


def test_capture_needs_contact_and_alignment():
    # Off-centre approaches: a corner of the teeth catches the electrode ring with the pack
    # 17-24° off the heading, and the robot, still pushing, may slowly pivot into alignment.
    # Whatever the contact dynamics do, a capture happens exactly when the teeth touch the
    # electrode with the pack within the 15° tolerance, and never otherwise.
    rejected = captured = 0
    for offset in (0.05, 0.06, 0.065, -0.055, -0.06, -0.065, 0.08, -0.1):
        sw = pack_scene(-0.5, offset, 0.0)
        for _ in range(30):
            ev = sw.step(np.array([[0.4, 0.4]]), NO1, NO1, YES1)
            touch, bearing = teeth_touch_electrode(sw), abs(pack_bearing_deg(sw))
            if ev.docked[0]:
                assert touch and bearing <= 15.0
                captured += 1
                break
            if touch:
                assert bearing > 15.0
                rejected += 1
    assert rejected >= 50  # many steps of electrode contact were refused as misaligned
    assert captured >= 1


def test_backing_into_a_pack_does_not_dock():
    sw = pack_scene(0.4, 0.0, 0.0)  # pack behind the robot
    assert drive(sw, -0.4, -0.4, 20) == []
    # It is pressed against the pack with its back.
    assert sw.collisions()[0]
    assert sw.world.poses()[0, 0] < 0.2


def test_spinning_with_the_side_against_a_pack_does_not_dock():
    sw = pack_scene(0.0, -0.13, 0.0)  # pack beside the left flank
    assert drive(sw, 0.05, 0.05, 3) == []
    assert drive(sw, 0.15, -0.15, 4) == []  # turn away (clockwise): side scrapes, no capture


def test_docked_robot_is_not_pushed_off_by_another():
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=1))
    w = sw.world
    w.set_pack_position(0, 0.0, 0.0)
    sw.refresh_pack_positions()
    w.set_robot_pose(0, -0.5, 0.0, 0.0)
    w.set_robot_pose(1, -0.18, 0.6, -math.pi / 2)  # will ram robot 0 from its left side
    mujoco.mj_forward(w.model, w.data)
    no, yes = np.zeros(2, dtype=bool), np.ones(2, dtype=bool)
    for _ in range(12):
        if sw.docked[0]:
            break
        sw.step(np.array([[0.4, 0.4], [0.0, 0.0]]), no, no, yes)
    assert sw.docked[0]
    p0 = w.poses()[0].copy()
    rammed = []
    for _ in range(15):  # 3 s of ramming at 0.8 m/s
        sw.step(np.array([[0.0, 0.0], [0.8, 0.8]]), no, no, yes)
        rammed.append(bool(sw.collisions()[1]))
        assert sw.docked[0]
    assert sum(rammed) >= 5  # the rammer keeps pushing (it bounces off between pushes)
    assert np.linalg.norm(w.poses()[0, :2] - p0[:2]) < 0.01


# --- mating -----------------------------------------------------------------------------------
PORT_FORWARD = 0.111  # IR port: 11.1 cm ahead of the centre, 2 cm right (cyber_rodent.xml)
PORT_RIGHT = 0.02


def facing_pair(port_distance: float, yaw_b_offset_deg: float = 0.0) -> SurvivalWorld:
    """Two robots on the x axis facing each other, IR ports ``port_distance`` apart.

    Robot 1's heading is turned by ``yaw_b_offset_deg`` about its own centre.
    """
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=0))
    # The ports are offset 2 cm to each robot's right, i.e. 4 cm apart sideways.
    along = math.sqrt(port_distance**2 - (2 * PORT_RIGHT) ** 2)
    centre_gap = along + 2 * PORT_FORWARD
    sw.world.set_robot_pose(0, -centre_gap / 2, 0.0, 0.0)
    sw.world.set_robot_pose(1, centre_gap / 2, 0.0, math.pi + math.radians(yaw_b_offset_deg))
    mujoco.mj_forward(sw.world.model, sw.world.data)
    return sw


def mate_steps(sw: SurvivalWorld, mate: tuple[bool, bool], steps: int, wheels=None) -> list:
    wheels = np.zeros((2, 2)) if wheels is None else wheels
    out = []
    for k in range(steps):
        ev = sw.step(wheels, np.array(mate), np.array(mate), np.ones(2, dtype=bool))
        out += [(k, pair) for pair in ev.matings()]
    return out


def test_pair_geometry_is_what_the_scene_says():
    sw = facing_pair(0.3)
    dist, angle = sw.ir_geometry()
    assert dist[0, 1] == pytest.approx(0.3, abs=2e-3)
    # 4 cm sideways over 29.7 cm: each port sees the other 7.7° off its axis.
    assert angle[0, 1] == pytest.approx(math.degrees(math.atan2(0.04, 0.2973)), abs=0.5)
    assert angle[1, 0] == pytest.approx(angle[0, 1], abs=0.5)


def test_facing_at_0_3_m_mate():
    # The default IR exchange needs the condition on 2 consecutive steps: the second one mates.
    sw = facing_pair(0.3)
    assert sw.config.mate_consecutive_steps == 2
    assert mate_steps(sw, (True, True), 2) == [(1, (0, 1))]


def test_facing_at_0_6_m_do_not_mate():
    sw = facing_pair(0.6)
    assert mate_steps(sw, (True, True), 5) == []


def test_40_degrees_off_axis_do_not_mate():
    sw = facing_pair(0.3, yaw_b_offset_deg=40.0)
    _, angle = sw.ir_geometry()
    assert angle[1, 0] > 30.0
    assert mate_steps(sw, (True, True), 5) == []


def test_one_robot_signalling_alone_does_not_mate():
    sw = facing_pair(0.3)
    assert mate_steps(sw, (True, False), 5) == []
    assert mate_steps(sw, (False, True), 5) == []


def test_driving_towards_each_other_mates_once_in_range():
    sw = facing_pair(1.0)
    found = mate_steps(sw, (True, True), 13, wheels=np.full((2, 2), 0.15))
    assert found, "no mating while closing in head-on"
    k, pair = found[0]
    assert pair == (0, 1)
    # Closing at 2 x 0.15 m/s from 1.0 m, the port gap first drops under 0.35 m after ~2.2 s,
    # i.e. ~11 steps of 0.2 s; it must not happen much earlier than that.
    assert 9 <= k <= 12


def test_consecutive_steps_are_required():
    cfg = SurvivalConfig(mate_consecutive_steps=3)
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=0), cfg)
    along = math.sqrt(0.3**2 - 0.04**2) + 2 * PORT_FORWARD
    sw.world.set_robot_pose(0, -along / 2, 0.0, 0.0)
    sw.world.set_robot_pose(1, along / 2, 0.0, math.pi)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    # Signalling is interrupted at step 1: the streak restarts, so the exchange is at step 4.
    pattern = [True, False, True, True, True]
    found = []
    for k, on in enumerate(pattern):
        ev = sw.step(np.zeros((2, 2)), np.zeros(2, bool), np.full(2, on), np.ones(2, bool))
        found += [(k, p) for p in ev.matings()]
    assert found == [(4, (0, 1))]


def test_a_robot_mates_with_one_partner_per_step():
    # With a wide 60° cone robot 0 faces robot 1 (0.31 m) and robot 2 (0.24 m) at once;
    # robots 1 and 2 do not face each other. The nearer pair exchanges (a one-step exchange),
    # robot 1 is left out.
    cfg = SurvivalConfig(mate_angle_deg=60, mate_consecutive_steps=1)
    sw = SurvivalWorld(WorldConfig(n_robots=3, n_packs=0), cfg)
    w = sw.world
    w.set_robot_pose(0, 0.0, 0.0, 0.0)
    w.set_robot_pose(1, 0.45, 0.17, math.pi)
    w.set_robot_pose(2, 0.42, -0.17, math.pi)
    mujoco.mj_forward(w.model, w.data)
    dist, angle = sw.ir_geometry()
    assert dist[0, 2] < dist[0, 1] <= 0.35 and max(angle[0, 1], angle[1, 0]) < 60
    ev = sw.step(np.zeros((3, 2)), np.zeros(3, bool), np.ones(3, bool), np.ones(3, bool))
    assert ev.matings() == [(0, 2)]
    assert ev.mate_partner.tolist() == [2, -1, 0]


def test_mate_reflex_turns_both_partners_away_after_an_exchange():
    cfg = SurvivalConfig(
        mate_reflex=True, reflex_min_steps=4, reflex_max_steps=8, mate_consecutive_steps=1
    )  # a one-step exchange, then a 0.8-1.6 s reflex
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=0), cfg, np.random.default_rng(3))
    along = math.sqrt(0.3**2 - 0.04**2) + 2 * PORT_FORWARD
    sw.world.set_robot_pose(0, -along / 2, 0.0, 0.0)
    sw.world.set_robot_pose(1, along / 2, 0.0, math.pi)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    assert mate_steps(sw, (True, True), 1) == [(0, (0, 1))]
    # Both start a reflex of 4..8 steps, each a spin in place at the reflex speed.
    assert all(4 <= sw.reflex_steps_left[i] <= 8 for i in range(2))
    for i in range(2):
        left, right = sw.reflex_wheels[i]
        assert left == -right and abs(left) == cfg.reflex_wheel_speed
    # While they turn they cannot mate, though both still signal Mate.
    turning = int(sw.reflex_steps_left.min())
    assert mate_steps(sw, (True, True), turning) == []
    # Without the rule the pair exchanges again on the very next step.
    plain = SurvivalWorld(
        WorldConfig(n_robots=2, n_packs=0),
        SurvivalConfig(mate_reflex=False, mate_consecutive_steps=1),
    )
    plain.world.set_robot_pose(0, -along / 2, 0.0, 0.0)
    plain.world.set_robot_pose(1, along / 2, 0.0, math.pi)
    mujoco.mj_forward(plain.world.model, plain.world.data)
    assert mate_steps(plain, (True, True), 2) == [(0, (0, 1)), (1, (0, 1))]
