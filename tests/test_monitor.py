"""Live monitoring with TensorBoard (evolution/lab/monitor.py): what the event files hold equals
statistics.csv, results are unchanged, resume writes each generation once, and a missing package
or an unusable directory is refused in one line before anything is created."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from evolution.lab.api import RunOutput
from evolution.lab.monitor import (
    SCALAR_TAGS,
    WEIGHT_HISTOGRAM_TAG,
    check_tensorboard,
    population_weights,
    tag_of,
    weight_scalars,
)
from evolution.lab.sweep import (
    KEEP_CHECKPOINTS,
    Execution,
    RunChunk,
    SweepSpec,
    advance_run,
    sweep,
)

#: Two robots, four agents, short lives: a generation takes a few seconds, and with the
#: trained behaviours and a longer mating range some agents complete the task (the batteries
#: and matings columns are numbers, not only NaN).
TINY = {
    "population_size": 4,
    "n_robots": 2,
    "lifetime_steps": 60,
    "time_sharing_steps": 30,
    "survival.mate_distance": 0.4,
}
NOT_SCALARS = ("generation", "method", "seed")


def tiny_args() -> list[str]:
    return [a for key, value in TINY.items() for a in ("--set", f"{key}={value}")]


def cli(*args: str, block_tensorboard: bool = False) -> subprocess.CompletedProcess:
    """The command line in a subprocess; with ``block_tensorboard`` as if the package were not
    installed (its import fails)."""
    block = "sys.modules['tensorboard'] = None; " if block_tensorboard else ""
    code = f"import sys; {block}from evolution.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=600,
        env={**os.environ, "LP_NUM_THREADS": "1"},
    )  # fmt: skip


def read_board(directory: Path):
    """TensorBoard's own reader over every event file of ``directory`` (one run)."""
    from tensorboard.backend.event_processing import event_accumulator as ea

    accumulator = ea.EventAccumulator(
        str(directory), size_guidance={ea.SCALARS: 0, ea.HISTOGRAMS: 0}
    )
    accumulator.Reload()
    return accumulator


def assert_board_equals_table(directory: Path, table: pd.DataFrame) -> None:
    """Every numeric column of ``table`` is a scalar whose steps are the generations and whose
    values are the table's (as TensorBoard stores them: float32); a weight histogram and the
    weights' spread at every generation."""
    board = read_board(directory)
    tags = board.Tags()
    generations = table["generation"].tolist()
    columns = [c for c in table.columns if c not in NOT_SCALARS]
    assert set(columns) == set(SCALAR_TAGS)  # every column has its own group and name
    for column in columns:
        events = board.Scalars(tag_of(column))
        assert [e.step for e in events] == generations, column
        for event, value in zip(events, table[column], strict=True):
            expected = float(np.float32(value))
            assert (math.isnan(event.value) and math.isnan(expected)) or (
                event.value == expected
            ), (column, event.step, event.value, value)
    assert set(tags["scalars"]) == {
        *map(tag_of, columns), "weights/spread", "weights/mean_abs"
    }  # fmt: skip
    for tag in ("weights/spread", "weights/mean_abs"):
        assert [e.step for e in board.Scalars(tag)] == generations
    histograms = board.Histograms(WEIGHT_HISTOGRAM_TAG)
    assert [h.step for h in histograms] == generations
    for h in histograms:
        assert h.histogram_value.num == TINY["population_size"] * 39
        assert sum(h.histogram_value.bucket) == h.histogram_value.num


def test_evolve_tensorboard_equals_statistics_and_changes_nothing(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    # Seed 3: two agents complete the task in generation 0, so the batteries and matings columns
    # hold numbers (and NaN after it, which the board must show as NaN too).
    common = ["evolve", "--generations", "3", "--seed", "3", "--no-progress", *tiny_args()]
    r = cli(*common, "--out", str(tmp_path / "plain"))
    assert r.returncode == 0, r.stderr
    board = tmp_path / "tb"
    r = cli(*common, "--out", str(tmp_path / "run"), "--tensorboard", str(board))
    assert r.returncode == 0, r.stderr
    for name in ("statistics.csv", "statistics_per_robot.csv", "events.csv"):
        assert (tmp_path / "run" / name).read_bytes() == (tmp_path / "plain" / name).read_bytes()
    table = pd.read_csv(tmp_path / "run" / "statistics.csv")
    assert table["completed"].max() > 0  # the batteries and matings columns hold numbers
    assert [p.name for p in board.iterdir()] == ["run"]  # one TensorBoard run per run directory
    assert_board_equals_table(board / "run", table)

    # The weights are the population's when the generation closed: the last one's is in the
    # checkpoint written at that step.
    from behaviours import BehaviourPolicies
    from evolution.runner import EvolutionRunner, latest_checkpoint

    newest = latest_checkpoint(tmp_path / "run" / "checkpoints")
    assert newest is not None and newest.name == "gen_00003.ckpt"
    with EvolutionRunner.from_checkpoint(newest, BehaviourPolicies.load_default()) as runner:
        weights = population_weights(runner)
    last = read_board(board / "run")
    for tag, value in weight_scalars(weights).items():
        assert last.Scalars(tag)[-1].value == float(np.float32(value))
    histogram = last.Histograms(WEIGHT_HISTOGRAM_TAG)[-1].histogram_value
    assert (histogram.min, histogram.max) == (weights.min(), weights.max())
    assert histogram.sum == pytest.approx(weights.sum())


def test_resume_continues_without_repeating_a_generation(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    from evolution.lab.api import RunOutput, RunSpec, execute

    out, board = tmp_path / "run", tmp_path / "tb"
    # A checkpoint every 2 generations: the third is written to TensorBoard but not
    # checkpointed, so the resumed run closes it again.
    first = execute(
        RunSpec("ee", 3, 0, overrides=TINY, policies="reactive"),
        RunOutput(out, checkpoint_every=2, tensorboard=board),
    )
    assert len(first) == 3 and sorted(p.name for p in (out / "checkpoints").iterdir()) == [
        "gen_00002.ckpt"
    ]
    assert [e.step for e in read_board(board).Scalars("agents/deaths")] == [0, 1, 2]
    table = execute(
        RunSpec("ee", 4, 0, overrides=TINY, policies="reactive"),
        RunOutput(out, tensorboard=board),
        resume=True,
    )
    assert len(list(board.glob("events.out.tfevents.*"))) == 2  # a new file for the resumed run
    pd.testing.assert_frame_equal(table, pd.read_csv(out / "statistics.csv"))
    assert_board_equals_table(board, table)  # generations 0-3, each once


def test_tensorboard_without_out_dir(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    from evolution.lab.api import RunOutput, RunSpec, execute, run

    spec = RunSpec("ce", 2, 0, overrides=TINY, policies="reactive")
    table = execute(spec, RunOutput(tensorboard=tmp_path / "tb"))
    pd.testing.assert_frame_equal(table, run("ce", 2, 0, policies="reactive", **TINY))
    assert_board_equals_table(tmp_path / "tb", table)


def test_local_sweep_writes_one_tensorboard_run_per_run(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    spec = SweepSpec(("ee", "ce"), (0,), 1, TINY, policies="reactive")
    board = tmp_path / "tb"
    results = sweep(spec, RunOutput(tmp_path / "sweep", tensorboard=board), Execution(workers=2))
    assert sorted(p.name for p in board.iterdir()) == ["ce-seed000", "ee-seed000"]
    for member, table in results.items():
        assert_board_equals_table(board / f"{member.method}-seed{member.seed:03d}", table)


def test_a_ray_chunk_returns_its_generations_records() -> None:
    task = RunChunk("ee", 0, 2, 2, TINY, "reactive", KEEP_CHECKPOINTS, None, monitor=True)
    result = advance_run(task)
    assert [r.generation for r in result.generations] == [0, 1]
    for record, (_, row) in zip(result.generations, result.table.iterrows(), strict=True):
        for column in SCALAR_TAGS:
            a, b = record.scalars[tag_of(column)], float(row[column])
            assert (math.isnan(a) and math.isnan(b)) or a == b, column
        assert record.weights.shape == (TINY["population_size"], 39)
    assert advance_run(task._replace(monitor=False)).generations == ()


def test_missing_package_is_one_line_naming_the_extra(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "tensorboard", None)  # as if it were not installed
    with pytest.raises(ValueError, match=r"--tensorboard needs tensorboard: pip install "
                       r"'cyber-rodent\[monitor\]'"):  # fmt: skip
        check_tensorboard(tmp_path / "tb")
    assert not (tmp_path / "tb").exists()

    for command in (
        ["evolve", "--generations", "1", *tiny_args()],
        ["sweep", "--seeds", "0", "--generations", "1", *tiny_args()],
    ):
        out, board = tmp_path / command[0], tmp_path / f"tb-{command[0]}"
        r = cli(*command, "--out", str(out), "--tensorboard", str(board), block_tensorboard=True)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
        assert "--tensorboard" in lines[0] and "pip install 'cyber-rodent[monitor]'" in lines[0]
        assert not out.exists() and not board.exists()


@pytest.mark.parametrize("command", ["evolve", "sweep"])
def test_unusable_tensorboard_dir_is_refused_before_anything_is_created(
    tmp_path: Path, command: str
) -> None:
    pytest.importorskip("tensorboard")
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    out = tmp_path / "out"
    for board, message in ((blocker, "is a file"), (blocker / "tb", "is a file")):
        r = cli(command, "--generations", "1", *tiny_args(), "--out", str(out),
                "--tensorboard", str(board))  # fmt: skip
        assert r.returncode == 2
        assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
        assert "--tensorboard" in r.stderr and message in r.stderr, r.stderr
        assert not out.exists()
    assert blocker.read_text() == "not a directory"


@pytest.mark.slow
def test_ray_sweep_writes_tensorboard_from_the_driver(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    pytest.importorskip("tensorboard")
    spec = SweepSpec(("ee",), (0, 1), 2, TINY, policies="reactive")
    board = tmp_path / "tb"
    output = RunOutput(tmp_path / "sweep", tensorboard=board)
    results = sweep(spec, output, Execution("ray", 2, "local"))
    local = sweep(spec, RunOutput(tmp_path / "local"), Execution(workers=2))
    assert sorted(p.name for p in board.iterdir()) == ["ee-seed000", "ee-seed001"]
    for member, table in results.items():
        pd.testing.assert_frame_equal(table, local[member])  # monitoring changes nothing
        directory = board / f"{member.method}-seed{member.seed:03d}"
        assert len(list(directory.glob("events.out.tfevents.*"))) == 1  # one writer per run
        assert_board_equals_table(directory, table)
