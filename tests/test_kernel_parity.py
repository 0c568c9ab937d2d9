"""Every per-step kernel against its numpy reference, on shared scenes (``conftest.py``).

Each rule of the hot path exists twice, with one signature: a compiled kernel and a numpy
reference (``docs/design.md`` §3). Here each pair runs on the same inputs and must give the
same outputs: bit for bit where both do the same arithmetic, to rounding where numpy's small
matrix products may round the last bit differently (the geometric front, the controller's
activations), with every decision equal. Each test also checks that its inputs exercised what
it is about (targets seen and hidden, every behaviour chosen, recharges continued and
stopped), so that it cannot pass vacuously.
"""

from __future__ import annotations

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from behaviours.kernels import (
    OK,
    BehaviourInputs,
    InputBuffers,
    InputRules,
    RangeSensors,
    greedy_commands,
    greedy_commands_reference,
    map_inputs,
    map_inputs_reference,
)
from cyber_rodent.commands import COMMAND_SPEEDS
from cyber_rodent.constants import PROXIMITY_SIX
from cyber_rodent.vision import BATTERY, FACE, LED
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.kernels import NearestTargets
from cyber_rodent.world import World
from evolution.kernels import (
    Act,
    ActionBuffers,
    ControllerBuffers,
    ControllerRules,
    Decide,
    Perceive,
    RobotState,
    ScheduleRules,
    SlotCounters,
    StepOutcome,
    decide,
    decide_reference,
    sense_decide_act,
    sense_decide_act_reference,
    steer,
    steer_reference,
    tick,
    tick_reference,
)
from tests.conftest import Scenes

PROXIMITY = np.asarray(PROXIMITY_SIX, dtype=np.int64)


def _copy(buffers: tuple) -> tuple:
    """A deep copy of a named tuple of arrays (nested named tuples included)."""
    return type(buffers)(
        *(_copy(b) if isinstance(b, tuple) else np.copy(b) if isinstance(b, np.ndarray) else b
          for b in buffers)
    )  # fmt: skip


def _assert_equal(a: tuple, b: tuple) -> None:
    for name, x, y in zip(a._fields, a, b, strict=True):
        if isinstance(x, tuple):
            _assert_equal(x, y)
        else:
            np.testing.assert_array_equal(x, y, err_msg=name)


def _inputs(n: int) -> InputBuffers:
    return InputBuffers(
        proximity=np.zeros((n, 6)),
        norm_bearing=np.zeros((n, 3)),
        norm_distance=np.zeros((n, 3)),
        behaviour=BehaviourInputs(
            mate=np.zeros((n, 2)),
            forage=np.zeros((n, 2)),
            search=np.zeros((n, 2)),
            mate_available=np.zeros(n, dtype=bool),
            forage_available=np.zeros(n, dtype=bool),
        ),
    )


def _sensors(world: World, raw: np.ndarray) -> RangeSensors:
    return RangeSensors(
        raw=raw,
        range_max=world.range_max,
        ranges=np.zeros_like(raw),
        proximity_columns=PROXIMITY,
        proximity_max=np.ascontiguousarray(world.range_max[:, PROXIMITY]),
    )


RULES = InputRules(3.25, LED, FACE, BATTERY)


# --- vision ------------------------------------------------------------------------------------
def test_geometric_vision_kernels_match_their_references(
    scene_world: World, scenes: Scenes
) -> None:
    """gather, front and nearest (MuJoCo's mj_ray from compiled code vs through ctypes)."""
    compiled = GeometricVision(scene_world, backend="numba")
    reference = GeometricVision(scene_world, backend="numpy")
    n = scene_world.config.n_robots
    seen = hidden = 0
    for _ in scenes(60):
        out_c, out_r = compiled.nearest_targets(), reference.nearest_targets()
        fc, fr = compiled.front, reference.front
        for name in ("cam", "rot", "centre", "gmat", "candidate", "sample_ok"):
            np.testing.assert_array_equal(getattr(fc, name), getattr(fr, name), err_msg=name)
        for name in ("bearing", "distance", "half_angle", "local", "rays"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=0, atol=1e-12)
        for name in ("width_px", "height_px", "full_area"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=1e-11, atol=0)
        np.testing.assert_array_equal(out_c.visible, out_r.visible)
        np.testing.assert_allclose(out_c.distance, out_r.distance, rtol=0, atol=1e-12)
        np.testing.assert_allclose(out_c.bearing, out_r.bearing, rtol=0, atol=1e-12)
        seen += int(out_c.visible.sum())
        hidden += int((fc.candidate.any(axis=1) & ~out_c.visible.any(axis=1)).sum())
    assert seen > 20 * n  # targets were seen ...
    assert hidden > 0  # ... and a robot's candidates were all hidden (rays decided something)


# --- behaviours --------------------------------------------------------------------------------
def test_map_inputs_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """Range readings (no hit, beyond range, in range) and nearest targets to inputs."""
    vision = GeometricVision(scene_world)
    n = scene_world.config.n_robots
    rng = np.random.default_rng(3)
    led_only = saturated = 0
    for _ in scenes(40):
        nearest = vision.nearest_targets()
        raw = scene_world.range_sensordata.copy()
        raw[rng.random(raw.shape) < 0.2] = -1.0  # no hit
        raw[rng.random(raw.shape) < 0.1] = 5.0  # beyond every sensor's range
        sensors_c, sensors_r = _sensors(scene_world, raw), _sensors(scene_world, raw)
        out_c, out_r = _inputs(n), _inputs(n)
        map_inputs(sensors_c, nearest, RULES, out_c)
        map_inputs_reference(sensors_r, nearest, RULES, out_r)
        _assert_equal(sensors_c, sensors_r)
        _assert_equal(out_c, out_r)
        led_only += int((nearest.visible[:, LED] & nearest.visible[:, FACE]).sum())
        saturated += int((sensors_c.ranges == scene_world.range_max).sum())
    assert led_only > 0 and saturated > 0


@pytest.mark.parametrize("size", [1, 4, 64])
def test_greedy_commands_match_their_reference(size: int) -> None:
    """The stacked greedy behaviours on random inputs, tile boundaries and bad input."""
    tables = BehaviourPolicies.load_default().tables
    assert tables is not None
    rng = np.random.default_rng(size)
    grid = np.linspace(0.0, 1.0, 41)  # exact tile boundaries
    chosen = set()
    for trial in range(200):
        draw = rng.random if trial % 2 else (lambda shape: rng.choice(grid, size=shape))
        inputs = BehaviourInputs(
            draw((size, 2)), draw((size, 2)), draw((size, 2)),
            np.ones(size, dtype=bool), np.ones(size, dtype=bool),
        )  # fmt: skip
        behaviour = rng.integers(3, size=size)
        out_c, out_r = np.full(size, -1), np.full(size, -2)
        assert greedy_commands(behaviour, inputs, tables, out_c) == OK
        assert greedy_commands_reference(behaviour, inputs, tables, out_r) == OK
        np.testing.assert_array_equal(out_c, out_r)
        chosen.update(out_c.tolist())
    assert len(chosen) >= 4  # many different commands: not one constant
    bad = BehaviourInputs(*(np.full((1, 2), np.nan),) * 3, np.ones(1, bool), np.ones(1, bool))
    for kernel in (greedy_commands, greedy_commands_reference):
        assert kernel(np.array([0]), bad, tables, np.zeros(1, dtype=np.int64)) != OK
        good = BehaviourInputs(*(np.full((1, 2), 0.5),) * 3, np.ones(1, bool), np.ones(1, bool))
        assert kernel(np.array([3]), good, tables, np.zeros(1, dtype=np.int64)) != OK


# --- evolution ---------------------------------------------------------------------------------
def _controller(n: int, weights: np.ndarray) -> ControllerBuffers:
    return ControllerBuffers(
        weights=weights,
        inputs=np.zeros((n, 12)),
        activations=np.zeros((n, 3)),
        behaviour=np.zeros(n, dtype=np.int64),
        led=np.zeros(n, dtype=bool),
        continue_recharge=np.zeros(n, dtype=bool),
    )


def test_decide_matches_its_reference() -> None:
    """The controller on random agents and inputs, hand-made exact ties included."""
    rng = np.random.default_rng(5)
    n = 4
    rules = ControllerRules(200.0, 40.0, LED, FACE, BATTERY)
    counts = np.zeros(3, dtype=int)
    kept = stopped = 0
    for trial in range(3000):
        w = rng.uniform(-1, 1, (n, 39))
        if trial % 10 == 0:  # exact ties between outputs (and zero activations)
            w[:, 3:] = np.round(w[:, 3:]) * (rng.random((n, 36)) < 0.2)
        robots = RobotState(
            rng.uniform(0, 200, n), rng.integers(0, 41, n), rng.random(n) < 0.5
        )
        perceived = _inputs(n)
        perceived.proximity[:] = rng.uniform(0, 1, (n, 6))
        perceived.norm_distance[:] = rng.uniform(0, 1, (n, 3))
        perceived.behaviour.mate_available[:] = rng.random(n) < 0.5
        perceived.behaviour.forage_available[:] = rng.random(n) < 0.5
        out_c, out_r = _controller(n, w), _controller(n, w)
        decide(rules, robots, perceived, out_c)
        decide_reference(rules, robots, perceived, out_r)
        np.testing.assert_array_equal(out_c.inputs, out_r.inputs)
        np.testing.assert_allclose(out_c.activations, out_r.activations, rtol=0, atol=1e-14)
        for name in ("behaviour", "led", "continue_recharge"):
            np.testing.assert_array_equal(getattr(out_c, name), getattr(out_r, name))
        counts += np.bincount(out_c.behaviour, minlength=3)
        kept += int(out_c.continue_recharge.sum())
        stopped += int((~out_c.continue_recharge).sum())
    assert (counts > 500).all() and kept > 500 and stopped > 500


def test_steer_matches_its_reference() -> None:
    rng = np.random.default_rng(8)
    n = 16
    dark = 0
    for _ in range(200):
        decided = _controller(n, np.zeros((n, 39)))
        decided.behaviour[:] = rng.integers(3, size=n)
        decided.led[:] = rng.random(n) < 0.5
        decided.continue_recharge[:] = rng.random(n) < 0.5
        docked = rng.random(n) < 0.3
        commands = rng.integers(len(COMMAND_SPEEDS), size=n)
        out = [
            ActionBuffers(commands.copy(), np.zeros((n, 2)), np.zeros(n, bool), np.zeros(n, bool))
            for _ in range(2)
        ]
        steer(decided, docked, COMMAND_SPEEDS, out[0])
        steer_reference(decided, docked, COMMAND_SPEEDS, out[1])
        _assert_equal(out[0], out[1])
        dark += int((decided.led & ~out[0].led).sum())
    assert dark > 0  # robots that keep recharging went dark


def test_tick_matches_its_reference() -> None:
    """The scheduler's bookkeeping on random event streams (idle robots included)."""
    rng = np.random.default_rng(6)
    n = 6
    rules = ScheduleRules(time_sharing_steps=10, lifetime_steps=30)
    counters = [
        SlotCounters(
            rng.random(n) < 0.8, np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n),
            np.zeros(n, np.int64), np.ones(n, bool),
        )  # fmt: skip
    ]
    counters.append(_copy(counters[0]))
    answers = []
    for step in range(400):
        outcome = StepOutcome(
            rng.uniform(0, 200, n), rng.random(n) < 0.01, rng.random(n) < 0.05,
            np.where(rng.random(n) < 0.02, 0, -1),
        )  # fmt: skip
        a = tick(counters[0], outcome, rules)
        b = tick_reference(counters[1], outcome, rules)
        assert a == b
        _assert_equal(counters[0], counters[1])
        answers.append(a)
        if step % 25 == 24:  # slots end: counters restart, as the slow path would do
            for c in counters:
                c.age[:] = c.time_slice[:] = 0
    assert 0 < sum(answers) < len(answers)


# --- the fused step ----------------------------------------------------------------------------
def test_sense_decide_act_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """The runner's one call per step: vision, inputs, controllers, behaviours, wheels."""
    n = scene_world.config.n_robots
    tables = BehaviourPolicies.load_default().tables
    assert tables is not None
    rng = np.random.default_rng(2)
    rules = ControllerRules(200.0, 40.0, LED, FACE, BATTERY)
    behaviours_seen = set()
    for _ in scenes(30):
        weights = rng.uniform(-1, 1, (n, 39))
        robots = RobotState(rng.uniform(1, 200, n), rng.integers(0, 40, n), scene_world.led_on)
        docked = rng.random(n) < 0.2
        calls = []
        for backend, kernel in (("numba", sense_decide_act), ("numpy", sense_decide_act_reference)):
            vision = GeometricVision(scene_world, backend=backend)
            inputs = _inputs(n)
            nearest = NearestTargets(np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3), bool))
            perceive = Perceive(
                _sensors(scene_world, scene_world.range_sensordata), nearest, RULES, inputs
            )
            decided = Decide(rules, robots, _controller(n, weights))
            action = ActionBuffers(
                np.zeros(n, np.int64), np.zeros((n, 2)), np.zeros(n, bool), np.zeros(n, bool)
            )
            act = Act(tables, docked, COMMAND_SPEEDS, action)
            assert kernel(vision.scene, perceive, decided, act) == OK
            calls.append((nearest, inputs, decided.out, action))
        (near_c, in_c, dec_c, act_c), (near_r, in_r, dec_r, act_r) = calls
        np.testing.assert_array_equal(near_c.visible, near_r.visible)
        np.testing.assert_allclose(near_c.distance, near_r.distance, rtol=0, atol=1e-12)
        np.testing.assert_allclose(in_c.norm_distance, in_r.norm_distance, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(dec_c.behaviour, dec_r.behaviour)
        np.testing.assert_array_equal(dec_c.continue_recharge, dec_r.continue_recharge)
        _assert_equal(act_c, act_r)
        behaviours_seen.update(dec_c.behaviour.tolist())
    assert len(behaviours_seen) >= 2


# --- whole runs --------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["ee", "ce"])
def test_a_run_is_the_same_on_either_backend(method: str) -> None:
    """Every kernel swapped for its reference at once (vision, inputs, controllers, behaviours,
    survival mechanics, scheduler): the same seed gives the same trajectory and events."""
    from evolution.runner import EvolutionRunner, RunConfig

    runs = []
    for backend in ("numba", "numpy"):
        runner = EvolutionRunner(RunConfig(method=method), 3, backend=backend)
        for _ in range(1500):
            runner.step()
        runs.append(runner)
    a, b = runs
    np.testing.assert_array_equal(a.world.data.qpos, b.world.data.qpos)
    np.testing.assert_array_equal(a.survival.energy, b.survival.energy)
    events = a.events.to_frame()
    assert events.equals(b.events.to_frame())
    for kind in ("dock", "mate", "recharge_end"):
        assert (events["kind"] == kind).sum() >= 3, kind


@pytest.mark.slow
@pytest.mark.parametrize("method", ["ee", "ce"])
def test_a_whole_generation_is_the_same_on_either_backend(method: str) -> None:
    """The same check over the first generation of the paper's colony (4 robots x 25 agents),
    with its statistics row."""
    from evolution.runner import EvolutionRunner, RunConfig

    runs = []
    for backend in ("numba", "numpy"):
        runner = EvolutionRunner(RunConfig(method=method), 0, backend=backend)
        runner.run(1)
        runs.append(runner)
    a, b = runs
    assert a.steps == b.steps and a.completed_generations == 1
    assert a.statistics().equals(b.statistics())
    assert a.events.to_frame().equals(b.events.to_frame())
    assert (a.events.to_frame()["kind"] == "mate").sum() >= 10
