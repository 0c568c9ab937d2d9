"""Deployment bundle: round trip, a standalone reference step that decides as the simulator,
the robot engineer's bundle.json and README.md, mated-only selection and the command line."""

from __future__ import annotations

import argparse
import ast
import dataclasses
import importlib
import importlib.util
import json
import math
import re
import sys

import numpy as np
import pytest
import torch

from behaviours import BehaviourPolicies
from behaviours.definitions import load_values
from behaviours.greedy_policy import GreedyPolicy
from cyber_rodent.profiles import HardwareProfile
from cyber_rodent.robot import cyber_rodent
from evolution.config import EvolutionConfig
from evolution.genome import Genome
from evolution.lab.deploy import (
    BUNDLE_FILE,
    README_FILE,
    REFERENCE_FILE,
    WEIGHTS_FILE,
    record_decisions,
    write_bundle,
)
from evolution.lab.deploy.__main__ import add_arguments, main, run
from evolution.lab.deploy.readme import SECTIONS
from evolution.lab.deploy.selection import choose_agents
from evolution.lab.transfer import Individual, hardware_run_config
from evolution.runner import EvolutionRunner, RunConfig, run_config_from_record

SMALL = EvolutionConfig(population_size=8, n_robots=4, lifetime_steps=80, time_sharing_steps=40)

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()
#: Its range sensors as (name, bearing in degrees, range in metres).
RANGE_ROWS = [(row.name, row.bearing_deg, row.limit) for row in CR.range_sensors]


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
    bundle = write_bundle(
        tmp_path_factory.mktemp("bundle"), genomes, config=RunConfig(evolution=SMALL),
        provenance={"test": 1},
    )  # fmt: skip
    return genomes, record, hw_record, bundle


def test_reference_step_imports_only_numpy_and_torch() -> None:
    """The bundle's reference_step.py is cyber_rodent/robot_step.py: the standard library (its
    command line: argparse, sys), numpy, and torch only inside the torch backend."""
    from cyber_rodent import robot_step as reference_step

    tree = ast.parse(open(reference_step.__file__).read())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add((node.module or "").split(".")[0])
    assert imported <= {"__future__", "json", "math", "dataclasses", "pathlib", "numpy", "torch",
                        "argparse", "sys", "typing"}  # fmt: skip
    top_level = {a.name for node in tree.body if isinstance(node, ast.Import) for a in node.names}
    assert "torch" not in top_level  # optional: imported by the torch backend only


def test_bundle_round_trips(recorded) -> None:
    genomes, _, _, bundle = recorded
    spec = json.loads((bundle / BUNDLE_FILE).read_text())
    assert spec["format"] == 2 and spec["package_version"]
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
        importlib.import_module("cyber_rodent.robot_step").__file__
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
    with pytest.raises(ValueError, match=r"max_energy must be a number in \(0"):
        write_bundle(tmp_path / "b", [Genome(np.zeros(39))],
                     config=RunConfig(evolution=EvolutionConfig(max_energy=0)))  # fmt: skip
    with pytest.raises(ValueError, match=r"config must be a RunConfig"):
        write_bundle(tmp_path / "b", [Genome(np.zeros(39))], config=EvolutionConfig())
    assert not list(tmp_path.iterdir())  # nothing written
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


# --- the robot engineer's bundle: bundle.json and README.md from the run's config ----------
#: A config whose every survival and time-sharing number differs from the paper's, so a value
#: the bundle took from anywhere but the config would show.
_ODD = RunConfig(evolution=EvolutionConfig(
    population_size=6, n_robots=2, lifetime_steps=90, time_sharing_steps=30, initial_energy=80.0,
    max_energy=150.0, max_recharge_steps=25, fitness_time_unit=50.0,
))  # fmt: skip
ODD = _ODD.replace(survival=dataclasses.replace(
    _ODD.survival, control_dt=0.25, energy_decay=2.0, recharge_rate=4.0,
    decay_while_recharging=True, reflex_min_steps=1, reflex_max_steps=5, reflex_wheel_speed=0.4,
    mate_angle_deg=20.0, mate_distance=0.3, mate_consecutive_steps=3, mate_reflex=False,
    dock_bearing_tolerance_deg=12.0, capture_rule="recharge",
))  # fmt: skip


@pytest.fixture(scope="module")
def odd_bundle(tmp_path_factory):
    genomes = np.random.default_rng(3).uniform(-1, 1, (2, 39))
    return write_bundle(tmp_path_factory.mktemp("odd") / "bundle", genomes, config=ODD)


def test_bundle_json_states_the_run_config(odd_bundle) -> None:
    spec = json.loads((odd_bundle / BUNDLE_FILE).read_text())
    s, evo = ODD.survival, ODD.evolution
    assert run_config_from_record(spec["run_config"]) == ODD  # the whole resolved config
    assert spec["control"] == {"dt_s": 0.25, "rate_hz": 4.0}
    assert spec["torch"]["version"] == torch.__version__ == spec["versions"]["torch"]
    assert spec["torch"]["load"] == "torch.export.load(path).module()"
    energy = spec["survival"]["energy"]
    assert (energy["initial"], energy["max"], energy["decay_per_step"]) == (80.0, 150.0, 2.0)
    assert energy["recharge_rate_per_step"] == s.recharge_rate
    assert energy["recharge_gain_per_step"] == 4.0 - 2.0  # decay_while_recharging
    recharge = spec["survival"]["recharge"]
    assert recharge["max_steps"] == 25 and recharge["capture_rule"] == "recharge"
    assert recharge["dock_bearing_tolerance_deg"] == 12.0
    reflex = spec["survival"]["reflex"]
    assert (reflex["min_steps"], reflex["max_steps"], reflex["wheel_speed_m_s"]) == (1, 5, 0.4)
    assert reflex["after_mating"] is False and reflex["after_recharge"] is True
    assert reflex["turn_per_step_rad"] == pytest.approx(0.4 * 0.25 / CR.half_wheel_base)
    sharing = spec["survival"]["time_sharing"]
    assert (sharing["steps"], sharing["lifetime_steps"]) == (30, 90)
    assert sharing["agents_per_robot_in_run"] == 3
    mating = spec["survival"]["mating"]
    assert mating["ir_port_distance_max_m"] == 0.3 and mating["ir_port_angle_max_deg"] == 20.0
    assert mating["consecutive_steps"] == 3
    assert mating["exchange_duration_s"] == pytest.approx(0.75)
    assert spec["survival"]["fitness"]["time_unit_steps"] == evo.fitness_time_unit
    norm = spec["normalisation"]
    assert (norm["max_energy"], norm["max_recharge_steps"]) == (150.0, 25)
    assert spec["controller"]["recharge_rule"].startswith("w0*energy/150 + w1*steps/25 + w2")
    inputs = spec["controller"]["inputs"]
    assert [i["name"] for i in inputs] == spec["controller"]["input_order"]
    assert inputs[0]["value"].startswith("energy / 150")
    # sensors: the constants' angles and ranges, positions and directions from the model
    finders = spec["sensors"]["rangefinders"]
    assert [(f["name"], f["angle_deg"], f["range_max_m"]) for f in finders] == [
        (n, a, r) for n, a, r in RANGE_ROWS
    ]
    for f in finders:
        a = math.radians(f["angle_deg"])
        np.testing.assert_allclose(f["direction"], [math.cos(a), math.sin(a), 0.0], atol=1e-4)
        assert f["position_m"][2] == pytest.approx(0.08)  # 8 cm high (docs/design.md §4)
    assert [f["proximity_input"] for f in finders] == [0, 1, 2, 3, 4, 5, None, None]
    assert spec["sensors"]["ir_port"]["position_m"] == pytest.approx([0.111, -0.02, 0.08])
    assert spec["sensors"]["camera"]["max_range_m"] == ODD.camera.max_range
    conv = spec["conventions"]
    assert conv["wheel_order"] == ["left", "right"] and "positive to the left" in conv["bearing"]
    assert conv["wheel_radius_m"] == CR.wheel_radius


def test_readme_has_every_section_and_the_run_numbers(odd_bundle) -> None:
    text = (odd_bundle / README_FILE).read_text()
    headings = re.findall(r"^## (.+)$", text, flags=re.M)
    assert headings == list(SECTIONS)
    assert "**0.25 s** (4 Hz)" in text
    assert f"torch **{torch.__version__}**" in text
    for line in ("DT = 0.25 s", "INITIAL_ENERGY = 80", "MAX_ENERGY = 150", "ENERGY_DECAY = 2",
                 "RECHARGE_GAIN = 2 per step", "MAX_RECHARGE_STEPS = 25", "TIME_SHARING = 30",
                 "LIFETIME = 90", "MATE_DISTANCE = 0.3 m", "MATE_ANGLE = 20 deg",
                 "MATE_STEPS = 3", "REFLEX_STEPS = 1..5", "REFLEX_SPEED = 0.4 m/s",
                 "FITNESS_UNIT = 50 steps"):  # fmt: skip
        assert line in text, line
    assert "# no reflex after mating" in text and "after mating: no." in text  # mate_reflex
    assert "as a captured battery on its first recharge step" in text  # capture_rule
    assert "| 0 | energy | energy / 150" in text
    assert "| 5 | range_back | 180 |" in text
    assert "reference_step.py" in text


def _readme_load_code(bundle) -> str:
    text = (bundle / README_FILE).read_text()
    section = text.split("## Loading the behaviours", 1)[1]
    return re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)


def test_readme_load_call_loads_the_programs(odd_bundle, monkeypatch) -> None:
    """The README's code, run as written in the bundle directory, loads the three programs,
    and their actions are the numpy greedy policies'."""
    monkeypatch.chdir(odd_bundle)
    namespace: dict = {}
    exec(compile(_readme_load_code(odd_bundle), "README.md", "exec"), namespace)
    programs, states = namespace["programs"], namespace["states"]
    np.testing.assert_array_equal(
        namespace["commands"], GreedyPolicy(load_values("forage")).act(states)
    )
    x = np.concatenate([np.random.default_rng(4).random((2000, 2)), [[0.0, 0.0], [1.0, 1.0]]])
    for name in ("mate", "forage", "search"):
        expected = GreedyPolicy(load_values(name)).act(x)
        np.testing.assert_array_equal(programs[name](torch.from_numpy(x)).numpy(), expected)
        assert len(set(expected.tolist())) >= 3  # a real comparison


def test_rewriting_a_bundle_replaces_it_whole(odd_bundle, tmp_path) -> None:
    out = tmp_path / "b"
    write_bundle(out, [Genome(np.zeros(39))], config=ODD)
    (out / "stale.txt").write_text("from an older bundle")
    write_bundle(out, [Genome(np.ones(39))], config=ODD)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in odd_bundle.iterdir())
    np.testing.assert_array_equal(np.load(out / WEIGHTS_FILE), np.ones((1, 39)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b"]  # no temporaries left
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("keep")
    with pytest.raises(ValueError, match="non-empty directory without bundle.json"):
        write_bundle(tmp_path / "notes", [Genome(np.zeros(39))])
    assert [p.name for p in (tmp_path / "notes").iterdir()] == ["mine.txt"]


# --- which agents: mated only by default --------------------------------------------------
def _individual(fitness: float, mated: bool, slot: int) -> Individual:
    return Individual(Genome(np.full(39, float(slot))), fitness, mated, 0, slot)


def test_choose_agents_takes_the_fittest_that_mated() -> None:
    # fittest first; the three fittest never mated (what the old choice bundled)
    ranked = [_individual(7.0, False, 0), _individual(7.0, False, 1), _individual(6.0, False, 2),
              _individual(3.5, True, 3), _individual(2.0, False, 4), _individual(1.5, True, 5)]
    chosen = choose_agents(ranked, 3, source="test")
    assert [a.slot for a in chosen.agents] == [3, 5]
    assert chosen.short and (chosen.requested, chosen.ranked, chosen.mated) == (3, 6, 2)
    assert chosen.note() == (
        "2 fittest that mated of 6 ranked agents (test; 2 mated); 3 were requested, only 2 "
        "qualified"
    )
    assert [a.slot for a in choose_agents(ranked, 1).agents] == [3]
    old = choose_agents(ranked, 3, include_unmated=True)
    assert [a.slot for a in old.agents] == [0, 1, 2] and not old.short
    nobody = choose_agents(ranked[:3], 2)
    assert nobody.agents == () and nobody.mated == 0
    with pytest.raises(ValueError, match=r"top must be an integer in \[1, 6\], got 7"):
        choose_agents(ranked, 7)


# --- the command line on tiny runs ---------------------------------------------------------
TINY = RunConfig(evolution=EvolutionConfig(
    population_size=8, n_robots=4, lifetime_steps=200, time_sharing_steps=50
))  # fmt: skip


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """One generation of 8 agents (seed 9: 2 of the 8 completed lives mated)."""
    from evolution.lab.api import run as run_evolution

    out = tmp_path_factory.mktemp("runs") / "tiny"
    run_evolution("ee", 1, 9, config=TINY, out_dir=out)
    return out


def test_cli_bundles_only_mated_agents_and_says_so(tiny_run, tmp_path, capsys) -> None:
    out = tmp_path / "bundle"
    assert main(["--from", str(tiny_run), "--top", "5", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "5 were requested, only 2 qualified" in printed
    spec = json.loads((out / BUNDLE_FILE).read_text())
    agents = spec["provenance"]["agents"]
    assert len(agents) == 2 and all(a["mated"] for a in agents)
    assert spec["selection"]["mated_only"] and spec["selection"]["bundled"] == 2
    assert np.load(out / WEIGHTS_FILE).shape == (2, 39)
    record = json.loads((tiny_run / "run.json").read_text())
    assert spec["run_config"] == record["config"]
    assert spec["control"]["dt_s"] == record["config"]["survival"]["control_dt"] == 0.2
    assert "5 were requested, only 2 qualified" in (out / README_FILE).read_text()
    # the old choice, on request, through the mountable pair
    parser = argparse.ArgumentParser(prog="cyber-rodent deploy")
    add_arguments(parser)
    args = parser.parse_args(
        ["--from", str(tiny_run), "--top", "5", "--include-unmated", "--out", str(out)]
    )
    assert run(args) == 0
    agents = json.loads((out / BUNDLE_FILE).read_text())["provenance"]["agents"]
    assert len(agents) == 5 and not all(a["mated"] for a in agents)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--top", "0"], r"--top must be an integer in \[1, ∞\), got '0'"),
        (["--top", "two"], r"--top must be an integer in \[1, ∞\), got 'two'"),
        (["--top", "9"], r"--top must be an integer in \[1, 8\] \(completed lives of generation "
                         r"0 of gen_00001.ckpt\), got 9"),
        (["--generation", "-1"], r"--generation must be an integer in \[0, ∞\), got '-1'"),
        (["--generation", "7"], r"--generation: .* no checkpoint of generation 7 \(available: "
                                r"1\)"),
        (["--out", "FILE"], r"--out .*file\.txt is a file; it must be a new directory"),
        (["--out", "NOTES"], r"--out .*notes is a non-empty directory without bundle.json"),
        (["--from", "NOWHERE"], r"--from: .*nowhere is not a run directory"),
    ],
)  # fmt: skip
def test_cli_bad_input_is_one_line_and_leaves_nothing(
    tiny_run, tmp_path, capsys, argv, message
) -> None:
    (tmp_path / "file.txt").write_text("mine")
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("mine")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    places = {"FILE": tmp_path / "file.txt", "NOTES": tmp_path / "notes",
              "NOWHERE": tmp_path / "nowhere"}  # fmt: skip
    argv = [str(places.get(a, a)) for a in argv]
    full = {"--from": str(tiny_run), "--out": str(tmp_path / "bundle")}
    full.update(dict(zip(argv[::2], argv[1::2], strict=True)))
    assert main([x for kv in full.items() for x in kv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("python -m evolution.lab.deploy: error: "), err
    assert re.search(message, err), err
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_cli_refuses_a_run_where_no_agent_mated(tmp_path, capsys) -> None:
    from evolution.lab.api import run as run_evolution

    config = RunConfig(evolution=EvolutionConfig(
        population_size=4, n_robots=2, lifetime_steps=40, time_sharing_steps=20
    ))  # fmt: skip
    config = config.replace(
        survival=dataclasses.replace(config.survival, mate_consecutive_steps=1000)
    )
    run_evolution("ee", 1, 1, config=config, out_dir=tmp_path / "run")
    out = tmp_path / "bundle"
    assert main(["--from", str(tmp_path / "run"), "--top", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "none of the 4 agents ranked" in err and "--include-unmated" in err
    assert not out.exists()


# --- the bundle a robot engineer installs and checks: portable behaviours, test vectors ---
def _run_reference(bundle, *args, block_torch=False):
    """Run the bundle's reference_step.py as a program in the bundle directory."""
    import subprocess

    if block_torch:  # an installation without torch: importing it fails
        command = [sys.executable, "-c", "import sys, runpy; sys.modules['torch'] = None; "
                   "sys.argv = ['reference_step.py', *sys.argv[1:]]; "
                   "runpy.run_path('reference_step.py', run_name='__main__')", *args]  # fmt: skip
    else:
        command = [sys.executable, REFERENCE_FILE, *args]
    return subprocess.run(command, cwd=bundle, capture_output=True, text=True, timeout=300)


def test_fresh_bundle_passes_its_check_on_every_backend(odd_bundle) -> None:
    spec = json.loads((odd_bundle / BUNDLE_FILE).read_text())
    vectors = spec["test_vectors"]
    # 2 robots; energy 80 at 2 per step: the agents die at step 40 and newcomers take over
    assert vectors["file"] == "test_vectors.npz" and vectors["rows"] == 80
    assert vectors["agents"] == [0, 1]  # every agent of the bundle acted
    result = _run_reference(odd_bundle, "--check", "--backend", "all")
    assert result.returncode == 0, result.stdout + result.stderr
    n = vectors["rows"]
    assert result.stdout.splitlines() == [
        f"PASS {n}/{n} (backend numpy)", f"PASS {n}/{n} (backend table)",
        f"PASS {n}/{n} (backend torch)",
    ]  # fmt: skip
    plain = _run_reference(odd_bundle, "--check")  # the README's command
    assert plain.returncode == 0 and plain.stdout == f"PASS {n}/{n} (backend numpy)\n"


def test_check_names_the_first_corrupted_row(odd_bundle, tmp_path) -> None:
    import shutil

    bundle = tmp_path / "corrupt"
    shutil.copytree(odd_bundle, bundle)
    with np.load(bundle / "test_vectors.npz") as data:
        vectors = {k: data[k] for k in data.files}
    row = 37
    from cyber_rodent.commands import N_COMMANDS

    expected = (int(vectors["command"][row]) + 1) % N_COMMANDS
    vectors["command"][row] = expected
    np.savez_compressed(bundle / "test_vectors.npz", **vectors)
    result = _run_reference(bundle, "--check")
    assert result.returncode == 1
    where = (f"row {row} (step {vectors['step'][row]}, robot {vectors['robot'][row]}, agent "
             f"{vectors['agent'][row]})")  # fmt: skip
    assert result.stdout.startswith(
        f"FAIL (backend numpy) {where}: command expected {expected}, got "
    ), result.stdout
    vectors["behaviour"][3] = (vectors["behaviour"][3] + 1) % 3
    np.savez_compressed(bundle / "test_vectors.npz", **vectors)
    assert "FAIL (backend numpy) row 3 (" in _run_reference(bundle, "--check").stdout


def test_reference_step_runs_on_numpy_alone(odd_bundle) -> None:
    n = json.loads((odd_bundle / BUNDLE_FILE).read_text())["test_vectors"]["rows"]
    result = _run_reference(odd_bundle, "--check", "--backend", "all", block_torch=True)
    assert result.returncode == 0 and result.stdout == (
        f"PASS {n}/{n} (backend numpy)\nPASS {n}/{n} (backend table)\n"
    ), result.stdout + result.stderr
    refused = _run_reference(odd_bundle, "--check", "--backend", "torch", block_torch=True)
    assert refused.returncode == 2 and "backend 'torch' needs torch" in refused.stderr
    summary = _run_reference(odd_bundle, block_torch=True)
    assert summary.returncode == 0 and "backends available here: numpy, table;" in summary.stdout


def test_numpy_table_and_torch_backends_agree(odd_bundle) -> None:
    """The three implementations of the behaviours, and the simulator's GreedyPolicy, choose
    the same command on random inputs and on the corners of the input square."""
    reference = _load_reference(odd_bundle)
    x = np.concatenate([np.random.default_rng(5).random((1500, 2)),
                        [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0]]])  # fmt: skip
    robots = {b: reference.ReferenceController(odd_bundle, backend=b)
              for b in ("numpy", "table", "torch")}  # fmt: skip
    for index, name in enumerate(("mate", "forage", "search")):
        expected = GreedyPolicy(load_values(name)).act(x)
        assert len(set(expected.tolist())) >= 3
        for backend, robot in robots.items():
            got = np.array([robot.policies[index].act(s) for s in x])
            np.testing.assert_array_equal(got, expected, err_msg=f"{name} {backend}")


def test_greedy_tables_are_the_policies_on_every_cell() -> None:
    from behaviours.portable import greedy_table
    from behaviours.tile_coding import TileCoder

    for name in ("mate", "forage", "search"):
        values = load_values(name)
        table = greedy_table(values)
        scale = TileCoder(values.coder_config).scale
        assert table.shape == tuple(int(s) + 1 for s in scale) and table.dtype == np.int8
        q = np.stack(np.meshgrid(*(np.arange(n) for n in table.shape), indexing="ij"), -1)
        states = np.minimum((q.reshape(-1, 2) + 0.5) / scale, 1.0)
        assert (np.floor(states * scale) == q.reshape(-1, 2)).all()  # one state per cell
        np.testing.assert_array_equal(table.reshape(-1), GreedyPolicy(values).act(states))


def test_portable_hash_is_the_tile_coders(odd_bundle) -> None:
    from behaviours.tile_coding import TileCoder

    reference = _load_reference(odd_bundle)
    robot = reference.ReferenceController(odd_bundle, backend="numpy")
    described = json.loads((odd_bundle / "behaviours.json").read_text())
    assert described["hash"]["multipliers_hex"] == ["0x7FEB352D", "0x846CA68B"]
    assert "mix32" in described["pseudo_code"] and len(described["algorithm"]) >= 5
    x = np.random.default_rng(6).random((300, 2))
    for index, name in enumerate(("mate", "forage", "search")):
        coder = TileCoder(load_values(name).coder_config)
        rows = np.array([robot.policies[index].rows(s) for s in x])
        np.testing.assert_array_equal(rows, coder.hashed_indices(x))


_GOOD = dict(
    ranges=np.full(8, 0.3), bearing=np.zeros(3), distance=np.ones(3),
    visible=np.array([True, False, True]), energy=100.0, led_previous=False, docked=False,
    recharge_steps=0,
)  # fmt: skip


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"energy": math.nan}, r"energy must be a finite number in \[0, 150\]; got nan"),
        ({"energy": math.inf}, r"energy must be a finite number in \[0, 150\]; got inf"),
        ({"energy": -1.0}, r"energy must be a finite number in \[0, 150\]; got -1.0"),
        ({"energy": 150.5}, r"energy must be a finite number in \[0, 150\]; got 150.5"),
        ({"energy": "full"}, r"energy must be a finite number .*; got 'full'"),
        ({"ranges": np.full(7, 0.3)}, r"ranges must be range readings .* shape \(8,\); got "
                                      r"shape \(7,\)"),
        ({"ranges": np.full(8, math.nan)}, r"ranges must be 8 range readings in m, finite and "
                                           r">= 0, shape \(8,\); got \[nan"),
        ({"ranges": np.r_[np.full(7, 0.3), math.inf]}, r"ranges must be 8 .*inf\]"),
        ({"ranges": np.r_[-0.01, np.full(7, 0.3)]}, r"ranges must be 8 .*got \[-0.01"),
        ({"bearing": np.array([4.0, 0.0, 0.0])}, r"bearing must be 3 bearings in \[-pi, pi\] "
                                                 r"rad, finite where visible.*got \[4.0"),
        ({"bearing": np.array([0.0, 0.0, math.nan])}, r"bearing must be .*got \[0.0, 0.0, nan"),
        ({"bearing": np.zeros(2)}, r"bearing must be bearings in rad .* shape \(3,\); got "
                                   r"shape \(2,\)"),
        ({"distance": np.array([-1.0, 1.0, 1.0])}, r"distance must be 3 distances in m, finite "
                                                   r"and >= 0 where visible"),
        ({"distance": np.array([1.0, 1.0, math.inf])}, r"distance must be 3 .*inf\]"),
        ({"visible": np.array([True, False])}, r"visible must be 3 flags \(bool, or 0 / 1\), "
                                               r"shape \(3,\); got \[True, False\]"),
        ({"visible": np.array([2, 0, 0])}, r"visible must be 3 flags .*got \[2, 0, 0\]"),
        ({"led_previous": 2}, r"led_previous must be a flag \(bool, or 0 / 1\); got 2"),
        ({"docked": math.nan}, r"docked must be a flag .*; got nan"),
        ({"recharge_steps": -1}, r"recharge_steps must be an integer in \[0, 25\]; got -1"),
        ({"recharge_steps": 26}, r"recharge_steps must be an integer in \[0, 25\]; got 26"),
        ({"recharge_steps": 1.5}, r"recharge_steps must be an integer in \[0, 25\]; got 1.5"),
    ],
)  # fmt: skip
def test_reference_step_refuses_bad_input(odd_bundle, change, message) -> None:
    robot = _load_reference(odd_bundle).ReferenceController(odd_bundle)
    robot.step(**_GOOD)  # the unchanged input is fine
    with pytest.raises(ValueError, match=message):
        robot.step(**{**_GOOD, **change})
    # a target that is not seen: its bearing and distance are ignored (the simulator: inf)
    robot.step(**{**_GOOD, "distance": np.array([1.0, math.inf, 1.0]),
                  "bearing": np.array([0.0, math.nan, 0.0])})  # fmt: skip


def test_readme_install_commands_and_portable_code(odd_bundle, monkeypatch) -> None:
    text = (odd_bundle / README_FILE).read_text()
    public = torch.__version__.split("+")[0]
    install = (f"python3 -m venv .venv && .venv/bin/pip install numpy=={np.__version__} && "
               f".venv/bin/pip install torch=={public}")  # fmt: skip
    assert install in text and ".venv/bin/python reference_step.py --check" in text
    if "+cpu" in torch.__version__:
        assert f"torch=={public} --index-url https://download.pytorch.org/whl/cpu" in text
        assert "builds tagged +cpu come from the PyTorch wheel index" in text
    section = text.split("## Portable behaviours", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)
    monkeypatch.chdir(odd_bundle)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    expected = GreedyPolicy(load_values("forage")).act(np.array([0.75, 0.25]))
    assert namespace["command"] == int(expected)


def test_bundle_without_programs_runs_on_numpy(tmp_path) -> None:
    bundle = write_bundle(tmp_path / "lean", np.zeros((1, 39)), programs=False,
                          action_values=False, vector_steps=30)  # fmt: skip
    assert not list(bundle.glob("*.pt2"))
    spec = json.loads((bundle / BUNDLE_FILE).read_text())
    assert spec["portable"]["backends"] == ["table"] and spec["test_vectors"]["rows"] == 120
    result = _run_reference(bundle, "--check")
    assert result.returncode == 0 and result.stdout == "PASS 120/120 (backend table)\n"
    refused = _run_reference(bundle, "--check", "--backend", "numpy")
    assert refused.returncode == 2 and "behaviours.npz has no q array" in refused.stderr
    assert "holds no `.pt2` programs" in (bundle / README_FILE).read_text()


def test_the_reference_step_logs_a_run_the_sysid_reader_accepts(odd_bundle, tmp_path) -> None:
    """``reference_step.py --check --log FILE`` (numpy alone) writes the run log format: one row
    per replayed step, its commands and ranges as the vectors hold them."""
    from cyber_rodent.sysid.log import read_log

    path = tmp_path / "run.csv"
    done = _run_reference(odd_bundle, "--check", "--backend", "numpy", "--log", str(path),
                          block_torch=True)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert not path.with_name("run.csv.partial").exists()
    log = read_log(path)
    with np.load(odd_bundle / "test_vectors.npz") as vectors:
        rows = len(vectors["agent"])
        first = log.table.sort_values(["step", "robot"]).iloc[0]
        ranges = vectors["ranges"][np.lexsort((vectors["robot"], vectors["step"]))[0]]
    assert len(log.table) == rows
    np.testing.assert_allclose([first[f"ir{i}"] for i in range(8)], ranges)
    assert set(log.table["led"].unique()) <= {False, True}
    assert log.table["mated"].isna().all()  # the step cannot know: empty, not True
    assert log.table["docked"].dtype == bool
