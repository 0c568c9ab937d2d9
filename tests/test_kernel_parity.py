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

import math

import mujoco
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
from cyber_rodent.backend import Backend
from cyber_rodent.commands import COMMAND_SPEEDS
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import RechargeEnd, StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.survival import kernels as survival_kernels
from cyber_rodent.survival.energy import recharge_gain
from cyber_rodent.vision import BATTERY, FACE, LED, N_CLASSES, CameraConfig, segmentation_kernels
from cyber_rodent.vision.batch_rendering import BatchOmniRenderer
from cyber_rodent.vision.batch_rendering import kernels as view_kernels
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.kernels import NearestTargets
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import target_geometry
from cyber_rodent.world import LED_OFF_RGBA, LED_ON_RGBA, World, WorldConfig
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

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()

PROXIMITY = np.asarray(CR.proximity, dtype=np.int64)



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
    seen = hidden = skipped = 0
    for _ in scenes(60):
        out_c, out_r = compiled.nearest_targets(), reference.nearest_targets()
        np.testing.assert_array_equal(out_c.visible, out_r.visible)
        np.testing.assert_allclose(out_c.distance, out_r.distance, rtol=0, atol=1e-12)
        np.testing.assert_allclose(out_c.bearing, out_r.bearing, rtol=0, atol=1e-12)
        # The search computed positions for all targets, sizes and samples only for those it
        # reached: its positions equal the full front's, its possible targets include every
        # candidate.
        lazy = _copy(compiled.front)
        compiled.measure_targets(), reference.measure_targets()  # the full front, each backend
        fc, fr = compiled.front, reference.front
        for name in ("cam", "rot", "centre", "gmat", "candidate", "sample_ok"):
            np.testing.assert_array_equal(getattr(fc, name), getattr(fr, name), err_msg=name)
        for name in ("bearing", "distance", "local", "rays"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=0, atol=1e-12)
        for name in ("left_px", "right_px", "top_px", "bottom_px"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=1e-11, atol=0)
        for name in ("width_px", "height_px", "full_area"):
            np.testing.assert_allclose(getattr(fc, name), getattr(fr, name), rtol=1e-11, atol=0)
        for name in ("bearing", "distance", "local", "diff"):
            np.testing.assert_array_equal(getattr(lazy, name), getattr(fc, name))
        assert not (fc.candidate & ~lazy.candidate).any()
        cand = fc.candidate
        seen += int(out_c.visible.sum())
        hidden += int((fc.candidate.any(axis=1) & ~out_c.visible.any(axis=1)).sum())
        skipped += int((~cand).sum())
    assert seen > 20 * n  # targets were seen ...
    assert hidden > 0  # ... a robot's candidates were all hidden (rays decided something)
    assert skipped > 0  # ... and targets were skipped by the search


def test_merge_kernel_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """The blob-merging rule on the crowded scenes: the same targets merged, the same spreads,
    and the whole full pass equal across backends."""
    compiled = GeometricVision(scene_world, backend="numba")
    reference = GeometricVision(scene_world, backend="numpy")
    merged = spread = 0
    for _ in scenes(60):
        mc, mr = compiled.measure_targets(), reference.measure_targets()
        np.testing.assert_array_equal(compiled.merging.merged, reference.merging.merged)
        np.testing.assert_allclose(mc.blob_spread, mr.blob_spread, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(mc.visible, mr.visible)
        merged += int(compiled.merging.merged.sum())
        spread += int((mc.blob_spread > 0).sum())
        # The kernel on hand-set inputs: every seen target, every sample in view and hit.
        for vision in (compiled, reference):
            m = vision.merging
            m.seen[...] = vision.front.candidate
            m.visible_share[...] = 1.0
            m.hit_geom[...] = vision.targets.sample_geom[None, :]
        compiled._merge()
        reference._merge()
        np.testing.assert_array_equal(compiled.merging.merged, reference.merging.merged)
        np.testing.assert_allclose(
            compiled.merging.spread, reference.merging.spread, rtol=0, atol=1e-12
        )
        merged += int(compiled.merging.merged.sum())
    if scene_world.config.n_packs + scene_world.config.n_robots > 4:
        assert merged > 0 and spread > 0  # the rule merged something


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
        state=np.zeros((n, 0)),
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
            np.zeros(n, np.int64), np.ones(n, bool), rng.integers(0, 50, n),
            rng.integers(0, 50, n),
        )  # fmt: skip
    ]
    counters.append(_copy(counters[0]))
    answers = []
    for step in range(400):
        outcome = StepOutcome(
            rng.uniform(0, 200, n), rng.random(n) < 0.01, rng.random(n) < 0.05,
            np.where(rng.random(n) < 0.02, 0, -1), rng.random(n) < 0.2,
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


# --- survival ----------------------------------------------------------------------------------
def _survival_rules(sw: SurvivalWorld) -> survival_kernels.SurvivalRules:
    """The rules' scalars as ``SurvivalWorld`` gives them to its kernels."""
    cfg = sw.config
    return survival_kernels.SurvivalRules(
        inv_wheel_radius=1.0 / float(sw.world.wheel_radius),
        top_speed=float(CR.top_speed),
        recharge_gain=float(recharge_gain(cfg)),
        max_energy=float(cfg.max_energy),
        max_recharge_steps=int(cfg.max_recharge_steps),
        energy_decay=float(cfg.energy_decay),
        mate_min_energy=float(cfg.mate_min_energy),
        max_steps_code=int(RechargeEnd.MAX_STEPS),
        full_code=int(RechargeEnd.FULL),
    )


def _random_survival_state(
    sw: SurvivalWorld, rng: np.random.Generator
) -> survival_kernels.SurvivalState:
    """A random state written into ``sw``'s arrays: some robots dead, some about to die, some
    docked (a few a step from the recharge limit or from full energy), some in their reflex."""
    n, cfg = sw.n_robots, sw.config
    gain = recharge_gain(cfg)
    alive = rng.random(n) < 0.8
    docked = alive & (rng.random(n) < 0.3)
    sw.energy[:] = rng.uniform(1.0, cfg.max_energy, n)
    dying = rng.random(n) < 0.25
    sw.energy[dying] = rng.uniform(0.0, cfg.energy_decay, n)[dying] + 1e-9
    near_full = docked & (rng.random(n) < 0.5)
    sw.energy[near_full] = cfg.max_energy - gain * rng.uniform(0.0, 1.5, n)[near_full]
    sw.energy[~alive] = 0.0
    sw.alive[:] = alive
    sw.docked[:] = docked
    steps = rng.integers(0, cfg.max_recharge_steps, n)
    steps[rng.random(n) < 0.3] = cfg.max_recharge_steps - 1
    sw.recharge_steps[:] = np.where(docked, steps, 0)
    reflex = ~docked & (rng.random(n) < 0.3)
    sw.reflex_steps_left[:] = np.where(reflex, rng.integers(1, cfg.reflex_max_steps + 1, n), 0)
    sw.reflex_wheels[:] = rng.uniform(-CR.top_speed, CR.top_speed, (n, 2))
    return survival_kernels.SurvivalState(
        sw.energy, sw.recharge_steps, sw.docked, sw.alive, sw.reflex_steps_left, sw.reflex_wheels
    )


def test_survival_begin_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """Commands, LEDs and mating signals on random survival states of the crowded scenes; bad
    wheel commands refused by both with nothing written."""
    sw = SurvivalWorld(scene_world, rng=np.random.default_rng(1))
    n = sw.n_robots
    rules = _survival_rules(sw)
    rng = np.random.default_rng(12)
    led_rgba = np.stack([LED_OFF_RGBA, LED_ON_RGBA]).astype(np.float64)
    counts = dict.fromkeys(
        ("docked", "dead", "reflex", "switched", "silenced", "refused", "release"), 0
    )
    for trial in scenes(40):
        state = _random_survival_state(sw, rng)
        wheels = rng.uniform(-CR.top_speed, CR.top_speed, (n, 2))
        wheels[rng.random((n, 2)) < 0.1] = CR.top_speed  # on the limit: allowed
        if trial % 5 == 4:  # one bad wheel: NaN, infinite or beyond the limit
            bad = (np.nan, -np.inf, 1.001 * CR.top_speed)[trial % 3]
            wheels[rng.integers(n), rng.integers(2)] = bad
        # Mostly "continue": a docked robot that stops must be released first (by the world).
        continue_recharge = rng.random(n) < (0.7 if trial % 3 == 0 else 1.0)
        commands = survival_kernels.StepCommands(
            wheels, rng.random(n) < 0.5, rng.random(n) < 0.6, continue_recharge
        )
        actuation = survival_kernels.Actuation(
            ctrl=np.full((n, 2), -9.0),
            led_on=scene_world.led_on.copy(),
            geom_rgba=scene_world.model.geom_rgba.copy(),
            led_geom=np.asarray(scene_world.led_geom, dtype=np.int64),
            led_rgba=led_rgba,
        )
        flags = survival_kernels.StepFlags(*(rng.random(n) < 0.5 for _ in range(3)))
        # Every other trial with a mating threshold at half the maximum energy.
        threshold = 0.0 if trial % 2 else 0.5 * sw.config.max_energy
        trial_rules = rules._replace(mate_min_energy=threshold)
        ran = []
        for kernel in (survival_kernels.begin, survival_kernels.begin_reference):
            args = (_copy(commands), _copy(state), _copy(actuation), trial_rules, _copy(flags))
            ran.append((kernel(*args), args))
        (status_c, args_c), (status_r, args_r) = ran
        assert status_c == status_r
        for a, b in zip(args_c, args_r, strict=True):
            _assert_equal(a, b)
        if status_c != survival_kernels.BEGIN_OK:  # refused: nothing written
            counts["refused" if status_c == survival_kernels.BAD_WHEELS else "release"] += 1
            _assert_equal(args_c[2], actuation)
            _assert_equal(args_c[4], flags)
            continue
        out_actuation, out_flags = args_c[2], args_c[4]
        counts["docked"] += int(state.docked.sum())
        counts["dead"] += int((~state.alive).sum())
        counts["reflex"] += int((state.reflex_steps_left > 0).sum())
        counts["switched"] += int((out_actuation.led_on != actuation.led_on).sum())
        counts["silenced"] += int((commands.mate & state.alive & ~out_flags.mate_signal).sum())
    release = counts.pop("release")
    assert all(k >= 5 for k in counts.values()) and release >= 1, (counts, release)


def test_survival_end_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """Reflex countdown, recharge, the stopping rules, decay and deaths on random states."""
    sw = SurvivalWorld(scene_world, rng=np.random.default_rng(1))
    n = sw.n_robots
    rules = _survival_rules(sw)
    rng = np.random.default_rng(13)
    reasons = np.zeros(max(rules.max_steps_code, rules.full_code) + 1, dtype=np.int64)
    deaths = decays = 0
    for _ in scenes(60):
        state = _random_survival_state(sw, rng)
        flags = survival_kernels.StepFlags(
            state.docked.copy(), state.reflex_steps_left > 0, rng.random(n) < 0.5
        )
        outcome = survival_kernels.EnergyOutcome(
            np.full(n, -7, dtype=np.int64), np.ones(n, dtype=bool)
        )
        ran = []
        for kernel in (survival_kernels.end, survival_kernels.end_reference):
            args = (_copy(state), rules, _copy(flags), _copy(outcome))
            ran.append((kernel(*args), args))
        (counts_c, args_c), (counts_r, args_r) = ran
        assert counts_c == counts_r
        for a, b in zip(args_c, args_r, strict=True):
            _assert_equal(a, b)
        stop_reason, died = args_c[3]
        assert counts_c == (int((stop_reason != 0).sum()), int(died.sum()))
        reasons += np.bincount(stop_reason, minlength=len(reasons))
        deaths += int(died.sum())
        decays += int((state.alive & ~state.docked).sum())
    assert reasons[rules.max_steps_code] >= 5 and reasons[rules.full_code] >= 5, reasons
    assert deaths >= 5 and decays > deaths


def test_teeth_on_electrodes_matches_its_reference(scene_world: World, scenes: Scenes) -> None:
    """The contact scan on the crowded scenes with robots placed with their teeth on packs."""
    sw = SurvivalWorld(scene_world, rng=np.random.default_rng(1))
    n, n_packs = sw.n_robots, sw.n_packs
    tables = sw.docking.tables
    teeth, electrodes = scene_world.teeth_geom, scene_world.electrode_geom
    rng = np.random.default_rng(14)
    eligible = refused = 0
    for _ in scenes(40):
        packs = scene_world.pack_positions()
        for i in range(min(n, n_packs, 3)):  # teeth 17 cm from a pack's centre: touching
            yaw = rng.uniform(-math.pi, math.pi)
            x, y = packs[i] - 0.17 * np.array([math.cos(yaw), math.sin(yaw)])
            scene_world.set_robot_pose(i, x, y, yaw)
        mujoco.mj_forward(scene_world.model, scene_world.data)
        state = _random_survival_state(sw, rng)
        flags = survival_kernels.StepFlags(
            state.docked.copy(), state.reflex_steps_left > 0, np.zeros(n, dtype=bool)
        )
        geom = scene_world.data.contact.geom
        ncon = len(geom)
        padded = np.zeros((ncon + 4, 2), dtype=np.int32)
        padded[:ncon] = geom
        if n_packs:  # a teeth-electrode pair past the contacts: never read
            padded[ncon:] = (teeth[0], electrodes[0])
        contacts = survival_kernels.ContactScan(
            padded, np.array([ncon], dtype=np.int64), np.full((ncon + 4, 2), -5, dtype=np.int64)
        )
        ran = []
        for kernel in (
            survival_kernels.teeth_on_electrodes,
            survival_kernels.teeth_on_electrodes_reference,
        ):
            args = (_copy(contacts), tables, _copy(state), _copy(flags))
            ran.append((kernel(*args), args))
        (k_c, args_c), (k_r, args_r) = ran
        assert k_c == k_r
        for a, b in zip(args_c, args_r, strict=True):
            _assert_equal(a, b)
        touching = (np.isin(geom[:, 0], teeth) & np.isin(geom[:, 1], electrodes)) | (
            np.isin(geom[:, 1], teeth) & np.isin(geom[:, 0], electrodes)
        )
        eligible += k_c
        refused += int(touching.sum()) - k_c
    if n_packs:
        assert eligible >= 5 and refused >= 5, (eligible, refused)
    else:
        assert eligible == refused == 0


# Scripted survival worlds: robots that seek packs, seek each other and wander.
SEEK_PACK, SEEK_ROBOT, WANDER = 0, 1, 2
#: Net +4 per recharge step: a robot that docks with less than 40 reaches the step limit first.
#: A hungrier world than the default (decay 1.5 per step), so that robots die often enough, and
#: without the reflex after mating, so that partners left facing mate again: every rule of the
#: kernels fires many times (the reflex after mating is not a kernel; see
#: tests/test_survival_physics.py).
SURVIVAL_CONFIG = SurvivalConfig(
    decay_while_recharging=True, energy_decay=1.5, mate_reflex=False, mate_consecutive_steps=1
)
#: Below this energy a scripted robot seeks a pack whatever its mode.
HUNGRY = 20.0


def _survival_world(backend: Backend, seed: int = 3) -> SurvivalWorld:
    world = World(WorldConfig(), np.random.default_rng(seed))
    return SurvivalWorld(world, SURVIVAL_CONFIG, np.random.default_rng(seed), backend=backend)


def _steer_to(pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Wheel speeds that turn towards ``target`` and drive on once roughly facing it."""
    x, y, yaw = pose
    error = (math.atan2(target[1] - y, target[0] - x) - yaw + math.pi) % (2 * math.pi) - math.pi
    forward = 0.35 * max(math.cos(error), 0.0) ** 4
    turn = float(np.clip(0.4 * error, -0.3, 0.3))
    return forward - turn, forward + turn


def _scripted_commands(
    sw: SurvivalWorld, mode: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, ...]:
    """The scripted robots' commands, from the world's state and ``rng``."""
    n = sw.n_robots
    poses = sw.world.poses()
    packs = sw.world.pack_positions()
    wheels = np.zeros((n, 2))
    noise = rng.uniform(-0.05, 0.05, size=(n, 2))
    wander = rng.uniform(-CR.top_speed, CR.top_speed, size=(n, 2))
    for i in range(n):
        if mode[i] == SEEK_PACK or sw.energy[i] < HUNGRY:
            near = packs[np.argmin(np.linalg.norm(packs - poses[i, :2], axis=1))]
            wheels[i] = _steer_to(poses[i], near)
        elif mode[i] == SEEK_ROBOT:
            others = np.delete(np.arange(n), i)
            gaps = np.linalg.norm(poses[others, :2] - poses[i, :2], axis=1)
            wheels[i] = _steer_to(poses[i], poses[others[np.argmin(gaps)], :2])
        else:
            wheels[i] = wander[i]
    wheels = np.clip(wheels + noise, -CR.top_speed, CR.top_speed)
    led = rng.random(n) < 0.5
    mate = mode == SEEK_ROBOT
    continue_recharge = rng.random(n) < 0.985
    return wheels, led, mate, continue_recharge


def _assert_same_survival(a: SurvivalWorld, b: SurvivalWorld) -> None:
    np.testing.assert_array_equal(a.world.data.qpos, b.world.data.qpos)
    np.testing.assert_array_equal(a.world.data.qvel, b.world.data.qvel)
    np.testing.assert_array_equal(a.world.data.ctrl, b.world.data.ctrl)
    for name in ("energy", "recharge_steps", "docked", "dock_pack", "reflex_steps_left", "alive"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in StepEvents.ARRAYS:
        np.testing.assert_array_equal(getattr(a.events, name), getattr(b.events, name), name)
    assert a.events.any == b.events.any
    np.testing.assert_array_equal(a.world.led_on, b.world.led_on)
    np.testing.assert_array_equal(a.world.model.geom_rgba, b.world.model.geom_rgba)


def test_compiled_mechanics_equal_numpy() -> None:
    """Whole survival worlds on either backend, given the same commands: scripted robots dock,
    end recharges, die and mate many times, with the same trajectory, events and state."""
    compiled, reference = _survival_world("numba"), _survival_world("numpy")
    rng = np.random.default_rng(5)
    n = compiled.n_robots
    mode = np.full(n, SEEK_PACK)
    counts = dict.fromkeys(("dock", "recharge_end", "death", "mate"), 0)
    reasons: set[RechargeEnd] = set()
    for step in range(2500):
        if step % 60 == 0:
            mode = rng.choice([SEEK_PACK, SEEK_ROBOT, WANDER], size=n, p=[0.35, 0.55, 0.1])
        commands = _scripted_commands(compiled, mode, rng)
        a = compiled.step(*commands)
        b = reference.step(*commands)
        _assert_same_survival(compiled, reference)
        counts["dock"] += len(a.dockings())
        counts["recharge_end"] += len(a.recharge_ends())
        reasons.update(reason for _, reason in a.recharge_ends())
        counts["mate"] += len(a.matings())
        for i in a.deaths():  # time sharing: the next agent takes over the robot
            counts["death"] += 1
            for sw in (compiled, reference):
                sw.set_energy(i, sw.config.initial_energy)
        assert a.dockings() == b.dockings() and a.recharge_ends() == b.recharge_ends()
        assert a.deaths() == b.deaths() and a.matings() == b.matings()
    # Not vacuous: every rule the kernels implement fired many times.
    for kind, k in counts.items():
        assert k >= 10, (kind, counts)
    assert reasons == {RechargeEnd.DECISION, RechargeEnd.MAX_STEPS, RechargeEnd.FULL}


# --- batch rendering ---------------------------------------------------------------------------
def test_compiled_views_match_numpy(
    scene_world: World, scenes: Scenes, batch_renderer: BatchOmniRenderer
) -> None:
    """Each view's camera, headlight and draw commands, some geoms hidden (they split runs)."""
    batch = batch_renderer
    m = scene_world.model
    for seed in scenes(10):
        if seed % 3 == 0:
            m.geom_rgba[batch.geometry.geoms[seed], 3] = 0.0  # a hidden geom splits runs
        outputs = []
        for fn in (view_kernels.frame_views, view_kernels.frame_views_reference):
            out = view_kernels.ViewOutputs(
                clip_t=np.zeros(batch.view_outputs.clip_t.shape, np.float32),
                head=np.zeros(batch.view_outputs.head.shape, np.float32),
                commands=np.zeros_like(batch.view_outputs.commands),
            )
            n = fn(batch.state, batch.view_geometry, out)
            outputs.append((n, out.clip_t, out.head, out.commands[:n].copy()))
        m.geom_rgba[batch.geometry.geoms[seed], 3] = 1.0
        (n0, clip0, head0, cmd0), (n1, clip1, head1, cmd1) = outputs
        assert n0 == n1 > 0
        np.testing.assert_array_equal(cmd0, cmd1)
        np.testing.assert_allclose(clip0, clip1, atol=1e-5)
        np.testing.assert_allclose(head0, head1, atol=1e-6)


def test_numpy_backend_renders_the_same_images(
    scene_world: World, scenes: Scenes, batch_renderer: BatchOmniRenderer
) -> None:
    """The renderer built with the numpy views kernel draws exactly what the compiled one does."""
    batch = batch_renderer
    assert batch.backend == "numba"
    with BatchOmniRenderer(scene_world, CameraConfig(), backend="numpy") as reference:
        assert reference.backend == "numpy"
        for _ in scenes(2):
            np.testing.assert_array_equal(reference.render(), batch.render())


# --- segmentation ------------------------------------------------------------------------------
def test_stacked_pair_test_kernel_matches_reference() -> None:
    """Random blob sets, many near the thresholds: the same pairs joined, the same roots."""
    rng = np.random.default_rng(3)
    n_joined = 0
    for _ in range(300):
        k = int(rng.integers(2, 9))
        bearing = rng.uniform(-np.pi, np.pi, k)
        bearing[1:] = np.where(rng.random(k - 1) < 0.6, bearing[0] + rng.normal(0, 0.02, k - 1),
                               bearing[1:])  # fmt: skip
        half = rng.uniform(0.01, 0.1, k)
        lo, hi = -half * rng.uniform(0.8, 1.2, k), half * rng.uniform(0.8, 1.2, k)
        top = rng.integers(0, 100, k)
        bottom = top + rng.integers(0, 20, k)  # some touch the strip's bottom row, 110
        parents = []
        joined = []
        for fn in (segmentation_kernels.join_stacked, segmentation_kernels.join_stacked_reference):
            parent = np.arange(k)
            joined.append(fn(bearing, lo, hi, top, bottom, parent, 111, 0.005))
            while not np.array_equal(parent[parent], parent):
                parent = parent[parent]
            parents.append(parent)
        assert joined[0] == joined[1]
        np.testing.assert_array_equal(parents[0], parents[1])
        n_joined += joined[0]
    assert 30 < n_joined < 270


def _labelling_buffers(
    rows: int, height: int, bearing: np.ndarray, capacity: int
) -> tuple[
    segmentation_kernels.StripBuffers, segmentation_kernels.Runs, segmentation_kernels.Extents
]:
    """The labelling's buffers, filled with marks that neither backend writes."""
    width = len(bearing)
    strip = segmentation_kernels.StripBuffers(
        height=height,
        n_classes=N_CLASSES,
        column_bearing=bearing,
        sin_col=np.sin(bearing),
        cos_col=np.cos(bearing),
        half_px=math.pi / width,
        bits=np.full((rows, width), 0xEE, dtype=np.uint8),
        edge_left=np.full((rows, N_CLASSES), -5, dtype=np.int64),
        edge_right=np.full((rows, N_CLASSES), -5, dtype=np.int64),
    )
    runs = segmentation_kernels.Runs(
        *(np.full(capacity, -5, dtype=np.int64) for _ in range(6)),
        comp_stats=np.full((capacity, 7), -5.0),
        comp_ints=np.full((capacity, 4), -5, dtype=np.int64),
    )
    ext = segmentation_kernels.Extents(
        np.zeros(3, dtype=np.int64), *(np.full(capacity, -5.0) for _ in range(3))
    )
    return strip, runs, ext


def _label_both(
    rgb: np.ndarray,
    table: segmentation_kernels.ClassTable,
    height: int,
    bearing: np.ndarray,
    capacity: int | None = None,
) -> tuple[tuple[int, int], segmentation_kernels.Runs]:
    """:func:`label` and its reference on one stacked image, then :func:`extents` and its
    reference for every class: every buffer equal. Returns (runs, components) and the runs."""
    rows, width = rgb.shape[:2]
    if capacity is None:
        capacity = rows * N_CLASSES * ((width + 1) // 2)  # the worst case
    ran = []
    for label, extents in (
        (segmentation_kernels.label, segmentation_kernels.extents),
        (segmentation_kernels.label_reference, segmentation_kernels.extents_reference),
    ):
        strip, runs, ext = _labelling_buffers(rows, height, bearing, capacity)
        n, k = label(rgb, table, strip, runs)
        done = [(n, k), strip, runs]
        if n >= 0:
            mean = np.arctan2(runs.comp_stats[:k, 1], runs.comp_stats[:k, 2])
            for cls in range(N_CLASSES):
                ext.counts[:] = (n, k, cls)
                ext.bearing[:k] = mean
                extents(runs, strip, ext)
                done.append(_copy(ext))
        ran.append(done)
    compiled, reference = ran
    assert compiled[0] == reference[0]
    if compiled[0][0] >= 0:
        for a, b in zip(compiled[1:], reference[1:], strict=True):
            _assert_equal(a, b)
    return compiled[0], compiled[2]


def _seam_joined(runs: segmentation_kernels.Runs, n: int, width: int) -> int:
    """Components holding both a run that starts at the strip's left edge and another that
    ends at its right edge."""
    comp, c0, c1 = runs.comp[:n], runs.c0[:n], runs.c1[:n]
    left = set(comp[(c0 == 0) & (c1 < width - 1)].tolist())
    right = set(comp[(c1 == width - 1) & (c0 > 0)].tolist())
    return len(left & right)


def test_labelling_kernels_match_their_references_on_rendered_strips(
    scene_world: World, scenes: Scenes, batch_renderer: BatchOmniRenderer
) -> None:
    """label and extents, buffer by buffer, and the detections of either backend's segmenter,
    on the crowded scenes rendered."""
    config = CameraConfig()
    geometry = target_geometry(scene_world)
    fast = OmniSegmenter(config, geometry, backend="numba")
    slow = OmniSegmenter(config, geometry, backend="numpy")
    bearing = fast.projection.column_bearing
    classes: set[int] = set()
    merged = detections = 0
    for _ in scenes(6):
        strips = batch_renderer.render()
        n_robots, height, width, _ = strips.shape
        rgb = np.ascontiguousarray(strips.reshape(n_robots * height, width, 3))
        (n, k), runs = _label_both(rgb, fast.table, height, bearing, n_robots * height * 24)
        assert n >= 0
        classes.update(runs.comp_ints[:k, 1].tolist())
        merged += n - k  # runs joined to others
        a, b = fast.detect(strips), slow.detect(strips)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
        detections += len(a[0])
    expected = {LED, FACE, BATTERY} if scene_world.config.n_packs else {LED, FACE}
    n = scene_world.config.n_robots
    assert expected <= classes and merged > 20 * n and detections >= 2 * n


def test_labelling_kernels_match_their_references_on_hand_made_strips(
    segmentation_strips: dict[str, tuple[CameraConfig, np.ndarray]],
) -> None:
    """label and extents on the hand-made strips (their colour table), on random class-bit
    images (overlapping classes, runs wider than half the strip, blobs across the seam) and
    with run buffers one run too small."""
    geometry = target_geometry(World(WorldConfig(n_robots=1, n_packs=1)))
    seams = overflows = wide = 0
    for config, strips in segmentation_strips.values():
        table = OmniSegmenter(config, geometry).table
        n_robots, height, width, _ = strips.shape
        rgb = np.ascontiguousarray(strips.reshape(n_robots * height, width, 3))
        bearing = OmniProjection(config).column_bearing
        (n, _), runs = _label_both(rgb, table, height, bearing)
        seams += _seam_joined(runs, n, width)
        if n > 0:  # one run more than the buffers hold: both refuse; exactly enough: both run
            assert _label_both(rgb, table, height, bearing, n - 1)[0] == (-1, 0)
            assert _label_both(rgb, table, height, bearing, n)[0][0] == n
            overflows += 1
    identity = segmentation_kernels.identity_table(N_CLASSES)
    rng = np.random.default_rng(9)
    overlapping = 0
    for _ in range(300):
        n_robots, height, width = (int(v) for v in rng.integers((1, 1, 2), (4, 9, 41)))
        rows = n_robots * height
        density = rng.uniform(0.1, 0.8, N_CLASSES)
        bits = np.zeros((rows, width), dtype=np.uint8)
        for c in range(N_CLASSES):
            bits |= (rng.random((rows, width)) < density[c]).astype(np.uint8) << c
        if rng.random() < 0.2:
            bits[rng.integers(rows)] = 1 << int(rng.integers(N_CLASSES))  # a whole row
        rgb = np.zeros((rows, width, 3), dtype=np.uint8)
        rgb[..., 2] = bits
        bearing = np.linspace(math.pi, -math.pi, width, endpoint=False)
        (n, _), runs = _label_both(rgb, identity, height, bearing)
        seams += _seam_joined(runs, n, width)
        wide += int((runs.c1[:n] - runs.c0[:n] + 1 > width // 2).sum())
        overlapping += int(((bits & (bits - 1)) != 0).sum())  # two classes or more
    assert seams >= 20 and overflows >= 3 and wide >= 20 and overlapping > 0


def test_segmenters_match_on_hand_made_strips(
    segmentation_strips: dict[str, tuple[CameraConfig, np.ndarray]],
) -> None:
    """Either backend's detections (random and near-threshold colours, blobs across the seam
    and touching at a corner, a pack cut by its ring, a checkerboard, empty strips) and blob
    measurements of single masks."""
    geometry = target_geometry(World(WorldConfig(n_robots=1, n_packs=1)))
    detections = measured = 0
    for config, strips in segmentation_strips.values():
        fast = OmniSegmenter(config, geometry, backend="numba")
        slow = OmniSegmenter(config, geometry, backend="numpy")
        a, b = fast.detect(strips), slow.detect(strips)
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
        detections += len(a[0])
        masks = fast.masks_from_classes(a[5])
        for c in range(N_CLASSES):
            for i in range(strips.shape[0]):
                blobs_c, blobs_r = fast.measure_blobs(masks[c, i], c), slow.measure_blobs(
                    masks[c, i], c
                )
                for x, y in zip(blobs_c, blobs_r, strict=True):
                    np.testing.assert_array_equal(x, y)
                measured += len(blobs_c[0])
    assert detections >= 10 and measured > detections


def test_mate_matches_its_reference(scene_world: World) -> None:
    """IR mating on random signals, states and streaks, with pairs of robots placed facing each
    other (at the distance and angle limits and beyond): streaks, exchanges and their order."""
    n = scene_world.config.n_robots
    config = SurvivalConfig(mate_consecutive_steps=2)
    rules = survival_kernels.MatingRules(
        reach2=config.mate_distance**2,
        cos_angle=math.cos(math.radians(config.mate_angle_deg)),
        consecutive_steps=config.mate_consecutive_steps,
    )
    rng = np.random.default_rng(17)
    d = scene_world.data
    exchanged = grown = reset = 0
    for trial in range(200):
        scene_world.reset(rng)
        for i in range(0, n - 1, 2):  # pairs facing each other, a little off axis
            x, y = rng.uniform(-0.6, 0.6, size=2)
            gap = rng.uniform(0.1, 0.4) / 2
            heading = rng.uniform(-math.pi, math.pi)
            c, s = math.cos(heading), math.sin(heading)
            twist = rng.normal(0.0, 0.12, size=2)
            scene_world.set_robot_pose(i, x - gap * c, y - gap * s, heading + twist[0])
            back = heading + math.pi + twist[1]
            scene_world.set_robot_pose(i + 1, x + gap * c, y + gap * s, back)
        mujoco.mj_forward(scene_world.model, d)
        signal = rng.random(n) < 0.8
        alive = rng.random(n) < 0.95
        docked = rng.random(n) < 0.05
        streak = rng.integers(0, 3, (n, n)) * (rng.random((n, n)) < 0.5)
        streak = np.triu(streak, 1) + np.triu(streak, 1).T
        partner = np.full(n, -1, dtype=np.int64)
        runs = []
        for kernel in (survival_kernels.mate, survival_kernels.mate_reference):
            ports = survival_kernels.IrPorts(
                site=np.asarray(scene_world.ir_port_site, dtype=np.int64),
                site_xpos=d.site_xpos,
                site_xmat=d.site_xmat,
                streak=streak.copy(),
                streak_active=np.array([trial % 4 != 0]),
                pairs=np.zeros((n * n, 3)),
            )
            out = partner.copy()
            runs.append((kernel(signal, alive, docked, ports, rules, out), ports, out))
        (any_c, ports_c, out_c), (any_r, ports_r, out_r) = runs
        assert any_c == any_r
        np.testing.assert_array_equal(out_c, out_r)
        np.testing.assert_array_equal(ports_c.streak, ports_r.streak)
        assert ports_c.streak_active[0] == ports_r.streak_active[0]
        exchanged += int(any_c)
        grown += int((ports_c.streak > streak).any())
        reset += int(((ports_c.streak == 0) & (streak > 0)).any())
    assert exchanged >= 2 and grown >= 5 and reset >= 10, (exchanged, grown, reset)


# --- pack reactivation (WorldConfig.pack_reactivation_steps) -----------------------------------
def test_count_down_packs_matches_its_reference() -> None:
    """Inactive packs' countdowns on random states: those that run out are active again in
    their own colour, the others stay dark; the count of packs still inactive."""
    rng = np.random.default_rng(21)
    world = World(WorldConfig(n_robots=2, n_packs=10))
    back = still = 0
    for _ in range(100):
        countdown = np.where(rng.random(10) < 0.6, rng.integers(1, 4, 10), 0)
        active = countdown == 0
        rgba = world.model.geom_rgba.copy()
        rgba[world.pack_geom[~active]] = (0.15, 0.15, 0.15, 1.0)
        packs = survival_kernels.PackAvailability(
            countdown=countdown.astype(np.int64),
            active=active,
            geom_rgba=rgba,
            pack_geom=np.asarray(world.pack_geom, dtype=np.int64),
            pack_rgba=world.pack_rgba,
        )
        ran = []
        for kernel in (
            survival_kernels.count_down_packs,
            survival_kernels.count_down_packs_reference,
        ):
            args = _copy(packs)
            ran.append((kernel(args), args))
        (left_c, out_c), (left_r, out_r) = ran
        assert left_c == left_r == int((countdown > 1).sum())
        _assert_equal(out_c, out_r)
        np.testing.assert_array_equal(out_c.countdown, np.maximum(countdown - 1, 0))
        np.testing.assert_array_equal(out_c.active, countdown <= 1)
        lit = out_c.geom_rgba[world.pack_geom[countdown <= 1]]
        np.testing.assert_array_equal(lit, world.pack_rgba[countdown <= 1].astype(np.float32))
        back += int((countdown == 1).sum())
        still += int((countdown > 1).sum())
    assert back >= 50 and still >= 50, (back, still)


def test_teeth_on_electrodes_refuses_inactive_packs_on_either_backend(
    scene_world: World, scenes: Scenes
) -> None:
    """The contact scan with random packs inactive: the same pairs from both, none onto an
    inactive pack, and contacts refused for that reason alone."""
    sw = SurvivalWorld(scene_world, rng=np.random.default_rng(1))
    n, n_packs = sw.n_robots, sw.n_packs
    rng = np.random.default_rng(15)
    free = survival_kernels.SurvivalState(
        np.full(n, 50.0), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool),
        np.ones(n, dtype=bool), np.zeros(n, dtype=np.int64), np.zeros((n, 2)),
    )  # fmt: skip
    flags = survival_kernels.StepFlags(*(np.zeros(n, dtype=bool) for _ in range(3)))
    kept = refused = 0
    for _ in scenes(40):
        packs = scene_world.pack_positions()
        for i in range(min(n, n_packs)):  # teeth 17 cm from a pack's centre: touching
            yaw = rng.uniform(-math.pi, math.pi)
            x, y = packs[i] - 0.17 * np.array([math.cos(yaw), math.sin(yaw)])
            scene_world.set_robot_pose(i, x, y, yaw)
        mujoco.mj_forward(scene_world.model, scene_world.data)
        geom = scene_world.data.contact.geom
        ncon = len(geom)
        active = rng.random(n_packs) < 0.5
        tables = sw.docking.tables._replace(pack_active=active)
        everyone = sw.docking.tables._replace(pack_active=np.ones(n_packs, dtype=bool))
        counts = []
        for kernel in (
            survival_kernels.teeth_on_electrodes,
            survival_kernels.teeth_on_electrodes_reference,
        ):
            pairs = []
            for table in (tables, everyone):
                contacts = survival_kernels.ContactScan(
                    geom.astype(np.int32).reshape(-1, 2), np.array([ncon], dtype=np.int64),
                    np.full((max(ncon, 1), 2), -5, dtype=np.int64),
                )  # fmt: skip
                k = kernel(contacts, table, free, flags)
                pairs.append(contacts.pairs[:k].copy())
            counts.append(pairs)
        (masked_c, all_c), (masked_r, all_r) = counts
        np.testing.assert_array_equal(masked_c, masked_r)
        np.testing.assert_array_equal(all_c, all_r)
        assert active[masked_c[:, 1]].all()
        np.testing.assert_array_equal(masked_c, all_c[active[all_c[:, 1]]])
        kept += len(masked_c)
        refused += len(all_c) - len(masked_c)
    if n_packs:
        assert kept >= 5 and refused >= 5, (kept, refused)
    else:
        assert kept == refused == 0


def test_geometric_vision_hides_inactive_packs_on_either_backend(
    scene_world: World, scenes: Scenes
) -> None:
    """Nearest targets, the full pass and blob merging with random packs inactive: the same
    answers from both backends, and no inactive pack among the visible targets."""
    n_packs = scene_world.config.n_packs
    compiled = GeometricVision(scene_world, backend="numba")
    reference = GeometricVision(scene_world, backend="numpy")
    first = len(compiled.target_cls) - n_packs  # the packs are the last targets
    rng = np.random.default_rng(16)
    dark = seen = others = 0
    for _ in scenes(40):
        for j in range(n_packs):
            scene_world.set_pack_active(j, bool(rng.random() < 0.5))
        active = scene_world.pack_active.copy()
        out_c, out_r = compiled.nearest_targets(), reference.nearest_targets()
        np.testing.assert_array_equal(out_c.visible, out_r.visible)
        np.testing.assert_allclose(out_c.distance, out_r.distance, rtol=0, atol=1e-12)
        mc, mr = compiled.measure_targets(), reference.measure_targets()
        np.testing.assert_array_equal(mc.visible, mr.visible)
        np.testing.assert_array_equal(compiled.front.candidate, reference.front.candidate)
        np.testing.assert_array_equal(compiled.merging.merged, reference.merging.merged)
        np.testing.assert_allclose(mc.blob_spread, mr.blob_spread, rtol=0, atol=1e-12)
        packs = mc.visible[:, first:]
        assert not packs[:, ~active].any()
        assert not compiled.front.candidate[:, first:][:, ~active].any()
        # The nearest pack seen is the nearest visible active one.
        for i in range(scene_world.config.n_robots):
            if packs[i].any():
                nearest = mc.distance[i, first:][packs[i]].min()
                assert out_c.visible[i, BATTERY] and out_c.distance[i, BATTERY] == nearest
        dark += int((~active).sum())
        seen += int(packs.sum())
        others += int(mc.visible[:, :first].sum())
    for j in range(n_packs):
        scene_world.set_pack_active(j, True)
    if n_packs:
        assert seen >= 10 and dark >= 10, (seen, dark)
    else:  # no packs: the other targets are seen as ever
        assert seen == dark == 0 and others > 0


def test_compiled_mechanics_with_pack_reactivation_equal_numpy() -> None:
    """Whole survival worlds whose packs go inactive after each docking, on either backend:
    the same trajectory, events, countdowns and colours; packs went dark and came back."""
    worlds = []
    for backend in ("numba", "numpy"):
        world = World(WorldConfig(pack_reactivation_steps=8), np.random.default_rng(3))
        worlds.append(
            SurvivalWorld(world, SURVIVAL_CONFIG, np.random.default_rng(3), backend=backend)
        )
    compiled, reference = worlds
    rng = np.random.default_rng(6)
    n = compiled.n_robots
    mode = np.full(n, SEEK_PACK)
    docks = reactivated = 0
    for step in range(1200):
        if step % 60 == 0:
            mode = rng.choice([SEEK_PACK, SEEK_ROBOT, WANDER], size=n, p=[0.6, 0.3, 0.1])
        commands = _scripted_commands(compiled, mode, rng)
        before = compiled.world.pack_active.copy()
        a = compiled.step(*commands)
        reference.step(*commands)
        _assert_same_survival(compiled, reference)
        np.testing.assert_array_equal(compiled.pack_countdown, reference.pack_countdown)
        np.testing.assert_array_equal(compiled.world.pack_active, reference.world.pack_active)
        assert compiled.docking.inactive_packs == reference.docking.inactive_packs
        assert compiled.docking.inactive_packs == int((compiled.pack_countdown > 0).sum())
        for i in a.deaths():
            for sw in (compiled, reference):
                sw.set_energy(i, sw.config.initial_energy)
        docks += len(a.dockings())
        reactivated += int((compiled.world.pack_active & ~before).sum())
    assert docks >= 10 and reactivated >= 10, (docks, reactivated)


def test_a_run_with_pack_reactivation_is_the_same_on_either_backend() -> None:
    """The evolution runner's fused sense-decide-act reads the packs' state: with packs that
    go inactive after a docking, both backends give the same trajectory and events."""
    from evolution.runner import EvolutionRunner, RunConfig

    runs = []
    for backend in ("numba", "numpy"):
        config = RunConfig(method="ee", world=WorldConfig(pack_reactivation_steps=30))
        runner = EvolutionRunner(config, 3, backend=backend)
        for _ in range(600):
            runner.step()
        runs.append(runner)
    a, b = runs
    np.testing.assert_array_equal(a.world.data.qpos, b.world.data.qpos)
    np.testing.assert_array_equal(a.world.pack_active, b.world.pack_active)
    events = a.events.to_frame()
    assert events.equals(b.events.to_frame())
    assert (events["kind"] == "dock").sum() >= 3
