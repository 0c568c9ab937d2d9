"""Controllers with memory: the agent's own state (zero at birth, saved and restored with the
agent, in checkpoints), the CTRNN by hand and against its reference, runs that resume bit for
bit, the inputs a run chooses (``evolution.inputs``) and what their readers may read, and a
config that grows without breaking older checkpoints."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from behaviours.kernels import BehaviourInputs, InputBuffers
from cyber_rodent.world import WorldConfig
from evolution.cli import main as cli_main
from evolution.config import GENOME_LENGTH, CtrnnConfig, EvolutionConfig
from evolution.controller import NeuralController
from evolution.controller_kernels import decide_ctrnn, decide_ctrnn_reference
from evolution.controllers import CONTROLLERS, CTRNN, resolve
from evolution.input_kernels import (
    EXTRA_INPUTS,
    INPUT_NAMES,
    INPUTS,
    ControllerInput,
    RobotState,
    available_inputs,
    register_input,
    select_inputs,
    source_fields,
)
from evolution.kernels import ControllerBuffers
from evolution.runner import EvolutionRunner, RunConfig
from evolution.runner.checkpoints import _record_differences, run_fingerprint
from evolution.runner.settings import apply, parse_set
from evolution.scheduler import CentralisedEvolution, EmbodiedEvolution

TINY = EvolutionConfig(population_size=8, n_robots=4, lifetime_steps=60, time_sharing_steps=15)
CTRNN_TINY = dataclasses.replace(TINY, controller="ctrnn", hidden_units=3)


def _perceived(n: int) -> InputBuffers:
    return InputBuffers(
        proximity=np.zeros((n, 6)),
        norm_bearing=np.full((n, 3), 0.5),
        norm_distance=np.ones((n, 3)),
        behaviour=BehaviourInputs(
            np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)), np.zeros(n, dtype=np.bool_),
            np.zeros(n, dtype=np.bool_),
        ),  # fmt: skip
    )


def _robots(n: int, rng: np.random.Generator | None = None) -> RobotState:
    energy = np.full(n, 100.0) if rng is None else rng.uniform(0, 200, n)
    return RobotState(energy, np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.bool_))


def _buffers(weights: np.ndarray, n_inputs: int, state_size: int) -> ControllerBuffers:
    n = weights.shape[0]
    return ControllerBuffers(
        weights, np.zeros((n, n_inputs)), np.zeros((n, 3)), np.zeros(n, dtype=np.int64),
        np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros((n, state_size)),
    )  # fmt: skip


# --- the CTRNN ------------------------------------------------------------------------------------
def test_ctrnn_is_built_in_with_its_genome_and_state() -> None:
    assert CONTROLLERS["ctrnn"] is CTRNN and not CTRNN.deployable
    layout = resolve(EvolutionConfig(controller="ctrnn", hidden_units=8))
    n = len(INPUTS)
    assert layout.length == 3 + 8 * n + 8 * 8 + 3 * 8 + 3 * 9 == 214
    assert layout.state_size == 16 and layout.constants == (1.0, 100.0, 1.0, 5.0)
    assert [block.name for block in layout.blocks] == [
        "recharge", "input", "recurrent", "bias", "tau", "gain", "output",
    ]  # fmt: skip
    assert resolve(EvolutionConfig()).state_size == 0  # the paper's has no memory


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_ctrnn_two_steps_hand_computed(backend: str) -> None:
    """One unit: input weight 0.6 from the bias input, self-weight 0.5, bias 0, gain gene -1
    (gain 1), time-constant gene 0 (τ = sqrt(1 * 100) = 10 steps); Mate = 2 r, Forage = -1,
    Search = 0 (its bias weight). From y = 0: r = σ(0) = 1/2, y1 = (0.6 + 0.5 / 2) / 10 =
    0.085; then y2 = y1 + (0.6 + 0.5 σ(y1) - y1) / 10."""
    config = EvolutionConfig(controller="ctrnn", hidden_units=1)
    layout = resolve(config)
    w = np.zeros(layout.length)
    w[layout.block("recharge")] = [1.0, 0.0, -0.6]
    w[layout.block("input")][INPUT_NAMES.index("bias")] = 0.6
    w[layout.block("recurrent")] = 0.5
    w[layout.block("gain")] = -1.0
    w[layout.block("output")] = [2.0, 0.0, 0.0, -1.0, 0.0, 0.0]  # (Mate, Forage, Search) x (r, 1)
    weights = np.stack([w, w])
    robots, perceived = _robots(2), _perceived(2)
    controller = NeuralController(weights, robots, perceived, backend=backend, controller=layout)
    sigma = lambda z: 1.0 / (1.0 + math.exp(-z))  # noqa: E731
    controller.decide()
    y1 = (0.6 + 0.5 * 0.5) / 10.0
    np.testing.assert_allclose(controller.state[:, 0], [y1, y1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(controller.state[:, 1], sigma(y1), rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        controller.buffers.activations, [[2 * sigma(y1), -1.0, 0.0]] * 2, rtol=0, atol=1e-15
    )
    assert controller.behaviour.tolist() == [2, 2]  # nothing in view: Search
    assert controller.led.tolist() == [True, True]  # Mate (2 σ > 0) > Forage (-1)
    controller.decide()
    y2 = y1 + (0.6 + 0.5 * sigma(y1) - y1) / 10.0
    np.testing.assert_allclose(controller.state[:, 0], [y2, y2], rtol=0, atol=1e-15)
    # the time constant and gain genes map log-uniformly onto their ranges, clipped
    w[layout.block("tau")] = 5.0  # clipped to 1: τ = 100
    w[layout.block("gain")] = 0.0  # gain sqrt(1 * 5)
    controller.state[:] = 0.0
    controller.buffers.weights[:] = w  # the controller reads its weights in place
    controller.decide()
    y = (0.6 + 0.5 * sigma(0.0)) / 100.0
    np.testing.assert_allclose(controller.state[:, 0], y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(controller.state[:, 1], sigma(math.sqrt(5.0) * y), atol=1e-15)


def test_ctrnn_kernel_matches_its_reference_over_many_steps() -> None:
    """Random networks and inputs, the state carried over 200 steps: states and activations to
    rounding, decisions equal."""
    rng = np.random.default_rng(4)
    n = 6
    layout = resolve(EvolutionConfig(controller="ctrnn", hidden_units=5))
    rules = layout.rules(200.0, 40.0)
    w = rng.uniform(-1, 1, (n, layout.length))
    w[:, layout.block("tau")] = rng.uniform(-2, 2, (n, 5))  # clipped ends included
    out_c = _buffers(w, layout.n_inputs, layout.state_size)
    out_r = _buffers(w, layout.n_inputs, layout.state_size)
    robots, perceived = _robots(n, rng), _perceived(n)
    for _ in range(200):
        x = rng.uniform(0, 1, (n, layout.n_inputs))
        out_c.inputs[:], out_r.inputs[:] = x, x
        perceived.behaviour.mate_available[:] = rng.random(n) < 0.5
        perceived.behaviour.forage_available[:] = rng.random(n) < 0.5
        decide_ctrnn(rules, robots, perceived, out_c)
        decide_ctrnn_reference(rules, robots, perceived, out_r)
        np.testing.assert_allclose(out_c.state, out_r.state, rtol=0, atol=1e-12)
        np.testing.assert_allclose(out_c.activations, out_r.activations, rtol=0, atol=1e-12)
        for name in ("behaviour", "led", "continue_recharge"):
            np.testing.assert_array_equal(getattr(out_c, name), getattr(out_r, name))
    assert np.abs(out_c.state[:, :5]).max() > 0.1  # the network moved


def test_ctrnn_ranges_are_settings() -> None:
    assert parse_set(["ctrnn.tau_high=40", "evolution.controller=ctrnn"]) == {
        "ctrnn.tau_high": 40.0, "evolution.controller": "ctrnn",
    }  # fmt: skip
    config = apply(RunConfig(), {"ctrnn.tau_high": 40.0, "evolution.controller": "ctrnn"})
    assert config.evolution.ctrnn.tau_high == 40.0
    assert resolve(config.evolution).constants == (1.0, 40.0, 1.0, 5.0)
    with pytest.raises(ValueError, match=r"^evolution\.ctrnn\.tau_low must be a number in \[1,"):
        CtrnnConfig(tau_low=0.5)  # an Euler step longer than the time constant
    with pytest.raises(ValueError, match=r"^evolution\.ctrnn\.gain_high must be a number in \[5"):
        CtrnnConfig(gain_low=5.0, gain_high=2.0)


# --- the state belongs to the agent ---------------------------------------------------------------
def _quiet(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A step in which nothing happens: energy 100, no death, capture or mating."""
    return np.full(n, 100.0), np.zeros(n, bool), np.zeros(n, bool), np.full(n, -1)


def test_the_state_is_saved_and_restored_with_its_agent_and_zero_at_birth() -> None:
    """One robot, two agents, slots of 3 steps: each agent finds its own state when its turn
    comes back; a newborn (after a death) starts from zeros."""
    config = EvolutionConfig(
        controller="ctrnn", hidden_units=1, population_size=2, n_robots=1, lifetime_steps=100,
        time_sharing_steps=3,
    )  # fmt: skip
    scheduler = EmbodiedEvolution(config, np.random.default_rng(0))
    live = scheduler.controller_state
    assert live.shape == (1, 2) and scheduler.slot_state.shape == (1, 2, 2)
    energy, died, captured, mated = _quiet(1)
    live[0] = [7.0, 8.0]  # agent 0 writes its state
    for _ in range(3):
        switched = scheduler.on_step(energy, died, captured, mated)
    assert switched[0] and scheduler.active_slot[0] == 1
    np.testing.assert_array_equal(live[0], [0.0, 0.0])  # agent 1's own (never run)
    np.testing.assert_array_equal(scheduler.slot_state[0, 0], [7.0, 8.0])
    live[0] = [1.0, 2.0]
    for _ in range(3):
        scheduler.on_step(energy, died, captured, mated)
    assert scheduler.active_slot[0] == 0
    np.testing.assert_array_equal(live[0], [7.0, 8.0])  # agent 0's state is back
    np.testing.assert_array_equal(scheduler.slot_state[0, 1], [1.0, 2.0])
    scheduler.on_step(np.zeros(1), np.ones(1, bool), captured, mated)  # agent 0 dies
    assert scheduler.slots[0][0].origin != 0  # replaced by a newborn
    np.testing.assert_array_equal(scheduler.slot_state[0, 0], [0.0, 0.0])
    np.testing.assert_array_equal(live[0], [1.0, 2.0])  # agent 1 runs now
    for _ in range(3):
        scheduler.on_step(energy, died, captured, mated)
    np.testing.assert_array_equal(live[0], [0.0, 0.0])  # the newborn's state


def test_ce_newborns_and_parked_robots_hold_no_state() -> None:
    config = EvolutionConfig(
        controller="ctrnn", hidden_units=1, population_size=2, n_robots=2, lifetime_steps=2,
        time_sharing_steps=2,
    )  # fmt: skip
    scheduler = CentralisedEvolution(config, np.random.default_rng(0))
    energy, died, captured, mated = _quiet(2)
    scheduler.controller_state[:] = 5.0
    scheduler.on_step(energy, died, captured, mated)
    scheduler.on_step(energy, died, np.array([True, False]), mated)  # all lives end: gen 1
    assert scheduler.generation == 1
    np.testing.assert_array_equal(scheduler.controller_state, 0.0)
    np.testing.assert_array_equal(scheduler.slot_state, 0.0)


def test_steps_since_recharge_and_mating_are_the_agents_own() -> None:
    """Counted per agent from birth, 0 while docked (after the step) and in a mating step;
    a switched-out agent's clock stops with it."""
    config = EvolutionConfig(population_size=4, n_robots=2, lifetime_steps=100,
                             time_sharing_steps=4)  # fmt: skip
    scheduler = EmbodiedEvolution(config, np.random.default_rng(1))
    since_recharge, since_mating = scheduler.since_view
    energy, died, captured, mated = _quiet(2)
    docked = np.zeros(2, bool)
    scheduler.on_step(energy, died, captured, mated, docked)
    assert since_recharge.tolist() == [1, 1] and since_mating.tolist() == [1, 1]
    docked[0] = True
    scheduler.on_step(energy, died, captured, mated, docked)
    assert since_recharge.tolist() == [0, 2]
    docked[0] = False
    scheduler.on_step(energy, died, captured, mated, docked)
    assert since_recharge.tolist() == [1, 3] and since_mating.tolist() == [3, 3]
    scheduler.on_step(energy, died, captured, np.array([1, 0]), docked)  # a mating: switch
    assert since_recharge.tolist() == [0, 0]  # the new agents' clocks: never lived
    assert scheduler.slot_since[0, 0].tolist() == [2, 0]  # agents 0 kept their counters
    assert scheduler.slot_since[1, 0].tolist() == [4, 0]
    for _ in range(4):  # agents 1 run their slot out, agents 0 come back
        scheduler.on_step(energy, died, captured, mated, docked)
    assert scheduler.slot_since[:, 1].tolist() == [[4, 4], [4, 4]]
    assert since_recharge.tolist() == [2, 4] and since_mating.tolist() == [0, 0]
    with pytest.raises(ValueError, match="read-only"):
        since_recharge[0] = 5  # read-only for the controller


# --- whole runs: both backends, checkpoints -------------------------------------------------------
def _run(evo: EvolutionConfig, steps: int, backend: str = "numpy") -> EvolutionRunner:
    runner = EvolutionRunner(RunConfig(evolution=evo), 2, BehaviourPolicies.load_default(),
                             backend=backend)  # fmt: skip
    for _ in range(steps):
        runner.step()
    return runner


def test_a_ctrnn_run_resumes_bit_identically_mid_generation(tmp_path: Path) -> None:
    """A checkpoint at an arbitrary step (inside a slot, inside a generation) continues exactly
    as the uninterrupted run: event log, population, every agent's state."""
    straight = _run(CTRNN_TINY, 230)
    first = _run(CTRNN_TINY, 97)
    path = first.save_checkpoint(tmp_path / "mid.ckpt")
    first.close()
    resumed = EvolutionRunner.from_checkpoint(path, BehaviourPolicies.load_default(),
                                              backend="numpy")  # fmt: skip
    for _ in range(230 - 97):
        resumed.step()
    np.testing.assert_array_equal(straight.events.state()["rows"], resumed.events.state()["rows"])
    assert straight.completed_generations >= 1
    np.testing.assert_array_equal(straight.scheduler.slot_state, resumed.scheduler.slot_state)
    np.testing.assert_array_equal(straight.controller.state, resumed.controller.state)
    assert np.abs(straight.scheduler.slot_state).max() > 0  # the agents did remember
    assert straight.scheduler.population() == resumed.scheduler.population()
    np.testing.assert_array_equal(straight.world.data.qpos, resumed.world.data.qpos)
    straight.close()
    resumed.close()


def test_learning_mode_with_the_ctrnn_controller() -> None:
    learning = dataclasses.replace(TINY.learning, enabled=True)
    evo = dataclasses.replace(CTRNN_TINY, learning=learning)
    runner = _run(evo, 30)
    assert runner.scheduler.population()[0].weights.shape == (resolve(evo).length + 10,)
    assert np.abs(runner.controller.state).max() > 0
    runner.close()


def test_deploy_refuses_a_controller_with_memory_in_one_line(tmp_path: Path) -> None:
    from evolution.lab.deploy import write_bundle

    config = RunConfig(evolution=EvolutionConfig(controller="ctrnn"))
    with pytest.raises(ValueError, match=r"^evolution\.controller = 'ctrnn': .*memory") as error:
        write_bundle(tmp_path / "b", np.zeros((1, 230)), config=config)
    assert "\n" not in str(error.value) and not (tmp_path / "b").exists()


# --- the inputs a run chooses ---------------------------------------------------------------------
def test_inputs_are_chosen_per_run() -> None:
    assert EvolutionConfig().inputs == "paper" and select_inputs("paper") == INPUTS
    assert EvolutionConfig().genome_length == GENOME_LENGTH == 3 + 3 * len(INPUTS)
    evo = EvolutionConfig(inputs="paper,steps_since_recharge")
    assert [row.name for row in resolve(evo).inputs] == [*INPUT_NAMES, "steps_since_recharge"]
    assert evo.genome_length == GENOME_LENGTH + 3
    assert parse_set(["evolution.inputs=paper,steps_since_mating"]) == {
        "evolution.inputs": "paper,steps_since_mating"
    }
    names = [row.name for row in available_inputs()]
    assert names[: len(INPUTS)] == list(INPUT_NAMES)
    assert {row.name for row in EXTRA_INPUTS} <= set(names)
    with pytest.raises(ValueError, match=r"^inputs must be comma-separated names from "
                       r"paper, energy, .*steps_since_recharge.*, got 'steps'$"):  # fmt: skip
        EvolutionConfig(inputs="paper,steps")
    with pytest.raises(ValueError, match=r"^evolution\.inputs names 'bias' twice"):
        EvolutionConfig(inputs="paper,bias")


def test_the_extra_inputs_read_the_robot() -> None:
    """Wheels: the previous step's commands, (v / 1.3 + 1) / 2; the counters over the
    lifetime (60 steps), clipped at 1; both backends agree."""
    evo = dataclasses.replace(
        TINY, inputs="paper,wheel_left,wheel_right,steps_since_recharge,steps_since_mating"
    )
    runners = [_run(evo, 0, backend) for backend in ("numba", "numpy")]
    for _ in range(80):
        wheels = [runner.action.wheels.copy() for runner in runners]
        since = [[view.copy() for view in runner.scheduler.since_view] for runner in runners]
        for runner, w, (recharge, mating) in zip(runners, wheels, since, strict=True):
            runner.step()
            x = runner.controller.buffers.inputs[:, len(INPUTS):]
            expected_w = np.clip((w / 1.3 + 1) / 2, 0, 1)
            np.testing.assert_allclose(x[:, :2], expected_w, rtol=0, atol=1e-15)
            active_since = np.minimum(1.0, recharge / 60.0), np.minimum(1.0, mating / 60.0)
            np.testing.assert_array_equal(x[:, 2], active_since[0])
            np.testing.assert_array_equal(x[:, 3], active_since[1])
    inputs = [runner.controller.buffers.inputs for runner in runners]
    np.testing.assert_array_equal(inputs[0][:, len(INPUTS):], inputs[1][:, len(INPUTS):])
    np.testing.assert_allclose(inputs[0], inputs[1], rtol=0, atol=1e-12)  # vision: to rounding
    assert len({tuple(np.round(row, 6)) for row in inputs[0][:, 12:14]}) > 1  # wheels moved
    for runner in runners:
        runner.close()


def test_a_reader_of_a_field_that_does_not_exist_is_refused_naming_them() -> None:
    def wheelz(i, src, arg) -> float:
        return float(src.robots.wheelz[i, 0])

    row = ControllerInput("wheelz", "robots.wheelz", "m/s", 0.0, 1.0, "a typo", wheelz)
    with pytest.raises(ValueError, match=r"^input wheelz: its reader failed .*wheelz.*; a reader "
                       r"may read src\.rules: .*src\.robots: energy, recharge_steps, led_on, "
                       r"wheels, since_recharge, since_mating; src\.perceived: "):  # fmt: skip
        register_input(row)
    assert "wheelz" not in [r.name for r in available_inputs()]
    assert "behaviour.mate_available" in source_fields()["perceived"]


def test_the_reader_fields_are_documented() -> None:
    text = (Path(__file__).resolve().parents[1] / "docs" / "extending.md").read_text()
    for part, names in source_fields().items():
        for name in names:
            assert f"`src.{part}.{name}`" in text, (part, name)


# --- a config that grows --------------------------------------------------------------------------
def test_new_fields_at_their_defaults_keep_every_fingerprint() -> None:
    """The published model's run has the fingerprint it had before `evolution.inputs` and
    `evolution.ctrnn` existed (recorded from that commit), so older checkpoints resume; a
    value other than the default enters it. (Today's default runs the fixed contact model,
    `world.contacts`, a change of behaviour, so its fingerprint differs.)"""
    published = RunConfig(world=WorldConfig(contacts="published"))
    assert run_fingerprint(published, 3, "x") == (
        "ffbe8809fcc18cb0d7cc31c0096981667db6c2029e044d500a6c223b901e0b65"
    )
    assert run_fingerprint(RunConfig(), 3, "x") != run_fingerprint(published, 3, "x")
    other = RunConfig(evolution=EvolutionConfig(ctrnn=CtrnnConfig(tau_high=50.0)))
    assert run_fingerprint(other, 3, "x") != run_fingerprint(RunConfig(), 3, "x")
    inputs = RunConfig(evolution=EvolutionConfig(inputs="paper,wheel_left"))
    assert run_fingerprint(inputs, 3, "x") != run_fingerprint(RunConfig(), 3, "x")


def test_a_fingerprint_mismatch_names_the_fields() -> None:
    record = json.loads(json.dumps(dataclasses.asdict(RunConfig()), default=list))
    del record["evolution"]["ctrnn"]
    record["evolution"]["lifetime_steps"] = 300
    text = _record_differences(record, RunConfig())
    assert "evolution.ctrnn (not in the checkpoint; " in text
    assert "evolution.lifetime_steps (300 there, 400 here)" in text
    assert _record_differences(json.loads(json.dumps(dataclasses.asdict(RunConfig()),
                                                     default=list)), RunConfig()) == ""


# --- from the command line ------------------------------------------------------------------------
CLI_TINY = [
    "--set", "evolution.population_size=8", "--set", "evolution.lifetime_steps=60", "--set",
    "evolution.time_sharing_steps=15", "--set", "evolution.hidden_units=3",
]  # fmt: skip


@pytest.mark.slow  # compiles the CTRNN's fused step (about 40 s)
def test_a_ctrnn_run_from_the_command_line_resumes_byte_identically(tmp_path: Path) -> None:
    common = ["--seed", "3", "--no-progress", "--set", "evolution.controller=ctrnn", *CLI_TINY]
    straight, cut = tmp_path / "straight", tmp_path / "cut"
    assert cli_main(["evolve", "--generations", "2", "--out", str(straight), *common]) == 0
    assert cli_main(["evolve", "--generations", "1", "--out", str(cut), *common]) == 0
    assert cli_main(["resume", str(cut), "--generations", "2", "--no-progress"]) == 0
    for name in ("statistics.csv", "events.csv"):
        assert (straight / name).read_bytes() == (cut / name).read_bytes(), name
    assert len((straight / "statistics.csv").read_text().splitlines()) == 3
    record = json.loads((straight / "run.json").read_text())
    assert record["config"]["evolution"]["controller"] == "ctrnn"

    from evolution.lab.api import RunOutput
    from evolution.lab.transfer import TransferSpec, transfer

    spec = TransferSpec(straight, generation=2, top=2, robots=2, agents_per_robot=2,
                        generations=1, max_steps=30)  # fmt: skip
    result = transfer(spec, RunOutput(tmp_path / "hw"))
    length = resolve(dataclasses.replace(CTRNN_TINY)).length
    assert all(i.genome.layout.controller_genes == length for i in result.individuals)


@pytest.mark.slow  # compiles the paper's controller over 13 inputs (about 30 s)
def test_an_extra_input_from_the_command_line(tmp_path: Path) -> None:
    out = tmp_path / "run"
    argv = ["evolve", "--generations", "1", "--out", str(out), "--no-progress", "--set",
            "evolution.inputs=paper,steps_since_recharge", *CLI_TINY[:6]]  # fmt: skip
    assert cli_main(argv) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["config"]["evolution"]["inputs"] == "paper,steps_since_recharge"
    checkpoint = sorted((out / "checkpoints").glob("gen_*.ckpt"))[-1]
    with EvolutionRunner.from_checkpoint(checkpoint, BehaviourPolicies.load_default()) as runner:
        assert runner.scheduler.active_weights.shape == (4, GENOME_LENGTH + 3)
