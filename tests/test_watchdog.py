"""The watchdog (cyber_rodent.survival.watchdog): a hand-built jam and a hand-built flip are
found, their start and end reported, the rescue frees them (energy unchanged), the compiled
rule and its numpy reference agree, and a run logs what it saw."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.survival.watchdog import Trouble, Watchdog, free_spot
from cyber_rodent.world import WorldConfig
from evolution.config import EvolutionConfig
from evolution.runner import EvolutionRunner, RunConfig
from evolution.runner.events import EventKind


def scene(backend: str, rescue: bool = False) -> tuple[SurvivalWorld, Watchdog, np.ndarray]:
    """Two robots, no packs: robot 0 pressed nose first into the east wall, robot 1 free."""
    sw = SurvivalWorld(WorldConfig(n_robots=2, n_packs=0), SurvivalConfig(), backend=backend)
    half = sw.world.config.field_size / 2
    sw.world.set_robot_pose(0, half - 0.12, 0.0, 0.0)  # facing the wall, touching it
    sw.world.set_robot_pose(1, -0.5, 0.0, math.pi / 2)
    mujoco.mj_forward(sw.world.model, sw.world.data)
    wheels = np.zeros((2, 2))
    rules = SurvivalConfig(rescue=rescue, rescue_after_steps=10)
    dog = Watchdog(sw.world, wheels, sw.docked, sw.reflex_steps_left, rules=rules,
                   backend=backend)  # fmt: skip
    return sw, dog, wheels


def run(sw: SurvivalWorld, dog: Watchdog, wheels: np.ndarray, steps: int) -> list:
    no = np.zeros(2, dtype=bool)
    found = []
    for k in range(steps):
        sw.step(wheels, no, no, no)
        events = dog.observe()
        if events is not None:
            found.append((k + 1, events))
    return found


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_robot_driving_into_a_wall_is_stuck_after_stuck_steps(backend: str) -> None:
    """Robot 0 commands 0.3 m/s into the wall: the first step sets where its run of steps
    begins, and 25 steps later without progress (step 26) it is stuck; free again once it
    backs off. Robot 1 turns on the spot (no forward command): never stuck."""
    sw, dog, wheels = scene(backend)
    wheels[0] = (0.3, 0.3)
    wheels[1] = (-0.3, 0.3)
    found = run(sw, dog, wheels, 40)
    starts = [(k, e.stuck_started) for k, e in found if e.stuck_started]
    assert starts == [(26, [0])]
    assert dog.state.stuck_steps.tolist() == [15, 0]
    # It backs off: accelerating through the 50 ms motor lag it still covers about
    # 0.3 m/s x (0.2 s - 0.05 s) = 4.5 cm in its first step, more than stuck_progress (0.2) of
    # the 6 cm it commands: free at once.
    wheels[0] = (-0.3, -0.3)
    found = run(sw, dog, wheels, 3)
    assert [(k, e.stuck_ended) for k, e in found] == [(1, [(0, 15)])]
    assert not any(e.tip_started for _, e in found)


def pin(sw: SurvivalWorld, robot: int) -> None:
    """Hold ``robot`` where it stands as the docking hold does (its weld switched on at its
    pose), without docking it: a robot pinned by something it cannot move."""
    m, d = sw.world.model, sw.world.data
    body, weld = sw.world.chassis_body[robot], sw.docking.hold_eq[robot]
    quat = d.xquat[body]
    conj = np.array([quat[0], -quat[1], -quat[2], -quat[3]])
    relpos = np.empty(3)
    mujoco.mju_rotVecQuat(relpos, -d.xpos[body], conj)
    m.eq_data[weld, 3:6], m.eq_data[weld, 6:10] = relpos, conj  # weld row: relpos, relquat
    d.eq_active[weld] = 1


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_robot_held_while_it_turns_on_the_spot_is_stuck(backend: str) -> None:
    """Fig. 6's EE seed 19 (published model): two robots each turned in place against the
    other for 700,000 steps. Robot 1, pinned, commands a turn on the spot at 0.2 m/s (no
    forward command): 25 steps without turning 0.5 rad, and it is stuck at step 26; released,
    it turns (0.2 m/s / 0.08 m = 2.5 rad/s: 0.5 rad commanded per step, of which it achieves
    more than stuck_progress, a fifth, in its first step) and is free again at once. A free
    robot turning at the slowest command that counts (0.05 m/s: 0.125 rad per step) is not."""
    sw, dog, wheels = scene(backend)
    pin(sw, 1)
    wheels[1] = (-0.2, 0.2)
    found = run(sw, dog, wheels, 30)
    assert [(k, e.stuck_started) for k, e in found if e.stuck_started] == [(26, [1])]
    sw.world.data.eq_active[sw.docking.hold_eq[1]] = 0
    found = run(sw, dog, wheels, 3)
    assert [(k, e.stuck_ended) for k, e in found if e.stuck_ended] == [(1, [(1, 5)])]
    wheels[1] = (-0.05, 0.05)
    assert all(not e.stuck_started for _, e in run(sw, dog, wheels, 60))


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_robot_that_dithers_on_the_spot_is_not_stuck(backend: str) -> None:
    """A free robot that spins left and right in turn (a greedy policy at a bearing near zero)
    turns back to where it began every other step, so it never gets 0.5 rad from it; but each
    step it achieves about a third of the 0.5 rad it commands (the motors reverse through their
    50 ms lag), more than ``stuck_progress`` (0.2), so it is moving. The same robot pinned
    achieves nothing, and is stuck after its 25th held step (its count began at 0 in the step
    before, its last free one)."""
    sw, dog, wheels = scene(backend)
    found = []
    for k in range(60):
        wheels[1] = (-0.2, 0.2) if k % 2 == 0 else (0.2, -0.2)
        found += [e for _, e in run(sw, dog, wheels, 1)]
    assert not any(e.stuck_started == [1] for e in found)
    pin(sw, 1)
    found = []
    for k in range(30):
        wheels[1] = (-0.2, 0.2) if k % 2 == 0 else (0.2, -0.2)
        found += [(k + 1, e) for _, e in run(sw, dog, wheels, 1)]
    assert [(k, e.stuck_started) for k, e in found if 1 in e.stuck_started] == [(25, [1])]


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_docked_or_idle_robot_is_never_stuck(backend: str) -> None:
    sw, dog, wheels = scene(backend)
    wheels[0] = (0.3, 0.3)
    sw.docked[0] = True  # by hand: a docked robot stands still by rule
    assert run(sw, dog, wheels, 30) == []
    sw.docked[0] = False
    sw.reflex_steps_left[0] = 50  # so does one in its reflex
    assert all(not e.stuck_started for _, e in run(sw, dog, wheels, 30))


def upside_down(sw: SurvivalWorld, robot: int, x: float, y: float) -> None:
    a = int(sw.world.root_qpos_adr[robot])
    sw.world.data.qpos[a : a + 3] = (x, y, 0.10)
    sw.world.data.qpos[a + 3 : a + 7] = (0.0, 1.0, 0.0, 0.0)  # turned by pi about x
    mujoco.mj_forward(sw.world.model, sw.world.data)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_robot_on_its_back_is_tipped_and_stays_so(backend: str) -> None:
    sw, dog, wheels = scene(backend)
    upside_down(sw, 1, -0.5, 0.0)
    found = run(sw, dog, wheels, 20)
    assert [(k, e.tip_started) for k, e in found] == [(1, [1])]
    assert dog.state.tipped_steps.tolist() == [0, 20]
    assert sw.world.uprightness()[1] < -0.99  # it cannot right itself


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_the_rescue_frees_a_jam_and_rights_a_flip(backend: str) -> None:
    """After 10 steps stuck (robot 0) or tipped (robot 1), each robot is set upright at the
    nearest free spot, at rest, facing as it did; its energy is unchanged."""
    sw, dog, wheels = scene(backend, rescue=True)
    upside_down(sw, 1, -0.5, 0.0)
    wheels[0] = (0.3, 0.3)
    sw.energy[:] = (150.0, 80.0)
    found = run(sw, dog, wheels, 40)
    rescued = [(k, e.rescued) for k, e in found if e.rescued]
    assert rescued[0] == (10, [(1, Trouble.TIPPED)])  # tipped from step 1: due at 10
    assert rescued[1] == (35, [(0, Trouble.STUCK)])  # stuck at 26: due at 35
    assert sw.world.uprightness()[1] > 0.99
    ends = [end for _, e in found for end in e.tip_ended + e.stuck_ended]
    assert (1, 10) in ends and (0, 10) in ends
    assert sw.energy[1] == pytest.approx(80.0 - 40.0)  # only the decay of its 40 steps


def test_the_free_spot_is_the_nearest_clear_one() -> None:
    """A robot's own spot when it is clear; else the first clear spot on the rings around it,
    inside the walls."""
    sw, _, _ = scene("numpy")
    assert np.allclose(free_spot(sw.world, 1), sw.world.poses()[1, :2])
    sw.world.set_robot_pose(0, -0.5, 0.1, 0.0)  # on top of robot 1
    mujoco.mj_forward(sw.world.model, sw.world.data)
    spot = free_spot(sw.world, 1)
    assert np.hypot(*(spot - sw.world.poses()[0, :2])) >= 0.28
    assert np.hypot(*(spot - sw.world.poses()[1, :2])) <= 0.30


def test_watchdog_settings_are_validated() -> None:
    with pytest.raises(ValueError, match=r"^stuck_steps must be an integer in \[1,"):
        SurvivalConfig(stuck_steps=0)
    with pytest.raises(ValueError, match=r"^tip_uprightness must be a number in \[-1, 1\]"):
        SurvivalConfig(tip_uprightness=2.0)
    assert SurvivalConfig().rescue is False  # the paper's robots were never helped


def test_a_run_logs_what_the_watchdog_saw() -> None:
    """A runner whose robot 0 is turned on its back: TIPPED in the event log, the summary
    names the robot, and the per-generation table counts it; with the rescue, RESCUE too."""
    evo = EvolutionConfig(population_size=8, lifetime_steps=60, time_sharing_steps=15)
    for rescue in (False, True):
        config = RunConfig(evolution=evo)
        config = config.replace(survival=config.survival.__class__(
            **{**config.survival.__dict__, "rescue": rescue}))  # fmt: skip
        with EvolutionRunner(config, 1, BehaviourPolicies.load_default(),
                             backend="numpy") as runner:  # fmt: skip
            runner.step()
            upside_down(runner.survival, 0, *runner.world.poses()[0, :2])
            for _ in range(40):
                runner.step()
            rows = runner.events.array
            tipped = rows[rows[:, 2] == EventKind.TIPPED]
            assert tipped[:, 1].tolist()[:1] == [0]
            summary = runner.summary()
            assert summary["tips"] >= 1 and 0 in summary["troubled_robots"]
            rescues = rows[rows[:, 2] == EventKind.RESCUE]
            assert (len(rescues) > 0) == rescue
            table = runner.events.watchdog([runner.steps])
            assert table[0]["tips"] == summary["tips"] and table[0]["robots"] >= 1


def test_the_compiled_rule_matches_its_reference() -> None:
    """Random poses, commands and flags over 400 steps (small moves, so runs of steps without
    progress happen): counters, anchors and change codes equal, bit for bit."""
    from cyber_rodent.survival.watchdog_kernels import (
        WatchInputs,
        WatchRules,
        WatchState,
        watch,
        watch_reference,
    )

    rng = np.random.default_rng(8)
    n, bodies = 7, 9
    rules = WatchRules(0.5, 5, 0.05**2, math.cos(0.5), 0.05, 4, 0.2, 0.2, 0.08)
    states = [
        WatchState(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
                   np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)),
                   np.zeros((n, 2), np.int64), np.zeros(n, np.int64))
        for _ in range(2)
    ]  # fmt: skip
    xmat, xpos = np.zeros((bodies, 9)), np.zeros((bodies, 3))
    yaw = rng.uniform(-math.pi, math.pi, bodies)
    chassis = np.arange(1, n + 1, dtype=np.int64)
    changes = 0
    for _ in range(400):
        xmat[:, 8] = np.where(rng.random(bodies) < 0.1, rng.uniform(-1, 0.6, bodies), 1.0)
        xpos[:, :2] += rng.normal(0, 0.01, (bodies, 2))
        yaw += rng.normal(0, 0.15, bodies)  # turning: sometimes 0.5 rad within a few steps
        xmat[:, 0], xmat[:, 3] = np.cos(yaw) * xmat[:, 8], np.sin(yaw) * xmat[:, 8]
        inputs = WatchInputs(
            xmat, xpos, chassis, rng.choice([0.0, 0.3, -0.3, 0.04], (n, 2)), rng.random(n) < 0.1,
            np.where(rng.random(n) < 0.1, 2, 0).astype(np.int64), rng.random(n) < 0.9,
        )  # fmt: skip
        a = watch(rules, inputs, states[0])
        b = watch_reference(rules, inputs, states[1])
        assert a == b
        for name in WatchState._fields:
            np.testing.assert_array_equal(getattr(states[0], name), getattr(states[1], name))
        changes += int(a)
    assert 20 < changes < 400
