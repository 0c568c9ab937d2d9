"""Survival rules: hand-computed energy arithmetic, recharge stopping rules, reflex, validation.

Docking here is real (the robot drives its teeth into a pack); the arithmetic after the capture
is checked against numbers worked out by hand from the paper's rules (Table 1, docs/design.md §5).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import RechargeEnd, SurvivalConfig, SurvivalWorld
from cyber_rodent.world import WorldConfig

FORWARD = np.array([[0.4, 0.4]])
STOP = np.zeros((1, 2))
NO = np.zeros(1, dtype=bool)
YES = np.ones(1, dtype=bool)

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()


def lone_robot(config: SurvivalConfig | None = None, n_packs: int = 1) -> SurvivalWorld:
    """One robot at (-0.5, 0) facing +x; if there is a pack, it sits at the origin."""
    sw = SurvivalWorld(WorldConfig(n_robots=1, n_packs=n_packs), config)
    place_lone_robot(sw)
    return sw


def place_lone_robot(sw: SurvivalWorld) -> None:
    w = sw.world
    if sw.n_packs:
        w.set_pack_position(0, 0.0, 0.0)
        sw.refresh_pack_positions()
    w.set_robot_pose(0, -0.5, 0.0, 0.0)
    mujoco.mj_forward(w.model, w.data)


def drive_until_docked(sw: SurvivalWorld, max_steps: int = 30) -> int:
    for k in range(max_steps):
        ev = sw.step(FORWARD, NO, NO, YES)
        if ev.docked[0]:
            return k
    raise AssertionError("robot did not dock")


def test_defaults_are_the_papers_numbers():
    cfg = SurvivalConfig()
    assert (cfg.initial_energy, cfg.max_energy, cfg.energy_decay) == (100, 200, 1)
    assert (cfg.recharge_rate, cfg.max_recharge_steps) == (5, 40)
    # Our readings where the paper is silent (docs/design.md §9, docs/calibration.md).
    assert cfg.control_dt == 0.2 and (cfg.reflex_min_steps, cfg.reflex_max_steps) == (2, 4)
    assert (cfg.mate_angle_deg, cfg.mate_distance, cfg.mate_consecutive_steps) == (15, 0.35, 2)
    assert cfg.mate_reflex and cfg.capture_rule == "docking"


def test_control_step_is_0_2_s_of_physics_substeps():
    sw = lone_robot(n_packs=0)
    assert sw.n_substeps == 24
    assert sw.n_substeps * sw.world.model.opt.timestep == pytest.approx(0.2)
    t0 = sw.world.time
    sw.step(STOP, NO, NO, YES)
    assert sw.world.time == pytest.approx(t0 + 0.2)


def test_death_at_step_100_from_100_without_charging():
    sw = lone_robot(n_packs=0)
    deaths = []
    for step in range(1, 106):
        ev = sw.step(STOP, NO, NO, YES)
        if ev.died[0]:
            deaths.append(step)
        if step == 99:
            assert sw.energy[0] == 1.0 and sw.alive[0]
    assert deaths == [100]  # reported once, at the step energy reaches 0
    assert sw.energy[0] == 0.0 and not sw.alive[0]


def test_dead_robot_stands_still_until_revived():
    sw = lone_robot(n_packs=0)
    sw.set_energy(0, 1.0)
    ev = sw.step(STOP, NO, NO, YES)
    assert ev.deaths() == [0]
    x0 = sw.world.poses()[0].copy()
    for _ in range(5):
        sw.step(FORWARD, YES, NO, YES)
    assert np.allclose(sw.world.poses()[0, :2], x0[:2], atol=2e-3)
    assert not sw.world.led_on[0]  # a dead robot's LED is dark
    sw.set_energy(0, 100.0)
    assert sw.alive[0]
    for _ in range(5):
        sw.step(FORWARD, NO, NO, YES)
    assert sw.world.poses()[0, 0] > x0[0] + 0.05
    assert sw.energy[0] == 95.0


def test_recharging_from_190_stops_at_200():
    sw = lone_robot()
    drive_until_docked(sw)
    sw.set_energy(0, 190.0)
    ev = sw.step(FORWARD, NO, NO, YES)  # recharge step 1: 190 + 5
    assert sw.energy[0] == 195.0 and sw.docked[0] and not ev.recharge_ended[0]
    assert sw.recharge_steps[0] == 1
    ev = sw.step(FORWARD, NO, NO, YES)  # recharge step 2: 200 = full -> ends
    assert sw.energy[0] == 200.0
    assert ev.recharge_ends() == [(0, RechargeEnd.FULL)]
    assert not sw.docked[0]
    ev = sw.step(FORWARD, NO, NO, YES)  # free again: pays the step
    assert sw.energy[0] == 199.0


def test_recharge_is_capped_at_40_steps():
    # With rate 2 the energy cannot fill up in 40 steps: 100 + 40 x 2 = 180 < 200.
    sw = lone_robot(SurvivalConfig(recharge_rate=2.0))
    drive_until_docked(sw)
    sw.set_energy(0, 100.0)
    ends = []
    for k in range(1, 46):
        ev = sw.step(FORWARD, NO, NO, YES)
        if ev.recharge_ended[0]:
            ends.append((k, RechargeEnd(int(ev.recharge_end_reason[0])), sw.energy[0]))
            break
        assert sw.recharge_steps[0] == k
    assert ends == [(40, RechargeEnd.MAX_STEPS, 180.0)]


def test_stop_decision_ends_recharge_before_the_step():
    sw = lone_robot()
    drive_until_docked(sw)
    sw.set_energy(0, 50.0)
    for _ in range(3):
        sw.step(FORWARD, NO, NO, YES)  # 50 -> 55 -> 60 -> 65
    ev = sw.step(FORWARD, NO, NO, NO)  # stop: no gain, the step costs 1
    assert ev.recharge_ends() == [(0, RechargeEnd.DECISION)]
    assert sw.energy[0] == 64.0
    assert not sw.docked[0] and sw.recharge_steps[0] == 0


def test_decay_while_recharging_gives_net_four():
    sw = lone_robot(SurvivalConfig(decay_while_recharging=True))
    drive_until_docked(sw)
    sw.set_energy(0, 100.0)
    for _ in range(3):
        sw.step(STOP, NO, NO, YES)
    assert sw.energy[0] == 112.0  # 100 + 3 x (5 - 1)


def test_reflex_rotates_then_returns_control():
    cfg = SurvivalConfig(reflex_min_steps=5, reflex_max_steps=5)
    sw = lone_robot(cfg)
    drive_until_docked(sw)
    sw.step(STOP, NO, NO, NO)  # stop at once: the reflex starts with this step
    assert sw.reflex_steps_left[0] == 4
    yaw0 = sw.world.poses()[0, 2]
    for _ in range(4):
        sw.step(FORWARD, NO, NO, YES)  # the caller's forward command is overridden
    assert sw.reflex_steps_left[0] == 0
    turned = abs((sw.world.poses()[0, 2] - yaw0 + math.pi) % (2 * math.pi) - math.pi)
    assert turned > math.radians(45)
    # The teeth no longer face the pack; under the caller's control again it drives away
    # without docking again.
    x_before = sw.world.poses()[0, :2].copy()
    for _ in range(5):
        ev = sw.step(FORWARD, NO, NO, YES)
        assert not ev.docked[0]
    assert np.linalg.norm(sw.world.poses()[0, :2] - x_before) > 0.1


def test_reflex_length_and_direction_are_seeded():
    def reflexes(seed: int) -> list[tuple[int, float]]:
        sw = lone_robot()
        out = []
        for k in range(4):
            sw.reset(np.random.default_rng(seed * 100 + k))
            place_lone_robot(sw)
            drive_until_docked(sw)
            sw.step(STOP, NO, NO, NO)  # stop: the reflex is drawn and runs its first step
            length = int(sw.reflex_steps_left[0]) + 1
            yaw0 = sw.world.poses()[0, 2]
            sw.step(STOP, NO, NO, YES)
            spin = (sw.world.poses()[0, 2] - yaw0 + math.pi) % (2 * math.pi) - math.pi
            out.append((length, math.copysign(1.0, spin)))
        return out

    a, b = reflexes(3), reflexes(3)
    assert a == b
    both = a + reflexes(4) + reflexes(5)
    assert all(2 <= k <= 4 for k, _ in both)
    assert {d for _, d in both} == {-1.0, 1.0}
    assert len({k for k, _ in both}) > 1


def test_same_seed_same_trajectory_and_events():
    def run(seed: int):
        sw = SurvivalWorld(WorldConfig(n_robots=4, n_packs=5), rng=np.random.default_rng(seed))
        rng = np.random.default_rng(99)
        log = []
        for _ in range(60):
            wheels = rng.uniform(-0.6, 0.6, size=(4, 2))
            flags = rng.random((3, 4)) < 0.5
            ev = sw.step(wheels, flags[0], flags[1], flags[2])
            log.append(repr(ev))
        return sw.world.data.qpos.copy(), sw.energy.copy(), log

    q1, e1, l1 = run(5)
    q2, e2, l2 = run(5)
    q3, _, _ = run(6)
    assert np.array_equal(q1, q2) and np.array_equal(e1, e2) and l1 == l2
    assert not np.array_equal(q1, q3)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("initial_energy", -1.0),
        ("initial_energy", 0.0),
        ("max_energy", 50.0),  # < initial 100
        ("energy_decay", -1.0),
        ("recharge_rate", float("nan")),
        ("max_recharge_steps", 0),
        ("control_dt", 0.0),
        ("reflex_max_steps", 1),  # < reflex_min_steps 2
        ("reflex_wheel_speed", 2.0),
        ("dock_bearing_tolerance_deg", 0.0),
        ("mate_angle_deg", 120.0),
        ("mate_distance", -0.1),
        ("mate_consecutive_steps", 0),
    ],
)
def test_invalid_config_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(SurvivalConfig(), **{field: value})


def test_control_dt_must_be_whole_substeps():
    with pytest.raises(ValueError, match="control_dt"):
        SurvivalWorld(WorldConfig(n_robots=1, n_packs=0), SurvivalConfig(control_dt=0.105))


@pytest.mark.parametrize(
    ("wheels", "match"),
    [
        (np.array([[np.nan, 0.0]]), "wheels"),
        (np.array([[0.0, np.inf]]), "wheels"),
        (np.array([[CR.top_speed + 0.1, 0.0]]), r"wheels must be in \[-1.3, 1.3\]"),
        (np.zeros((2, 2)), r"wheels must have shape \(1, 2\)"),
    ],
)
def test_bad_wheel_commands_raise(wheels, match):
    sw = lone_robot(n_packs=0)
    with pytest.raises(ValueError, match=match):
        sw.step(wheels, NO, NO, YES)


def test_bad_flags_and_energy_raise():
    sw = lone_robot(n_packs=0)
    with pytest.raises(ValueError, match="mate"):
        sw.step(STOP, NO, np.array([np.nan]), YES)
    with pytest.raises(ValueError, match="led"):
        sw.step(STOP, np.zeros(3, dtype=bool), NO, YES)
    with pytest.raises(ValueError, match=r"energy must be in \[0, 200"):
        sw.set_energy(0, 250.0)
    with pytest.raises(ValueError, match="energy"):
        sw.set_energy(0, -1.0)


# --- run state (checkpoints) -------------------------------------------------------------------
STATE_CONFIG = SurvivalConfig(mate_consecutive_steps=3, mate_reflex=False)
#: Model fields a run changes (pack placement, docking welds, LED colours); a checkpoint saves
#: them with the physics.
RUN_MODEL_FIELDS = ("body_pos", "eq_data", "geom_rgba")


def state_scene(seed: int) -> SurvivalWorld:
    """Robot 0 in front of pack 0 (it docks); robots 1 and 2 face each other 0.3 m apart."""
    sw = SurvivalWorld(
        WorldConfig(n_robots=3, n_packs=1), STATE_CONFIG, np.random.default_rng(seed)
    )
    w = sw.world
    w.set_pack_position(0, 0.0, 0.5)
    sw.refresh_pack_positions()
    w.set_robot_pose(0, -0.5, 0.5, 0.0)
    w.set_robot_pose(1, -0.26, -0.5, 0.0)
    w.set_robot_pose(2, 0.26, -0.5, math.pi)
    mujoco.mj_forward(w.model, w.data)
    return sw


def scripted_commands(rng: np.random.Generator, k: int) -> tuple[np.ndarray, ...]:
    """Robot 0 drives into its pack, then wanders; robots 1 and 2 stand and signal Mate."""
    wheels = np.zeros((3, 2))
    wheels[0] = (0.4, 0.4) if k < 15 else rng.uniform(-0.6, 0.6, size=2)
    led = rng.random(3) < 0.5
    mate = rng.random(3) < 0.8
    continue_recharge = rng.random(3) < 0.85
    return wheels, led, mate, continue_recharge


def assert_same_state(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key, value in a.items():
        if isinstance(value, np.ndarray):
            assert value.dtype == b[key].dtype, key
            np.testing.assert_array_equal(value, b[key], err_msg=key)
        elif isinstance(value, dict) and key != "rng":
            assert_same_state(value, b[key])
        else:
            assert value == b[key], key


def test_state_and_load_state_resume_a_world_bit_identically():
    rng = np.random.default_rng(11)
    original = state_scene(0)
    # Step until the state is not a trivial one: a reflex under way and a mating streak.
    k = 0
    while not (original.reflex_steps_left[0] and original.mating.streak[1, 2]):
        original.step(*scripted_commands(rng, k))
        k += 1
        assert k < 200, "no reflex with a mating streak"
    state = original.state()
    # Plain data only: arrays, Python scalars, and dicts of those.
    for key, value in [*state.items(), *state["events"].items(), *state["rng"].items()]:
        assert isinstance(value, np.ndarray | bool | int | float | str | dict), key

    resumed = SurvivalWorld(WorldConfig(n_robots=3, n_packs=1), STATE_CONFIG)
    views = {name: getattr(resumed, name) for name in ("energy", "docked", "reflex_wheels")}
    m, d = resumed.world.model, resumed.world.data
    for name in RUN_MODEL_FIELDS:
        getattr(m, name)[...] = getattr(original.world.model, name)
    mujoco.mj_copyData(d, m, original.world.data)
    resumed.load_state(state)
    assert all(getattr(resumed, name) is view for name, view in views.items())  # in place
    assert_same_state(resumed.state(), state)

    mated = 0
    for j in range(k, k + 50):
        commands = scripted_commands(rng, j)
        a, b = original.step(*commands), resumed.step(*commands)
        assert repr(a) == repr(b)
        for name in a.ARRAYS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert_same_state(original.state(), resumed.state())
        np.testing.assert_array_equal(original.world.data.qpos, resumed.world.data.qpos)
        np.testing.assert_array_equal(original.world.data.qvel, resumed.world.data.qvel)
        np.testing.assert_array_equal(original.world.data.ctrl, resumed.world.data.ctrl)
        np.testing.assert_array_equal(original.world.model.geom_rgba, resumed.world.model.geom_rgba)
        mated += len(a.matings())
    assert mated and not original.reflex_steps_left[0]  # streaks and reflex were carried on


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda s: s.pop("energy"), r"missing keys \['energy'\]"),
        (lambda s: s.__setitem__("extra", 1), r"unknown keys \['extra'\]"),
        (lambda s: s.__setitem__("energy", np.zeros(4)), r"\['energy'\] must be a float64 array"),
        (lambda s: s.__setitem__("docked", np.zeros(3)), r"\['docked'\] must be a bool array"),
        (lambda s: s["events"].pop("died"), r"\['events'\] .*missing keys \['died'\]"),
        (lambda s: s.__setitem__("step_count", 1.5), r"\['step_count'\] must be an integer"),
        (lambda s: s.__setitem__("mid_step", 0), r"\['mid_step'\] must be true or false"),
        (lambda s: s["rng"].__setitem__("bit_generator", "MT19937"), "PCG64 generator"),
        (lambda s: s["rng"]["state"].pop("inc"), r"\['rng'\] is not a generator state"),
    ],
)
def test_load_state_refuses_a_state_that_does_not_fit(change, match):
    sw = state_scene(0)
    sw.step(*scripted_commands(np.random.default_rng(0), 0))
    state = sw.state()
    state["energy"] += 1.0
    change(state)
    before = sw.state()
    with pytest.raises(ValueError, match=match):
        sw.load_state(state)
    assert_same_state(sw.state(), before)  # nothing was written
