"""Deployment bundle: round trip, a standalone reference step that decides as the simulator."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import json
import math
import sys

import numpy as np
import pytest
import torch

from behaviours import BehaviourPolicies
from behaviours.definitions import load_values
from behaviours.greedy_policy import GreedyPolicy
from cyber_rodent.profiles import HardwareProfile
from evolution.config import EvolutionConfig
from evolution.deploy import (
    BUNDLE_FILE,
    REFERENCE_FILE,
    WEIGHTS_FILE,
    record_decisions,
    write_bundle,
)
from evolution.genome import Genome
from evolution.runner import EvolutionRunner, RunConfig
from evolution.transfer import hardware_run_config

SMALL = EvolutionConfig(population_size=8, n_robots=4, lifetime_steps=80, time_sharing_steps=40)


def _load_reference(bundle):
    """Import the bundle's own copy of the reference step, as a robot would."""
    spec = importlib.util.spec_from_file_location("bundle_reference_step", bundle / REFERENCE_FILE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A simulated run with the shipped behaviours, recorded, and a bundle of its population."""
    runner = EvolutionRunner(RunConfig(evolution=SMALL), 2, BehaviourPolicies.load_default())
    genomes = list(runner.scheduler.population())
    record = record_decisions(runner, 300)
    # and a hardware-profile run (noisy sensors, other field) from the same population
    hw_config = hardware_run_config(RunConfig(evolution=SMALL), HardwareProfile(), robots=3,
                                    agents_per_robot=2)  # fmt: skip
    hw = EvolutionRunner(hw_config, 3, BehaviourPolicies.load_default(), genomes[:6])
    hw_record = record_decisions(hw, 200)
    # every genome that ran (offspring are born during the recording), in first-seen order
    ran = np.concatenate([record["weights"].reshape(-1, 39), hw_record["weights"].reshape(-1, 39)])
    _, first = np.unique(ran, axis=0, return_index=True)
    genomes = [Genome(ran[i]) for i in sorted(first)]
    bundle = write_bundle(tmp_path_factory.mktemp("bundle"), genomes, provenance={"test": 1})
    return genomes, record, hw_record, bundle


def test_reference_step_imports_only_numpy_and_torch() -> None:
    from evolution.deploy import reference_step

    tree = ast.parse(open(reference_step.__file__).read())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add((node.module or "").split(".")[0])
    assert imported <= {"__future__", "json", "math", "dataclasses", "pathlib", "numpy", "torch"}


def test_bundle_round_trips(recorded) -> None:
    genomes, _, _, bundle = recorded
    spec = json.loads((bundle / BUNDLE_FILE).read_text())
    assert spec["format"] == 1 and spec["package_version"]
    assert spec["controller"]["input_order"][0] == "energy"
    assert spec["controller"]["input_order"][-1] == "led_previous"
    assert spec["normalisation"]["max_energy"] == 200.0
    assert spec["normalisation"]["range_max"] == [1.0, 0.3, 0.3, 0.3, 0.3, 0.3]
    assert spec["provenance"] == {"test": 1}
    weights = np.load(bundle / WEIGHTS_FILE)
    np.testing.assert_array_equal(weights, np.stack([g.weights for g in genomes]))
    # each exported behaviour equals the greedy policy of the shipped values
    states = np.random.default_rng(0).random((500, 2))
    for name, file in spec["behaviours"]["files"].items():
        module = torch.export.load(bundle / file).module()
        expected = GreedyPolicy(load_values(name)).act(states)
        np.testing.assert_array_equal(module(torch.from_numpy(states)).numpy(), expected)
    assert (bundle / REFERENCE_FILE).read_text() == open(
        importlib.import_module("evolution.deploy.reference_step").__file__
    ).read()


@pytest.mark.parametrize("which", ["sim", "hardware"])
def test_reference_step_reproduces_the_simulator(recorded, which) -> None:
    genomes, record, hw_record, bundle = recorded
    record = record if which == "sim" else hw_record
    reference = _load_reference(bundle)
    robot = reference.ReferenceController(bundle)
    rows = {g.weights.tobytes(): i for i, g in enumerate(genomes)}
    steps, n = record["behaviour"].shape
    seen_behaviours = set()
    for t in range(steps):
        for r in range(n):
            robot.use_agent(rows[record["weights"][t, r].tobytes()])
            d = robot.step(
                record["ranges"][t, r], record["bearing"][t, r], record["distance"][t, r],
                record["visible"][t, r], float(record["energy"][t, r]),
                bool(record["led_previous"][t, r]), bool(record["docked"][t, r]),
                int(record["recharge_steps"][t, r]),
            )  # fmt: skip
            where = f"step {t} robot {r}"
            np.testing.assert_allclose(d.inputs, record["inputs"][t, r], rtol=0, atol=1e-15)
            assert d.behaviour == record["behaviour"][t, r], where
            assert d.led_selection == record["led_selection"][t, r], where
            assert d.led == record["led"][t, r], where
            assert d.command == record["command"][t, r], where
            assert d.continue_recharge == record["continue_recharge"][t, r], where
            seen_behaviours.add(d.behaviour)
    assert seen_behaviours == {0, 1, 2}  # the recording exercises every behaviour
    assert record["docked"].any() and not record["continue_recharge"].all()


def test_bad_bundle_input_gets_clear_errors(recorded, tmp_path) -> None:
    _, _, _, bundle = recorded
    with pytest.raises(ValueError, match=r"genomes must be at least one genome of 39 weights"):
        write_bundle(tmp_path / "b", np.zeros((2, 5)))
    with pytest.raises(ValueError, match=r"max_energy must be in \(0, ∞\)"):
        write_bundle(tmp_path / "b", [Genome(np.zeros(39))], max_energy=0)
    reference = _load_reference(bundle)
    n = len(recorded[0])
    with pytest.raises(ValueError, match=rf"agent must be an integer in \[0, {n - 1}\]"):
        reference.ReferenceController(bundle, agent=n)


def test_reference_step_hand_computed(tmp_path) -> None:
    """Recharge part [0, 0, -1] always continues; selection weights make Mate's activation the
    bias (1) and Forage's the energy input (0.25), Search's 0.5 x the LED input."""
    weights = np.zeros(39)
    weights[2] = -1.0  # recharge: 0 * energy + 0 * steps - 1 <= 0 -> continue
    weights[3 + 10] = 1.0  # Mate <- bias
    weights[3 + 12 + 0] = 1.0  # Forage <- energy / 200
    weights[3 + 24 + 11] = 0.5  # Search <- LED at the previous step
    bundle = write_bundle(tmp_path / "b", [Genome(weights)])
    robot = _load_reference(bundle).ReferenceController(bundle)
    ranges = np.array([1.0, 0.15, 0.3, 0.3, 0.3, 0.3, 0.06, 0.3])  # front-left 30 at half range
    nothing = dict(bearing=np.zeros(3), distance=np.zeros(3), visible=np.zeros(3, dtype=bool))
    d = robot.step(ranges, **nothing, energy=50.0, led_previous=True)
    np.testing.assert_array_equal(
        d.inputs, [0.25, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    )
    assert d.behaviour == 2  # nothing in view: Search, though Mate's activation is larger
    assert d.led_selection and d.led  # LED: Mate (1) > Forage (0.25)
    np.testing.assert_array_equal(d.behaviour_input, [0.5, 0.0])  # two largest proximities
    assert d.continue_recharge
    docked = robot.step(ranges, **nothing, energy=50.0, led_previous=True, docked=True)
    assert docked.led_selection and not docked.led  # dark while it keeps recharging
    face = dict(bearing=np.array([0.0, math.pi / 2, 0.0]), distance=np.array([0, 1.15, 0]),
                visible=np.array([False, True, False]))  # fmt: skip
    d = robot.step(ranges, **face, energy=50.0, led_previous=False)
    assert d.behaviour == 0  # a face in view: Mate wins with activation 1
    np.testing.assert_allclose(d.behaviour_input, [0.75, 1.15 / (2.3 * math.sqrt(2))])
    assert d.inputs[7] == pytest.approx(1.15 / (2.3 * math.sqrt(2)))
