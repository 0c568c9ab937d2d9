"""The Fig. 7 reproduction command: runs, reuse of finished runs, resume, tables and figures."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.paper_fig7 import main, summarise
from evolution.lab.api import RunOutput, RunSpec
from evolution.lab.experiment import evolve

#: A tiny source colony: 2 robots x 5 agents, 40-step lifetimes.
SMALL = ["population_size=10", "n_robots=2", "lifetime_steps=40", "time_sharing_steps=20"]


def argv(root: Path, seeds: str = "0-1", source_generations: int = 2) -> list[str]:
    args = ["--out", str(root / "runs"), "--seeds", seeds, "--generations", "3",
            "--source-generations", str(source_generations), "--table-dir",
            str(root / "tables"), "--figure-dir", str(root / "images"),
            "--no-progress"]  # fmt: skip
    for item in SMALL:
        args += ["--set", item]
    return args


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The whole command once, with a tiny source and two transfer seeds."""
    root = tmp_path_factory.mktemp("fig7")
    assert main(argv(root)) == 0
    return root


def test_writes_tables_and_figures(finished: Path) -> None:
    tables, images = finished / "tables", finished / "images"
    for name in ("source/statistics.csv", "source/run.json", "fig7_pooled.csv",
                 "fig7_summary.csv"):  # fmt: skip
        assert (tables / name).is_file()
    for seed in (0, 1):
        for name in ("statistics_per_robot.csv", "transfer.json"):
            assert (tables / f"transfer-seed{seed}" / name).is_file()
    assert not list(tables.rglob("*.ckpt"))
    for name in ("fig7_seed0", "fig7_pooled"):
        assert (images / f"{name}.png").is_file() and (images / f"{name}.pdf").is_file()
    pooled = pd.read_csv(tables / "fig7_pooled.csv")
    assert set(pooled["robot"]) == {0, 1, 2} and set(pooled["runs"]) == {2}
    summary = pd.read_csv(tables / "fig7_summary.csv")
    assert list(summary.columns) == ["seed", "robot", "batteries_first3", "batteries_last3",
                                     "deaths"]  # fmt: skip
    assert len(summary) == 6 and list(summary["seed"]) == [0, 0, 0, 1, 1, 1]
    for seed in (0, 1):
        per_robot = pd.read_csv(finished / "runs" / f"transfer-seed{seed}" /
                                "statistics_per_robot.csv")  # fmt: skip
        events = pd.read_csv(finished / "runs" / f"transfer-seed{seed}" / "events.csv")
        expected = summarise(per_robot, events)
        got = summary[summary["seed"] == seed].drop(columns="seed").reset_index(drop=True)
        pd.testing.assert_frame_equal(got, expected, check_exact=False, rtol=1e-3)


def test_reuses_finished_runs_and_reruns_an_interrupted_transfer(
    finished: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = finished / "runs"
    before = {s: (runs / f"transfer-seed{s}" / "statistics_per_robot.csv").read_bytes()
              for s in (0, 1)}  # fmt: skip
    source = (runs / "source" / "statistics.csv").read_bytes()
    (runs / "transfer-seed1" / "events.csv").unlink()  # as if killed before the end
    assert main(argv(finished)) == 0
    out = capsys.readouterr().out
    assert "source (2 generations): reused" in out
    assert "transfer seed 0: reused" in out and "transfer seed 1: transferred" in out
    assert "batteries_first3" in out  # the summary is printed
    assert (runs / "source" / "statistics.csv").read_bytes() == source
    for seed in (0, 1):
        path = runs / f"transfer-seed{seed}" / "statistics_per_robot.csv"
        assert path.read_bytes() == before[seed]


def test_resumes_an_unfinished_source_to_the_same_result(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    overrides = dict(item.split("=") for item in SMALL)
    spec = RunSpec("ee", 1, 0, overrides={k: int(v) for k, v in overrides.items()})
    evolve(spec, RunOutput(tmp_path / "runs" / "source", keep_checkpoints=0))
    assert main(argv(tmp_path, seeds="0")) == 0
    assert "source (2 generations): resumed" in capsys.readouterr().out
    for name in ("source/statistics.csv", "transfer-seed0/statistics_per_robot.csv"):
        assert (tmp_path / "runs" / name).read_bytes() == (finished / "runs" / name).read_bytes()


@pytest.mark.parametrize(
    "change, message",
    [
        (["--seeds", "3-1"], "the end is below the start"),
        (["--generations", "0"], "--generations must be >= 1"),
        (["--source-generations", "0"], "--source-generations must be >= 1"),
        (["--source-seed", "-1"], "--source-seed must be >= 0"),
        (["--set", "population_size=7"], "population"),
        (["--set", "no_such_key=1"], "no_such_key"),
    ],
)
def test_bad_arguments_exit_2_before_creating_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: list[str], message: str
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(argv(tmp_path) + change)
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_an_out_path_that_is_a_file_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "runs").write_text("")
    with pytest.raises(SystemExit):
        main(argv(tmp_path))
    assert "--out" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]


def test_summary_windows_skip_missing_generations_and_count_deaths() -> None:
    per_robot = pd.DataFrame({
        "generation": [0, 0, 1, 1, 2, 3, 3, 4, 4],
        "robot": [0, 1, 0, 1, 0, 0, 1, 0, 1],
        "batteries_mean": [1.0, 2.0, 3.0, math.nan, 5.0, 6.0, 4.0, 7.0, 8.0],
    })  # fmt: skip
    events = pd.DataFrame({"robot": [1, 1, 0, 1], "kind": ["death", "death", "dock", "mate"]})
    summary = summarise(per_robot, events)
    assert list(summary["robot"]) == [0, 1]
    # first 3 generations 0-2, last 3 generations 2-4; NaN and absent generations are skipped
    assert list(summary["batteries_first3"]) == [3.0, 2.0]
    assert list(summary["batteries_last3"]) == [6.0, 6.0]
    assert list(summary["deaths"]) == [0, 2]
