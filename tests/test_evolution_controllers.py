"""Controllers as components (evolution.controllers) and the controller inputs as one table
(evolution.input_kernels): the mlp controller against its reference and by hand, genomes that
follow the controller, a one-generation mlp run, a controller and an input defined here."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from behaviours.kernels import BehaviourInputs, InputBuffers
from cyber_rodent.backend import jit_built, with_callees
from cyber_rodent.vision.types import BATTERY, FACE, LED
from evolution.checkpoint import CheckpointError
from evolution.cli import main as cli_main
from evolution.config import GENOME_LENGTH, EvolutionConfig, GeneticConfig
from evolution.controller import NeuralController
from evolution.controller_kernels import decide_mlp, decide_mlp_reference
from evolution.controllers import (
    CONTROLLERS,
    MLP,
    PAPER,
    ControllerSpec,
    GeneBlock,
    register_controller,
    resolve,
    step_kernels,
    unregister_controller,
)
from evolution.genome import Genome, GenomeLayout
from evolution.input_kernels import (
    INPUT_NAMES,
    INPUTS,
    N_INPUTS,
    ControllerInput,
    InputSources,
    RobotState,
    input_names_allowed,
    markdown_table,
    register_input,
    unregister_input,
)
from evolution.kernels import (
    PAPER_STEP,
    ControllerBuffers,
    choose,
    choose_reference,
    recharge_decision,
    recharge_decision_reference,
    sense_decide_act,
)
from evolution.runner import EvolutionRunner, RunConfig
from evolution.runner.settings import parse_set, settings, to_toml

ROOT = Path(__file__).resolve().parents[1]
SMALL = EvolutionConfig(population_size=8, n_robots=4, lifetime_steps=200, time_sharing_steps=50)


def _perceived(n: int) -> InputBuffers:
    return InputBuffers(
        proximity=np.zeros((n, 6)),
        norm_bearing=np.full((n, 3), 0.5),
        norm_distance=np.ones((n, 3)),
        behaviour=BehaviourInputs(
            mate=np.zeros((n, 2)),
            forage=np.zeros((n, 2)),
            search=np.zeros((n, 2)),
            mate_available=np.zeros(n, dtype=np.bool_),
            forage_available=np.zeros(n, dtype=np.bool_),
        ),
    )


def _robots(n: int) -> RobotState:
    return RobotState(np.zeros(n), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.bool_))


def _buffers(weights: np.ndarray, n_inputs: int = N_INPUTS) -> ControllerBuffers:
    n = weights.shape[0]
    return ControllerBuffers(
        weights=weights,
        inputs=np.zeros((n, n_inputs)),
        activations=np.zeros((n, 3)),
        behaviour=np.zeros(n, dtype=np.int64),
        led=np.zeros(n, dtype=bool),
        continue_recharge=np.zeros(n, dtype=bool),
        state=np.zeros((n, 0)),
    )


# --- the mlp controller ------------------------------------------------------------------------
def test_mlp_kernel_matches_its_reference() -> None:
    """Random genomes and inputs, hand-made exact ties included: activations to rounding,
    decisions equal."""
    rng = np.random.default_rng(11)
    n, units = 4, 5
    layout = resolve(EvolutionConfig(controller="mlp", hidden_units=units))
    rules = layout.rules(200.0, 40.0)
    counts = np.zeros(3, dtype=int)
    kept = stopped = 0
    for trial in range(2000):
        w = rng.uniform(-1, 1, (n, layout.length))
        output = layout.block("output")
        if trial % 10 == 0:  # exact ties: equal output weights, zero hidden layer
            w[:, layout.block("hidden")] = 0.0
            size = output.stop - output.start
            w[:, output] = np.round(w[:, output]) * (rng.random((n, size)) < 0.3)
        robots = RobotState(rng.uniform(0, 200, n), rng.integers(0, 41, n), rng.random(n) < 0.5)
        perceived = _perceived(n)
        perceived.behaviour.mate_available[:] = rng.random(n) < 0.5
        perceived.behaviour.forage_available[:] = rng.random(n) < 0.5
        out_c, out_r = _buffers(w), _buffers(w)
        x = rng.uniform(0, 1, (n, N_INPUTS))
        out_c.inputs[:], out_r.inputs[:] = x, x
        decide_mlp(rules, robots, perceived, out_c)
        decide_mlp_reference(rules, robots, perceived, out_r)
        np.testing.assert_allclose(out_c.activations, out_r.activations, rtol=0, atol=1e-13)
        for name in ("behaviour", "led", "continue_recharge"):
            np.testing.assert_array_equal(getattr(out_c, name), getattr(out_r, name))
        counts += np.bincount(out_c.behaviour, minlength=3)
        kept += int(out_c.continue_recharge.sum())
        stopped += int((~out_c.continue_recharge).sum())
    assert (counts > 300).all() and kept > 300 and stopped > 300


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_mlp_decision_hand_computed(backend: str) -> None:
    """Two hidden units: h0 = tanh(0) = 0 (all its weights zero), h1 = tanh(atanh(0.5)) = 0.5
    from its bias weight; Mate = 2 h1 = 1, Forage = -h1 + 0.25 = -0.25, Search = its bias 0.7;
    recharge [1, 0, -0.6] at energy 100 of 200: 0.5 - 0.6 <= 0, continue."""
    config = EvolutionConfig(controller="mlp", hidden_units=2)
    layout = resolve(config)
    assert layout.length == 3 + 2 * 12 + 3 * 3
    w = np.zeros(layout.length)
    w[layout.block("recharge")] = [1.0, 0.0, -0.6]
    hidden = w[layout.block("hidden")].reshape(2, 12)  # a view
    hidden[1, INPUT_NAMES.index("bias")] = math.atanh(0.5)
    output = w[layout.block("output")].reshape(3, 3)  # (outputs, units + bias)
    output[0] = [0.0, 2.0, 0.0]  # Mate
    output[1] = [0.0, -1.0, 0.25]  # Forage
    output[2] = [0.0, 0.0, 0.7]  # Search
    weights = np.stack([w, w])
    robots, perceived = _robots(2), _perceived(2)
    robots.energy[:] = 100.0
    perceived.behaviour.mate_available[:] = [True, False]
    controller = NeuralController(weights, robots, perceived, backend=backend, controller=layout)
    controller.decide()
    out = controller.buffers
    np.testing.assert_allclose(out.activations, [[1.0, -0.25, 0.7]] * 2, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(out.behaviour, [0, 2])  # Mate where available, else Search
    np.testing.assert_array_equal(out.led, [True, True])  # Mate (1) > Forage (-0.25)
    np.testing.assert_array_equal(out.continue_recharge, [True, True])
    robots.energy[:] = 160.0  # 0.8 - 0.6 > 0: stop
    controller.decide()
    np.testing.assert_array_equal(out.continue_recharge, [False, False])


def test_shared_output_rules_match_their_references() -> None:
    rng = np.random.default_rng(3)
    n = 6
    for _ in range(200):
        out_c, out_r = _buffers(np.zeros((n, 39))), _buffers(np.zeros((n, 39)))
        a = np.round(rng.uniform(-1, 1, (n, 3)), 1)  # ties included
        out_c.activations[:], out_r.activations[:] = a, a
        perceived = _perceived(n)
        perceived.behaviour.mate_available[:] = rng.random(n) < 0.5
        perceived.behaviour.forage_available[:] = rng.random(n) < 0.5
        choose_reference(perceived.behaviour, out_r)
        for i in range(n):
            choose(i, perceived.behaviour, out_c)
        np.testing.assert_array_equal(out_c.behaviour, out_r.behaviour)
        np.testing.assert_array_equal(out_c.led, out_r.led)
        robots = RobotState(rng.uniform(0, 200, n), rng.integers(0, 41, n), np.zeros(n, bool))
        w = rng.uniform(-1, 1, (n, 8))
        reference = np.zeros(n, dtype=bool)
        recharge_decision_reference(robots_rules := resolve(EvolutionConfig()).rules(200.0, 40.0),
                                    robots, w, 2, reference)  # fmt: skip
        compiled = [recharge_decision(i, robots_rules, robots, w[i], 2) for i in range(n)]
        np.testing.assert_array_equal(compiled, reference)


# --- the genome follows the controller -----------------------------------------------------------
def test_genome_length_and_operators_follow_the_controller() -> None:
    paper = EvolutionConfig()
    mlp = EvolutionConfig(controller="mlp", hidden_units=4)
    assert paper.genome_length == GENOME_LENGTH == 39
    assert mlp.genome_length == 3 + 4 * N_INPUTS + 3 * (4 + 1) == 66
    learning = dataclasses.replace(mlp, learning=dataclasses.replace(mlp.learning, enabled=True))
    assert learning.genome_length == 66 + 10
    layout = GenomeLayout.of(learning)
    assert (layout.controller, layout.meta, layout.shaping) == (
        slice(0, 66), slice(66, 70), slice(70, 76)
    )
    rng = np.random.default_rng(0)
    genetics = GeneticConfig()
    genome = Genome.random(rng, genetics, layout=layout)
    assert genome.weights.shape == (76,) and genome.learns and genome.controller.shape == (66,)
    assert ((genome.meta >= 0) & (genome.meta <= 1)).all()
    assert (np.abs(genome.controller) <= 1).all() and (np.abs(genome.shaping) <= 1).all()
    # crossover cuts anywhere in the 76 genes, mutation can touch every one
    other = Genome.random(rng, genetics, layout=layout)
    cuts = set()
    for _ in range(3000):
        child, _ = genome.crossover(other, rng)
        assert child.layout == layout
        cuts.add(int(np.argmax(child.weights != genome.weights)))
    assert cuts == set(range(1, 76))
    moved = np.zeros(76, dtype=bool)
    for _ in range(200):
        mutant = genome.mutate(rng, genetics)
        assert mutant.layout == layout and ((mutant.meta >= 0) & (mutant.meta <= 1)).all()
        moved |= mutant.weights != genome.weights
    assert moved.all()
    with pytest.raises(ValueError, match="different layouts"):
        genome.crossover(Genome.random(rng, genetics, layout=GenomeLayout(76)), rng)
    with pytest.raises(ValueError, match=r"shape \(66,\)"):
        Genome(np.zeros(39), GenomeLayout.of(mlp))
    # the paper's genomes are drawn as before: the same generator gives the same genes
    a = Genome.random(np.random.default_rng(4), genetics, layout=GenomeLayout.of(paper))
    assert a == Genome.random(np.random.default_rng(4), genetics)


def test_a_block_declares_its_initial_range() -> None:
    spec = ControllerSpec(
        name="scaled_for_test",
        description="paper's rule, selection drawn at a tenth of the range",
        blocks=lambda config, n: (
            GeneBlock("recharge", (3,)),
            GeneBlock("selection", (3, n), initial_scale=0.1),
        ),
        decide=PAPER.decide,
        decide_reference=PAPER.decide_reference,
    )
    register_controller(spec)
    try:
        layout = GenomeLayout.of(EvolutionConfig(controller="scaled_for_test"))
        genes = np.stack(
            [Genome.random(np.random.default_rng(s), layout=layout).weights for s in range(200)]
        )
        assert np.abs(genes[:, 3:]).max() <= 0.1 < np.abs(genes[:, :3]).max()
    finally:
        unregister_controller("scaled_for_test")


# --- the setting ---------------------------------------------------------------------------------
def test_controller_is_a_setting() -> None:
    known = settings()
    names = ", ".join(CONTROLLERS)  # the registry's names, whatever is built in
    assert known["evolution.controller"].default == "paper"
    assert known["evolution.controller"].allowed == f"one of {names}"
    assert known["evolution.hidden_units"].allowed == "integer in [1, 64]"
    assert parse_set(["evolution.controller=mlp", "evolution.hidden_units=3"]) == {
        "evolution.controller": "mlp", "evolution.hidden_units": 3,
    }  # fmt: skip
    text = to_toml()
    assert 'controller = "paper"' in text and "hidden_units = 8" in text
    with pytest.raises(ValueError, match=rf"controller must be one of {names}, got 'nn'"):
        EvolutionConfig(controller="nn")
    with pytest.raises(ValueError, match=r"hidden_units must be an integer in \[1, 64\]"):
        EvolutionConfig(hidden_units=0)


# --- a run with the mlp controller ---------------------------------------------------------------
@pytest.fixture(scope="module")
def mlp_run(tmp_path_factory) -> tuple[Path, str]:
    """One EE generation of 8 agents with the mlp controller, from the command line."""
    out = tmp_path_factory.mktemp("mlp") / "run"
    argv = [
        "evolve", "--method", "ee", "--seed", "1", "--generations", "1", "--out", str(out),
        "--no-progress", "--set", "evolution.controller=mlp", "--set",
        "evolution.population_size=8", "--set", "evolution.lifetime_steps=200", "--set",
        "evolution.time_sharing_steps=50",
    ]  # fmt: skip
    assert cli_main(argv) == 0
    return out, (out / "statistics.csv").read_text()


def test_one_generation_with_the_mlp_controller(mlp_run) -> None:
    out, table = mlp_run
    lines = table.splitlines()
    assert len(lines) == 2 and lines[1].startswith("0,")
    record = json.loads((out / "run.json").read_text())
    assert record["config"]["evolution"]["controller"] == "mlp"
    checkpoint = sorted((out / "checkpoints").glob("gen_*.ckpt"))[-1]
    with EvolutionRunner.from_checkpoint(checkpoint, BehaviourPolicies.load_default()) as runner:
        assert runner.config.evolution.controller == "mlp"
        assert runner.scheduler.active_weights.shape == (4, 3 + 8 * 12 + 3 * 9)
        assert runner.controller.layout.spec is MLP
    # a resume with another controller is refused, naming the setting
    config = runner.config.replace(evolution=dataclasses.replace(runner.config.evolution,
                                                                 controller="paper"))  # fmt: skip
    with pytest.raises(CheckpointError, match=r"evolution\.controller = 'mlp' there, 'paper' here"):
        EvolutionRunner.from_checkpoint(
            checkpoint, BehaviourPolicies.load_default(), expect=(config, 1)
        )


def test_deploy_refuses_the_mlp_controller_in_one_line(mlp_run, tmp_path, capsys) -> None:
    from evolution.lab.deploy import write_bundle
    from evolution.lab.deploy.__main__ import main as deploy_main

    out, _ = mlp_run
    assert deploy_main(["--from", str(out), "--top", "1", "--include-unmated", "--out",
                        str(tmp_path / "bundle")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "evolution.controller = 'mlp'" in err, err
    assert not (tmp_path / "bundle").exists()
    config = RunConfig(evolution=EvolutionConfig(controller="mlp"))
    with pytest.raises(ValueError, match=r"^evolution\.controller = 'mlp': a deployment bundle"):
        write_bundle(tmp_path / "b", np.zeros((1, resolve(config.evolution).length)),
                     config=config)  # fmt: skip


def test_transfer_carries_the_controller(mlp_run, tmp_path) -> None:
    from evolution.lab.api import RunOutput
    from evolution.lab.transfer import TransferSpec, transfer

    out, _ = mlp_run
    spec = TransferSpec(out, generation=1, top=2, robots=2, agents_per_robot=2, generations=1,
                        max_steps=30)  # fmt: skip
    result = transfer(spec, RunOutput(tmp_path / "hw"))
    assert all(i.genome.layout.controller_genes == 126 for i in result.individuals)
    record = json.loads((tmp_path / "hw" / "run.json").read_text())
    assert record["config"]["evolution"]["controller"] == "mlp"


@pytest.mark.slow  # compiles the mlp's learning step (about 25 s)
def test_learning_mode_with_the_mlp_controller() -> None:
    learning = dataclasses.replace(SMALL.learning, enabled=True)
    evo = dataclasses.replace(SMALL, controller="mlp", hidden_units=3, learning=learning)
    with EvolutionRunner(RunConfig(evolution=evo), 0, BehaviourPolicies.load_default()) as runner:
        assert runner.scheduler.population()[0].weights.shape == (3 + 36 + 12 + 10,)
        for _ in range(20):
            runner.step()
        assert runner.learning is not None and runner.learning.values.alpha.min() > 0


# --- the seam: a controller defined here -------------------------------------------------------
def bias_only(rules, robots, perceived, out) -> None:
    """Three output biases (genes 3..5) are the activations; the paper's recharge part."""
    for i in range(out.weights.shape[0]):
        for o in range(3):
            out.activations[i, o] = out.weights[i, rules.layout[1, 0] + o]
        choose(i, perceived.behaviour, out)
        out.continue_recharge[i] = recharge_decision(i, rules, robots, out.weights[i], 0)


def bias_only_reference(rules, robots, perceived, out) -> None:
    start = int(rules.layout[1, 0])
    out.activations[...] = out.weights[:, start : start + 3]
    choose_reference(perceived.behaviour, out)
    recharge_decision_reference(rules, robots, out.weights, 0, out.continue_recharge)


BIAS_ONLY = ControllerSpec(
    name="bias_only",
    description="a constant preference per behaviour",
    blocks=lambda config, n_inputs: (GeneBlock("recharge", (3,)), GeneBlock("bias", (3,))),
    decide=jit_built(bias_only, inline=True),
    decide_reference=bias_only_reference,
)


@pytest.fixture
def bias_only_registered():
    register_controller(BIAS_ONLY)
    yield BIAS_ONLY
    unregister_controller(BIAS_ONLY.name)
    assert "bias_only" not in CONTROLLERS


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_a_controller_defined_in_a_test_runs(bias_only_registered, backend) -> None:
    evo = dataclasses.replace(SMALL, controller="bias_only")
    assert evo.genome_length == 6
    # every agent prefers Search above all (bias 1 > 0 > -1): every robot searches
    genomes = [Genome(np.array([0.0, 0.0, 1.0, -1.0, 0.0, 1.0]), GenomeLayout(6))] * 8
    config = RunConfig(evolution=evo)
    with EvolutionRunner(config, 2, BehaviourPolicies.load_default(), genomes,
                         backend=backend) as runner:  # fmt: skip
        assert runner.scheduler.active_weights.shape == (4, 6)
        for _ in range(15):
            runner.step()
            np.testing.assert_array_equal(runner.controller.behaviour, 2)
            np.testing.assert_array_equal(runner.controller.buffers.activations, [[-1, 0, 1]] * 4)
            assert not runner.controller.continue_recharge.any()  # 1 > 0: never keeps docking
        assert runner.steps == 15


@pytest.mark.slow  # compiles the factory's fused step (about 25 s)
def test_the_built_kernels_of_the_paper_give_the_paper_run() -> None:
    """The paper's rule through the in-process kernel factory, not its prebuilt kernels: the
    same trajectory, bit for bit (the factory is the path of every other controller)."""
    built = dataclasses.replace(PAPER, name="paper_built", prebuilt=None)
    register_controller(built)
    try:
        assert step_kernels(built, INPUTS) is not step_kernels(PAPER, INPUTS)
        runs = []
        for name in ("paper", "paper_built"):
            evo = dataclasses.replace(SMALL, controller=name)
            with EvolutionRunner(RunConfig(evolution=evo), 5,
                                 BehaviourPolicies.load_default()) as runner:  # fmt: skip
                for _ in range(150):
                    runner.step()
                runs.append((runner.world.data.qpos.copy(), runner.events.state()["rows"],
                             runner.scheduler.population()))  # fmt: skip
        np.testing.assert_array_equal(runs[0][0], runs[1][0])
        np.testing.assert_array_equal(runs[0][1], runs[1][1])
        assert len(runs[0][1]) > 0 and runs[0][2] == runs[1][2]
    finally:
        unregister_controller("paper_built")


def test_every_controller_runs_the_papers_fused_code() -> None:
    """One source: another controller's stage and fused calls, and their references, are the
    paper's own functions, their code unchanged, rebuilt around its rule."""
    built = step_kernels(MLP, INPUTS)
    for kernel, paper in zip(built, PAPER_STEP, strict=True):
        assert kernel is not paper
        code = getattr(kernel, "py_func", kernel).__code__
        assert code is getattr(paper, "py_func", paper).__code__
    with pytest.raises(ValueError, match="reads no name decide_paper"):
        with_callees(sense_decide_act, decide_paper=decide_mlp)  # it calls decide, not that


# --- the input table -----------------------------------------------------------------------------
def test_the_design_document_shows_the_input_table() -> None:
    text = (ROOT / "docs" / "design.md").read_text()
    assert markdown_table() in text
    assert INPUT_NAMES == tuple(row.name for row in INPUTS) and len(INPUT_NAMES) == 12


def energy_squared(i, src, arg) -> float:
    """The active agent's energy over the maximum, squared."""
    e = src.robots.energy[i] / src.rules.max_energy
    return e * e


ENERGY_SQUARED = ControllerInput(
    name="energy_squared",
    reads="robots.energy",
    normalisation="(energy / {max_energy})^2",
    low=0.0,
    high=1.0,
    description="the energy input, squared",
    read=energy_squared,
)


@pytest.fixture
def energy_squared_registered():
    register_input(ENERGY_SQUARED)
    yield ENERGY_SQUARED
    unregister_input(ENERGY_SQUARED.name)
    assert ENERGY_SQUARED.name not in input_names_allowed()


def test_a_registered_input_joins_only_the_runs_that_name_it(energy_squared_registered) -> None:
    assert EvolutionConfig().genome_length == GENOME_LENGTH  # the default run is the paper's
    assert resolve(EvolutionConfig()).inputs == INPUTS
    named = EvolutionConfig(inputs="paper,energy_squared")
    assert [row.name for row in resolve(named).inputs] == [*INPUT_NAMES, "energy_squared"]
    assert named.genome_length == GENOME_LENGTH + 3


@pytest.mark.parametrize(
    "controller", ["paper", pytest.param("mlp", marks=pytest.mark.slow)]  # each compiles ~25 s
)
def test_an_input_added_here_reaches_the_fused_step(energy_squared_registered, controller) -> None:
    evo = dataclasses.replace(
        SMALL, controller=controller, hidden_units=2, inputs="paper,energy_squared"
    )
    layout = resolve(evo)
    assert layout.n_inputs == N_INPUTS + 1
    if controller == "paper":
        assert evo.genome_length == GENOME_LENGTH + 3 == 42  # one more weight per output
    else:
        assert evo.genome_length == 3 + 2 * 13 + 3 * 3
    states = []
    for backend in ("numba", "numpy"):
        with EvolutionRunner(RunConfig(evolution=evo), 3, BehaviourPolicies.load_default(),
                             backend=backend) as runner:  # fmt: skip
            assert runner.sense_decide_act != runner.sense_decide_act_stepwise  # the fused call
            assert runner.scheduler.population()[0].weights.shape == (evo.genome_length,)
            for _ in range(40):
                energy = runner.survival.energy.copy()
                runner.step()
                x = runner.controller.buffers.inputs
                assert x.shape == (4, 13)
                np.testing.assert_array_equal(x[:, 12], (energy / 200.0) ** 2)
                np.testing.assert_array_equal(x[:, 0], energy / 200.0)
            states.append((runner.world.data.qpos.copy(), runner.scheduler.population()))
    np.testing.assert_allclose(states[0][0], states[1][0], rtol=0, atol=1e-9)


def test_an_added_input_is_recorded_by_checkpoints(energy_squared_registered, tmp_path) -> None:
    evo = dataclasses.replace(SMALL, inputs="paper,energy_squared")
    with EvolutionRunner(RunConfig(evolution=evo), 1, BehaviourPolicies.load_default()) as runner:
        for _ in range(5):
            runner.step()
        path = runner.save_checkpoint(tmp_path / "c.ckpt")
    unregister_input(ENERGY_SQUARED.name)
    try:
        with pytest.raises(CheckpointError, match=r"inputs must be .*got 'energy_squared'"):
            EvolutionRunner.from_checkpoint(path, BehaviourPolicies.load_default())
    finally:
        register_input(ENERGY_SQUARED)
    restored = EvolutionRunner.from_checkpoint(path, BehaviourPolicies.load_default())
    assert restored.steps == 5
    restored.close()


def test_an_input_without_an_observation_cannot_be_deployed(energy_squared_registered, tmp_path):
    from evolution.lab.deploy import write_bundle

    with pytest.raises(ValueError, match=r"^controller input 'energy_squared' states no observ"):
        write_bundle(tmp_path / "b", np.zeros((1, 42)),
                     config=RunConfig(evolution=EvolutionConfig(inputs="paper,energy_squared")))
    assert not (tmp_path / "b").exists()


def test_inputs_are_filled_from_their_readers() -> None:
    """Each column holds its row's reader's value (the paper's compiled fill and the table)."""
    rng = np.random.default_rng(9)
    n = 5
    robots = RobotState(rng.uniform(0, 200, n), rng.integers(0, 41, n), rng.random(n) < 0.5)
    perceived = _perceived(n)
    perceived.proximity[:] = rng.uniform(0, 1, (n, 6))
    perceived.norm_distance[:] = rng.uniform(0, 1, (n, 3))
    rules = resolve(EvolutionConfig()).rules(200.0, 40.0)
    controller = NeuralController(np.zeros((n, 39)), robots, perceived)
    controller.decide()
    src = InputSources(rules, robots, perceived)
    expected = [[row.python_reader()(i, src, row.arg) for row in INPUTS] for i in range(n)]
    np.testing.assert_array_equal(controller.buffers.inputs, expected)
    np.testing.assert_array_equal(controller.buffers.inputs[:, 7], perceived.norm_distance[:, FACE])
    np.testing.assert_array_equal(controller.buffers.inputs[:, 8], perceived.norm_distance[:, LED])
    np.testing.assert_array_equal(
        controller.buffers.inputs[:, 9], perceived.norm_distance[:, BATTERY]
    )


def test_input_rows_are_checked() -> None:
    with pytest.raises(ValueError, match="snake_case"):
        dataclasses.replace(ENERGY_SQUARED, name="Energy²")
    with pytest.raises(ValueError, match="low"):
        dataclasses.replace(ENERGY_SQUARED, low=2.0)
    with pytest.raises(ValueError, match="exists"):
        register_input(dataclasses.replace(ENERGY_SQUARED, name="bias"))
    with pytest.raises(ValueError, match="exists"):
        register_controller(dataclasses.replace(MLP))
    with pytest.raises(ValueError, match="not a registered controller"):
        unregister_controller("paper")
    assert re.fullmatch(r"(\| .* \|\n)+", markdown_table())
