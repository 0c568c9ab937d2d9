"""The rescue's counterfactual (benchmarks/jam_rescue.py): a continuation from a checkpoint is
a pure function of it, and bad arguments exit 2 in one line. (The rescue itself is tested on
hand-built scenes in tests/test_watchdog.py.)"""

from __future__ import annotations

from pathlib import Path

from benchmarks.jam_rescue import continue_run, describe, main
from evolution.config import EvolutionConfig
from evolution.lab.api import run as run_evolution
from evolution.runner import RunConfig

TINY = RunConfig(evolution=EvolutionConfig(
    population_size=8, n_robots=4, lifetime_steps=200, time_sharing_steps=50
))  # fmt: skip


def test_a_continuation_is_a_pure_function_of_the_checkpoint(tmp_path: Path) -> None:
    run_evolution("ee", 2, 3, config=TINY, out_dir=tmp_path)  # keeps the newest 3
    checkpoint = tmp_path / "checkpoints" / "gen_00001.ckpt"
    off = continue_run(checkpoint, 300, rescue=False)
    again = continue_run(checkpoint, 300, rescue=False)
    assert off == again  # a pure function of the checkpoint
    assert all(robot["rescues"] == 0 for robot in off["robots"])
    text = describe(off)
    assert text.startswith("rescue off, 300 control steps:") and "CR3" in text


def test_bad_steps_exit_2_in_one_line(tmp_path: Path, capsys) -> None:
    assert main([str(tmp_path / "none.ckpt"), "--steps", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--steps" in err[0]
