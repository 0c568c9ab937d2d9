"""Experiments end to end: the CLI's evolve -> plot -> render, sweeps, kill + resume, bad input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import imageio.v3 as iio
import pandas as pd
import pytest

from evolution.lab.api import RunOutput
from evolution.lab.sweep import Execution, SweepSpec, load_sweep, parse_seeds, run_dir, sweep

#: A tiny world and population: two robots, four agents, short lives, so a generation takes
#: a few seconds.
TINY = ["population_size=4", "n_robots=2", "lifetime_steps=60", "time_sharing_steps=30"]
TINY_OVERRIDES = {
    "population_size": 4,
    "n_robots": 2,
    "lifetime_steps": 60,
    "time_sharing_steps": 30,
}


def cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "evolution.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "LP_NUM_THREADS": "1"},
    )


def tiny_args() -> list[str]:
    return [a for item in TINY for a in ("--set", item)]


def test_evolve_plot_render(tmp_path: Path) -> None:
    out = tmp_path / "run"
    r = cli(
        "evolve",
        "--generations",
        "2",
        "--seed",
        "1",
        "--out",
        str(out),
        "--no-progress",
        *tiny_args(),
        "--set",
        "survival.mate_distance=0.4",
    )
    assert r.returncode == 0, r.stderr
    assert "cyber-rodent sweep" in r.stdout  # tells the user how to run the full experiment
    table = pd.read_csv(out / "statistics.csv")
    assert table["generation"].tolist() == [0, 1]
    per_robot = pd.read_csv(out / "statistics_per_robot.csv")  # Fig. 7's measure
    assert set(per_robot["generation"]) <= {0, 1} and set(per_robot["robot"]) <= {0, 1, 2, 3}
    assert list(per_robot.columns)[:3] == ["generation", "robot", "batteries_mean"]
    run = json.loads((out / "run.json").read_text())
    assert run["seed"] == 1 and run["config"]["evolution"]["population_size"] == 4
    assert run["config"]["survival"]["mate_distance"] == 0.4
    assert run["settings"]["survival.mate_distance"] == 0.4  # what differs from the paper
    assert {"cyber-rodent", "git_commit"} <= set(run["versions"])
    versions = json.loads((out / "versions.json").read_text())
    assert versions["packages"]["mujoco"] == "3.17.0"
    events = pd.read_csv(out / "events.csv")
    assert {"step", "robot", "kind"} <= set(events.columns)
    assert list((out / "checkpoints").glob("gen_*.ckpt"))

    r = cli("plot", str(out))
    assert r.returncode == 0, r.stderr
    image = iio.imread(out / "figures" / "fig6.png")
    assert image.ndim == 3 and image.shape[0] > 200
    assert (out / "figures" / "fig6.pdf").read_bytes().startswith(b"%PDF")
    summary = pd.read_csv(out / "figures" / "fig6_summary.csv")
    assert summary["span"].tolist() == ["last", "last 5"] and (summary["runs"] == 1).all()

    before = sorted(p.name for p in out.rglob("*"))
    video = tmp_path / "run.mp4"
    r = cli("render", str(out), "--out", str(video), "--frames", "5", "--no-progress")
    assert r.returncode == 0, r.stderr
    frames = iio.imread(video)
    assert frames.shape[0] == 5 and frames.std() > 10
    assert sorted(p.name for p in out.rglob("*")) == before  # the run dir is untouched


def test_kill_mid_run_then_resume_is_identical(tmp_path: Path) -> None:
    reference = tmp_path / "reference"
    r = cli(
        "evolve",
        "--generations",
        "3",
        "--seed",
        "2",
        "--out",
        str(reference),
        "--no-progress",
        *tiny_args(),
    )
    assert r.returncode == 0, r.stderr

    killed = tmp_path / "killed"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "evolution.cli",
            "evolve",
            "--generations",
            "3",
            "--seed",
            "2",
            "--out",
            str(killed),
            "--no-progress",
            *tiny_args(),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    # The statistics table is published just after each checkpoint, so wait for both: a kill
    # between the two would leave nothing to compare below.
    deadline = time.monotonic() + 240
    while not (
        list((killed / "checkpoints").glob("gen_00001.ckpt"))
        and (killed / "statistics.csv").exists()
    ):
        assert proc.poll() is None, "the run ended before it could be killed"
        assert time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert len(pd.read_csv(killed / "statistics.csv")) < 3  # really interrupted

    r = cli("resume", str(killed), "--no-progress")
    assert r.returncode == 0, r.stderr
    pd.testing.assert_frame_equal(
        pd.read_csv(killed / "statistics.csv"), pd.read_csv(reference / "statistics.csv")
    )
    pd.testing.assert_frame_equal(
        pd.read_csv(killed / "events.csv"), pd.read_csv(reference / "events.csv")
    )


def _serial(tmp_path: Path, spec: SweepSpec) -> dict:
    from behaviours import BehaviourPolicies
    from evolution.lab.api import run

    reactive = BehaviourPolicies.reactive()
    return {
        member: run(member.method, spec.generations, member.seed, policies=reactive,
                    **spec.settings_of(member.cell))
        for member in spec.runs
    }  # fmt: skip


def test_local_sweep_equals_serial_runs(tmp_path: Path) -> None:
    spec = SweepSpec(("ee", "ce"), (0, 1), 1, TINY_OVERRIDES, policies="reactive")
    results = sweep(spec, RunOutput(tmp_path / "sweep"), Execution(workers=2))
    serial = _serial(tmp_path, spec)
    for key in spec.runs:
        pd.testing.assert_frame_equal(results[key], serial[key])
        assert (run_dir(tmp_path / "sweep", *key) / "statistics.csv").exists()
    loaded = load_sweep(tmp_path / "sweep")
    assert sorted(loaded) == ["ce", "ee"] and len(loaded["ee"]) == 2


@pytest.mark.slow
def test_ray_sweep_equals_serial_runs(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    spec = SweepSpec(("ee",), (0, 1), 1, TINY_OVERRIDES, policies="reactive")
    results = sweep(spec, RunOutput(tmp_path / "sweep"), Execution("ray", 2, "local"))
    serial = _serial(tmp_path, spec)
    for key in spec.runs:
        pd.testing.assert_frame_equal(results[key], serial[key])


def test_parse_seeds() -> None:
    assert parse_seeds("0-3") == (0, 1, 2, 3)
    assert parse_seeds("7") == (7,)
    assert parse_seeds("0,2,5-6") == (0, 2, 5, 6)
    for bad in ("3-1", "a", "1,1", "-2", ""):
        with pytest.raises(ValueError, match="seed"):
            parse_seeds(bad)


@pytest.mark.parametrize(
    "args, message",
    [
        (["evolve", "--method", "xx"], "method must be one of ee, ce"),
        (["evolve", "--set", "no_such_key=1"], "unknown config key 'no_such_key'"),
        (
            ["evolve", "--set", "population_size=many"],
            "evolution.population_size must be an integer in [1, 10000], got 'many'",
        ),
        (["evolve", "--set", "crossover_probability=2"], "crossover_probability"),
        (["evolve", "--set", "population_size=10"], "divisible"),
        (["evolve", "--generations", "0"], "generations"),
        (["evolve", "--set", "survival.bogus=1"], "unknown config key 'survival.bogus'; closest"),
        (["evolve", "--set", "survival.mate_distance=0"], "survival.mate_distance must be a"),
        (["sweep", "--grid", "survival.reflex_max_steps"], "use KEY=V1,V2,..."),
        (["sweep", "--grid", "survival.reflex_max_steps=4,x"], "reflex_max_steps must be an"),
        (["sweep", "--grid", "survival.reflex_max_steps=1,8"], "reflex_max_steps must be an"),
        (["sweep", "--seeds", "9-2"], "seed range"),
        (["sweep", "--methods", "ee,xx"], "methods"),
        (["sweep", "--seeds", "0-1", "--ray", "127.0.0.1:1"], "cannot reach a Ray cluster"),
    ],
)
def test_bad_input_is_one_line_and_leaves_no_run_dir(tmp_path: Path, args, message) -> None:
    out = tmp_path / "out"
    r = cli(*args, "--out", str(out))
    assert r.returncode == 2
    assert message in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_existing_out_needs_resume_or_force(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    r = cli("evolve", "--out", str(out))
    assert r.returncode == 2 and "--resume" in r.stderr
    r = cli("evolve", "--out", str(out), "--force")
    assert r.returncode == 2 and "refusing to delete" in r.stderr
    assert (out / "notes.txt").read_text() == "mine"


def test_config_prints_a_commented_toml_that_evolve_accepts(tmp_path: Path) -> None:
    r = cli("config", "--set", "survival.mate_distance=0.4")
    assert r.returncode == 0, r.stderr
    parsed = tomllib.loads(r.stdout)
    assert parsed["survival"]["mate_distance"] == 0.4
    assert parsed["evolution"]["lifetime_steps"] == 400
    assert "# largest IR port-to-port distance" in r.stdout
    path = tmp_path / "config.toml"
    path.write_text(r.stdout)
    r = cli("config", "--config", str(path))
    assert r.returncode == 0 and tomllib.loads(r.stdout) == parsed


def test_grid_sweep_runs_every_cell_and_compares_them(tmp_path: Path) -> None:
    out = tmp_path / "grid"
    args = ["sweep", "--methods", "ee", "--seeds", "0", "--generations", "1", "--workers", "2"]
    grid = ["--grid", "survival.mate_consecutive_steps=1,2", "--policies", "reactive"]
    r = cli(*args, *grid, "--out", str(out), "--no-progress", *tiny_args())
    assert r.returncode == 0, r.stderr
    assert "sweep: 2 runs x 1 generations on 2 workers; projected run time about" in r.stdout
    record = json.loads((out / "grid.json").read_text())
    assert [c["name"] for c in record["cells"]] == [
        "mate_consecutive_steps=1", "mate_consecutive_steps=2"
    ]
    for steps in (1, 2):
        run = json.loads((out / f"mate_consecutive_steps={steps}" / "ee-seed000" / "run.json")
                         .read_text())  # fmt: skip
        assert run["config"]["survival"]["mate_consecutive_steps"] == steps
    cells = pd.read_csv(out / "figures" / "cells.csv")
    assert cells["survival.mate_consecutive_steps"].tolist() == [1, 2]
    assert (out / "figures" / "cells.png").exists()
    # Resuming with another grid is refused before anything runs.
    other = ["--grid", "survival.mate_consecutive_steps=1,3"]
    r = cli(*args, *other, "--out", str(out), "--resume", "--no-progress", *tiny_args())
    assert r.returncode == 2 and "another grid" in r.stderr


def test_a_run_killed_before_its_first_record_can_start_again(tmp_path: Path) -> None:
    from evolution.lab.experiment import VERSIONS_FILE, prepare_out_dir

    out = tmp_path / "run"
    out.mkdir()
    (out / VERSIONS_FILE).write_text("{}")  # all that a run killed at once leaves
    assert prepare_out_dir(out, resume=False, force=False) == out
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="exists and is not empty"):
        prepare_out_dir(out, resume=False, force=False)


@pytest.mark.parametrize(
    "leftovers",
    [
        {"run.json": '{"config": {"meth'},  # cut short
        {"run.json": "[]"},
        {".run.json.abc123.partial.json": "{"},  # a killed atomic write
        {"checkpoints/": ""},
        {"checkpoints/.gen_00000.ckpt.x.partial.ckpt": "", "run.json": ""},
    ],
)
def test_a_run_stopped_while_starting_is_replaced_with_force(tmp_path: Path, leftovers) -> None:
    from evolution.lab.experiment import (
        VERSIONS_FILE,
        prepare_out_dir,
        resume_run,
        stopped_while_starting,
    )

    out = tmp_path / "run"
    out.mkdir()
    command = ["cyber-rodent", "evolve", "--seed", "3", "--out", str(out)]
    (out / VERSIONS_FILE).write_text(json.dumps({"command": command}))
    for name, text in leftovers.items():
        path = out / name
        if name.endswith("/"):
            path.mkdir()
        else:
            path.parent.mkdir(exist_ok=True)
            path.write_text(text)
    assert stopped_while_starting(out)
    with pytest.raises(ValueError, match="stopped while starting.*--force"):
        prepare_out_dir(out, resume=False, force=False)
    with pytest.raises(ValueError, match="--resume: .* start it again with --force"):
        prepare_out_dir(out, resume=True, force=False)
    with pytest.raises(ValueError, match=r"nothing to resume.*evolve --seed 3 --out .* --force"):
        resume_run(out)
    assert prepare_out_dir(out, resume=False, force=True) == out
    assert not out.exists()  # cleared; the run creates it again once it has started


def test_a_run_or_notes_are_not_taken_for_a_stopped_start(tmp_path: Path) -> None:
    from evolution.lab.experiment import VERSIONS_FILE, stopped_while_starting

    run = tmp_path / "run"
    run.mkdir()
    (run / VERSIONS_FILE).write_text("{}")
    (run / "run.json").write_text('{"seed": 0}')  # a readable record: a run to continue
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / VERSIONS_FILE).write_text("{}")
    (notes / "notes.txt").write_text("mine")
    assert not stopped_while_starting(run) and not stopped_while_starting(notes)
    assert not stopped_while_starting(tmp_path / "missing")


def test_resume_points_a_sweep_directory_to_sweep_resume(tmp_path: Path) -> None:
    out = tmp_path / "fig6"
    r = cli("sweep", "--seeds", "0", "--ray", "127.0.0.1:1", "--out", str(out))
    assert r.returncode == 2 and not out.exists()
    out.mkdir()
    argv = ["cyber-rodent", "sweep", "--seeds", "0-3", "--out", str(out), "--force"]
    (out / "sweep.json").write_text(json.dumps({"command": argv}))
    r = cli("resume", str(out))
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1
    assert "sweep --resume: cyber-rodent sweep --seeds 0-3 --out" in r.stderr
    assert r.stderr.rstrip().endswith("--resume") and "--force" not in r.stderr


def test_projected_sweep_time_scales_with_the_work() -> None:
    from evolution.lab.sweep import RENDERED_STEP_COST, projected_seconds

    spec = SweepSpec(("ee",), (0, 1), 10, TINY_OVERRIDES)
    base = projected_seconds(spec, workers=1)
    assert base > 0
    longer = SweepSpec(("ee",), (0, 1), 20, TINY_OVERRIDES)
    assert projected_seconds(longer, workers=1) == pytest.approx(2 * base)
    assert projected_seconds(spec, workers=2) == pytest.approx(base / 2)
    assert projected_seconds(spec, workers=8) == pytest.approx(base / 2)  # 2 runs, 2 at a time
    rendered = SweepSpec(("ee",), (0, 1), 10, {**TINY_OVERRIDES, "vision": "rendered"})
    assert projected_seconds(rendered, workers=1) == pytest.approx(RENDERED_STEP_COST * base)
    # The paper's Fig. 6 on 2 workers: hours, not minutes or days.
    fig6 = SweepSpec(("ee", "ce"), parse_seeds("0-19"), 120)
    assert 2 * 3600 < projected_seconds(fig6, workers=2) < 24 * 3600


def test_sweep_refuses_too_many_runs_before_listing_them() -> None:
    from evolution.lab.sweep import MAX_RUNS

    with pytest.raises(ValueError, match=f"more than {MAX_RUNS} seeds"):
        parse_seeds(f"0-{10**12}")
    grid = (("survival.mate_consecutive_steps", tuple(range(1, 101))),)
    with pytest.raises(ValueError, match=f"at most {MAX_RUNS} runs"):
        SweepSpec(("ee", "ce"), tuple(range(100)), 1, grid=grid)
