"""When a docking counts as a captured battery: ``SurvivalConfig.capture_rule``.

"docking" (the default) counts the docking itself; "recharge" counts only the docking's first
recharge step, so a docking whose recharge the controller stops at once is no capture
(docs/design.md §9.5). The dockings are real (a robot drives its teeth into a pack, as in
``test_survival.py``); the step numbers are worked out by hand from the rules: the recharge
decision is taken at the start of a step, "stop" ends the recharge before that step's physics.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from cyber_rodent.survival import RechargeEnd, SurvivalConfig, SurvivalWorld
from cyber_rodent.survival.events import StepEvents
from cyber_rodent.world import WorldConfig
from evolution.config import EvolutionConfig
from evolution.runner import EventKind, EvolutionRunner, RunConfig
from tests.test_evolution_runner import REACTIVE, make_genome, one_robot, place
from tests.test_survival import FORWARD, NO, STOP, YES, drive_until_docked, place_lone_robot

BACKENDS = ["numba", "numpy"]


def lone_robot(rule: str, backend: str, **config: Any) -> SurvivalWorld:
    """One robot 0.5 m in front of a pack, facing it (``test_survival.lone_robot``)."""
    sw = SurvivalWorld(
        WorldConfig(n_robots=1, n_packs=1),
        SurvivalConfig(capture_rule=rule, **config),
        backend=backend,
    )
    place_lone_robot(sw)
    return sw


def test_the_default_rule_is_the_docking_and_others_are_refused() -> None:
    assert SurvivalConfig().capture_rule == "docking"
    with pytest.raises(ValueError, match="capture_rule"):
        SurvivalConfig(capture_rule="contact")


@pytest.mark.parametrize("backend", BACKENDS)
def test_docking_rule_counts_the_docking_even_if_the_recharge_stops_at_once(backend) -> None:
    sw = lone_robot("docking", backend)
    drive_until_docked(sw)
    ev = sw.events
    assert ev.docked[0] and ev.captured[0]  # the docking step is the capture
    ev = sw.step(STOP, NO, NO, NO)  # stop before the first recharge step
    assert ev.recharge_ends() == [(0, RechargeEnd.DECISION)]
    assert not ev.captured[0]
    for _ in range(10):  # the reflex, then free driving: no capture, no docking
        ev = sw.step(FORWARD, NO, NO, YES)
        assert not ev.captured[0] and not ev.docked[0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_recharge_rule_a_docking_stopped_at_once_is_no_capture(backend) -> None:
    sw = lone_robot("recharge", backend)
    drive_until_docked(sw)
    assert sw.events.docked[0] and not sw.events.captured[0]
    ev = sw.step(STOP, NO, NO, NO)  # stop: zero recharge steps
    assert ev.recharge_ends() == [(0, RechargeEnd.DECISION)]
    assert sw.recharge_steps[0] == 0 and not ev.captured[0]
    for _ in range(10):
        ev = sw.step(FORWARD, NO, NO, YES)
        assert not ev.captured[0] and not ev.docked[0]


@pytest.mark.parametrize("backend", BACKENDS)
def test_recharge_rule_counts_the_first_recharge_step_only(backend) -> None:
    sw = lone_robot("recharge", backend)
    drive_until_docked(sw)
    sw.set_energy(0, 50.0)
    assert not sw.events.captured[0]
    captured = []
    for _ in range(3):  # recharge steps 1, 2, 3: 50 -> 55 -> 60 -> 65
        ev = sw.step(STOP, NO, NO, YES)
        captured.append(bool(ev.captured[0]))
        assert ev.any or not ev.captured[0]
    assert captured == [True, False, False]
    assert sw.energy[0] == 65.0 and sw.recharge_steps[0] == 3
    ev = sw.step(STOP, NO, NO, NO)  # stop: the docking ends, no new capture
    assert ev.recharge_ends() == [(0, RechargeEnd.DECISION)] and not ev.captured[0]


@pytest.mark.parametrize(
    ("rule", "expected"),
    [("docking", [True, False, False]), ("recharge", [False, True, False])],
)
def test_one_recharge_step_then_stop(rule, expected) -> None:
    # Steps: the docking, one recharge step (continue), then "stop" (no gain, pays the step).
    sw = lone_robot(rule, "numpy")
    drive_until_docked(sw)
    sw.set_energy(0, 50.0)
    captured = [bool(sw.events.captured[0])]
    ev = sw.step(STOP, NO, NO, YES)
    captured.append(bool(ev.captured[0]))
    assert sw.energy[0] == 55.0 and sw.recharge_steps[0] == 1
    ev = sw.step(STOP, NO, NO, NO)
    captured.append(bool(ev.captured[0]))
    assert sw.energy[0] == 54.0 and ev.recharge_ends() == [(0, RechargeEnd.DECISION)]
    assert captured == expected


@pytest.mark.parametrize("backend", BACKENDS)
def test_recharge_rule_counts_a_single_recharge_step_that_ends_the_recharge(backend) -> None:
    # max_recharge_steps=1: the first recharge step is also the last (MAX_STEPS), and its
    # release zeroes the counter; it is still a capture, on that step.
    sw = lone_robot("recharge", backend, max_recharge_steps=1)
    drive_until_docked(sw)
    ev = sw.step(STOP, NO, NO, YES)
    assert ev.recharge_ends() == [(0, RechargeEnd.MAX_STEPS)]
    assert ev.captured[0] and sw.recharge_steps[0] == 0 and not sw.docked[0]


def test_captured_is_part_of_the_events_copy_and_state() -> None:
    sw = lone_robot("docking", "numpy")
    drive_until_docked(sw)
    assert sw.events.copy().captured[0]
    state = sw.state()
    assert state["events"]["captured"][0]


def test_a_state_without_captured_loads_with_captured_equal_to_docked() -> None:
    # A state written before StepEvents.captured existed (every docking was a capture).
    sw = lone_robot("docking", "numpy")
    drive_until_docked(sw)
    state = sw.state()
    del state["events"]["captured"]
    sw.events.captured[:] = False
    sw.load_state(state)
    assert "captured" not in state["events"]  # the caller's state is not changed
    np.testing.assert_array_equal(sw.events.captured, sw.events.docked)
    assert sw.events.captured[0]
    assert "captured" in StepEvents.ARRAYS


# --- through the evolution runner: what the scheduler credits ---------------------------------
def _docking_runner(rule: str, recharge: tuple[float, float, float]) -> EvolutionRunner:
    """One robot 0.5 m in front of a pack, its agents always choose Forage
    (``test_evolution_runner._docking_runner``)."""
    g = make_genome(mate=-5.0, forage=5.0, recharge=recharge)
    cfg = one_robot(packs=1, time_sharing_steps=100)
    cfg = dataclasses.replace(cfg, survival=dataclasses.replace(cfg.survival, capture_rule=rule))
    runner = EvolutionRunner(cfg, 0, REACTIVE, [g, g])
    place(runner, {0: (-0.5, 0.0, 0.0)}, packs={0: (0.0, 0.0)})
    return runner


@pytest.mark.parametrize(("rule", "batteries"), [("docking", 1), ("recharge", 0)])
def test_a_docking_stopped_at_once_is_credited_by_the_rule(rule, batteries) -> None:
    # Recharge weights (0, 0, 1): output 1 > 0, so the agent stops on its first decision,
    # the step after docking, with zero recharge steps.
    runner = _docking_runner(rule, (0.0, 0.0, 1.0))
    while not runner.events.counts()["dock"]:
        runner.step()
        assert runner.steps < 40, "the robot did not dock"
    d = runner.steps
    for _ in range(5):  # the stop, then the reflex
        runner.step()
    rows = runner.events.array
    np.testing.assert_array_equal(
        rows[:, [0, 2, 5]],
        [[d, EventKind.DOCK, 0], [d + 1, EventKind.RECHARGE_END, RechargeEnd.DECISION]],
    )
    assert runner.scheduler.agent(0, 0).batteries == batteries


@pytest.mark.parametrize("rule", ["docking", "recharge"])
def test_a_docking_that_recharges_is_credited_once_by_either_rule(rule) -> None:
    # Recharge weights (0, 0, -1): the agent keeps recharging (40 steps at most).
    runner = _docking_runner(rule, (0.0, 0.0, -1.0))
    for _ in range(30):
        runner.step()
    assert runner.survival.docked[0] and runner.survival.recharge_steps[0] > 1
    assert runner.scheduler.agent(0, 0).batteries == 1


def recharge_steps_of_dockings(runner: EvolutionRunner) -> list[tuple[int, int, int, int]]:
    """(robot, slot, generation, recharge steps) of each docking in the runner's event log.

    A "stop" decision at step e ends the recharge before e's physics (e - d - 1 recharge
    steps after a docking at step d); a stopping rule at step e, or an agent switch at the
    end of step e, after it (e - d); a docking still open has recharged until now.
    """
    rows = runner.events.array
    out = []
    for robot in range(runner.config.evolution.n_robots):
        mine = rows[rows[:, 1] == robot]
        open_dock: np.ndarray | None = None
        for row in mine:
            step, kind = int(row[0]), int(row[2])
            if kind == EventKind.DOCK:
                assert open_dock is None
                open_dock = row
            elif kind == EventKind.RECHARGE_END:
                assert open_dock is not None
                d = int(open_dock[0])
                if row[5] == RechargeEnd.DECISION:
                    steps = step - d - 1
                else:
                    steps = step - d
                out.append((robot, int(open_dock[3]), int(open_dock[4]), steps))
                open_dock = None
        if open_dock is not None:
            d = int(open_dock[0])
            out.append((robot, int(open_dock[3]), int(open_dock[4]), runner.steps - d))
    return out


@pytest.mark.parametrize("rule", ["docking", "recharge"])
def test_agents_batteries_are_the_dockings_the_rule_counts(rule) -> None:
    # 4 robots x 2 agents that always forage, born with the full 200 energy, with a 1000-step
    # life: within 300 steps no agent dies or is replaced, so each agent's batteries are its
    # whole record. They recharge while energy / 200 - 0.75 <= 0: a docking above 150 stops
    # at once (zero recharge steps), one at 150 or below recharges; both kinds happen.
    evo = EvolutionConfig(
        population_size=8, n_robots=4, lifetime_steps=1000, time_sharing_steps=40,
        initial_energy=200.0,
    )  # fmt: skip
    survival = SurvivalConfig(initial_energy=200.0, capture_rule=rule)
    genome = make_genome(mate=-5.0, forage=5.0, recharge=(1.0, 0.0, -0.75))
    runner = EvolutionRunner(RunConfig(evolution=evo, survival=survival), 3, REACTIVE, [genome] * 8)
    for _ in range(300):
        runner.step()
    rows = runner.events.array
    assert not np.isin(rows[:, 2], [EventKind.DEATH, EventKind.BIRTH]).any()
    dockings = recharge_steps_of_dockings(runner)
    assert sum(steps == 0 for *_, steps in dockings) >= 3
    assert sum(steps >= 1 for *_, steps in dockings) >= 3
    expected = np.zeros((4, 2), dtype=np.int64)
    for robot, slot, generation, steps in dockings:
        assert generation == 0
        if rule == "docking" or steps >= 1:
            expected[robot, slot] += 1
    batteries = [[runner.scheduler.agent(r, s).batteries for s in range(2)] for r in range(4)]
    np.testing.assert_array_equal(batteries, expected)
