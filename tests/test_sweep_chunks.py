"""The Ray backend's unit of work without Ray: a run advanced chunk by chunk through
:func:`evolution.lab.sweep.advance_run`, its files kept only by the caller, ends with the files of
one uninterrupted run, byte for byte."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from evolution.checkpoint import CheckpointError
from evolution.lab.api import RunOutput, RunSpec
from evolution.lab.sweep import KEEP_CHECKPOINTS, RunChunk, advance_run, run_one

#: Two robots, four agents, short lives: a generation takes a fraction of a second.
TINY = {"population_size": 4, "n_robots": 2, "lifetime_steps": 60, "time_sharing_steps": 30}
GENERATIONS = 3


def files_of(directory: Path) -> dict[str, bytes]:
    return {
        path.relative_to(directory).as_posix(): path.read_bytes()
        for path in sorted(directory.rglob("*"))
        if path.is_file()
    }


def test_chunks_give_the_files_of_an_uninterrupted_run(tmp_path: Path) -> None:
    whole = tmp_path / "whole"
    table = run_one(RunSpec("ee", GENERATIONS, 0, overrides=TINY, policies="reactive"),
                    RunOutput(str(whole)))  # fmt: skip

    held: dict[str, bytes] = {}  # the driver's copy of the run directory
    checkpoint: tuple[str, bytes] | None = None
    progress = []
    while True:
        task = RunChunk("ee", 0, GENERATIONS, 1, TINY, "reactive", KEEP_CHECKPOINTS, checkpoint)
        result = advance_run(task)
        progress.append(result.completed)
        assert "events.csv" in result.files or result.completed < GENERATIONS
        held.update(result.files)
        kept = sorted(name for name in held if name.startswith("checkpoints/"))
        for name in kept[:-KEEP_CHECKPOINTS]:
            del held[name]
        checkpoint = (Path(kept[-1]).name, held[kept[-1]])
        if result.completed >= GENERATIONS:
            break
    assert progress == [1, 2, 3]  # one generation per chunk, each from the last checkpoint
    assert sorted(held) == sorted(files_of(whole))
    for name, data in files_of(whole).items():
        assert held[name] == data, name
    pd.testing.assert_frame_equal(result.table, table)

    # A finished run's chunk runs nothing and writes no checkpoint, as a resume does.
    again = advance_run(task._replace(checkpoint=checkpoint))
    assert again.completed == GENERATIONS
    assert not [name for name in again.files if name.startswith("checkpoints/")]
    assert again.files["statistics.csv"] == held["statistics.csv"]


def test_a_chunk_refuses_the_checkpoint_of_another_run() -> None:
    first = advance_run(RunChunk("ee", 0, 1, 1, TINY, "reactive", KEEP_CHECKPOINTS, None))
    checkpoint = ("gen_00001.ckpt", first.files["checkpoints/gen_00001.ckpt"])
    with pytest.raises(CheckpointError):
        advance_run(RunChunk("ee", 1, 2, 1, TINY, "reactive", KEEP_CHECKPOINTS, checkpoint))


def test_a_step_budget_ends_a_run_in_chunks_as_in_one_process(tmp_path: Path) -> None:
    """A budget of 150 control steps stops the run before its 3 generations (each takes 120
    steps here): locally and in chunks it stops at step 150 with the same files, and the
    chunk that spends the budget reports the run finished."""
    whole = tmp_path / "whole"
    spec = RunSpec("ee", GENERATIONS, 0, overrides=TINY, policies="reactive", max_steps=150)
    run_one(spec, RunOutput(str(whole)))
    record = (whole / "run.json").read_text()
    assert '"max_steps": 150' in record and '"control_steps": 150' in record
    held: dict[str, bytes] = {}
    checkpoint: tuple[str, bytes] | None = None
    for _ in range(5):
        task = RunChunk("ee", 0, GENERATIONS, 1, TINY, "reactive", KEEP_CHECKPOINTS,
                        checkpoint, max_steps=150)  # fmt: skip
        result = advance_run(task)
        held.update(result.files)
        kept = sorted(name for name in held if name.startswith("checkpoints/"))
        checkpoint = (Path(kept[-1]).name, held[kept[-1]])
        if result.finished:
            break
    assert result.finished and result.completed == 1
    for name, data in files_of(whole).items():
        assert held[name] == data, name
