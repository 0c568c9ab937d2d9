"""The colony study's second round: its plan's arithmetic on hand-computed cases."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmarks.colony_toggles import (
    GROUP,
    ROBOT_HOUR_WINDOW,
    Run,
    cliff_delta,
    holm,
    main,
    parse_groups,
    pending,
    per_life,
    per_robot_hour,
    run_row,
    study_cells,
    study_spec,
)
from evolution.lab.sweep import run_dir


def test_holm_steps_down_and_keeps_the_order() -> None:
    # sorted: 0.01 x 3 = 0.03; 0.03 x 2 = 0.06; 0.04 x 1 = 0.04, raised to the running 0.06
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, 0.6]) == pytest.approx([1.0, 1.0])  # capped at 1
    adjusted = holm([0.02, math.nan])
    assert adjusted[0] == pytest.approx(0.02) and math.isnan(adjusted[1])  # NaN is no test


def test_cliff_delta_is_the_share_of_pairs_above_minus_below() -> None:
    assert cliff_delta(np.array([3.0, 4.0]), np.array([1.0, 2.0])) == 1.0
    assert cliff_delta(np.array([1.0, 3.0]), np.array([2.0])) == 0.0
    # (2, 5) against (1, 3, 4): 2 beats 1; 5 beats all three; 4 pairs above, 2 below: 2 / 6
    assert cliff_delta(np.array([2.0, 5.0]), np.array([1.0, 3.0, 4.0])) == pytest.approx(2 / 6)


def _run(batteries: list[float], steps: list[int], n_robots: int = 100) -> Run:
    stats = pd.DataFrame(
        {"generation": range(len(steps)), "batteries_mean": batteries, "closed_at_step": steps}
    )
    return Run("EE-T", 0, n_robots, 0.2, stats, None, stats)


def test_the_measures_read_their_windows() -> None:
    # 100 robots x 0.2 s / 3600: 18,000 steps make 100 robot-hours.
    hours = [30, 73, 96, 97, 150]
    run = _run([1.0, 2.0, 4.0, 8.0, 16.0], [h * 180 for h in hours])
    assert ROBOT_HOUR_WINDOW == (72.0, 96.0)
    assert per_robot_hour(run) == pytest.approx(3.0)  # 73 and 96 h: in; 30 and 97 h: out
    short = _run([1.0, 2.0], [30 * 180, 90 * 180])
    assert math.isnan(per_robot_hour(short))  # never reached 96 robot-hours
    late = _run(list(map(float, range(60))), [1000 * (g + 1) for g in range(60)])
    assert per_life(late) == pytest.approx(np.mean(range(50, 60)))


def test_the_watchdog_row_counts_per_robot_hour_and_per_trouble() -> None:
    # 60 generations, the last closing at 18,000 steps: 100 robots x 18,000 x 0.2 s = 100 h.
    steps = [300 * (g + 1) for g in range(60)]
    stats = pd.DataFrame({
        "generation": range(60), "batteries_mean": 1.0, "closed_at_step": steps,
        "completed": 80, "deaths": 5, "matings_mean": 3.0, "random_share": 0.5,
    })  # fmt: skip
    dog = pd.DataFrame({"generation": range(60), "tips": 0, "jams": 0, "rescues": 0,
                        "tipped_steps": 0, "stuck_steps": 0, "robots": 100})  # fmt: skip
    dog.loc[3, ["jams", "stuck_steps"]] = (2, 30)  # two jams, 30 robot-steps stuck
    dog.loc[40, ["jams", "stuck_steps"]] = (1, 150)
    row = run_row(Run("EE-T", 0, 100, 0.2, stats, dog, stats))
    assert row["robot_hours"] == pytest.approx(100.0)
    assert row["jams_per_robot_hour"] == pytest.approx(3 / 100)
    assert row["jam_mean_steps"] == pytest.approx(180 / 3)  # 60 steps (12 s) per jam
    assert row["stuck_share"] == pytest.approx(180 * 0.2 / 3600 / 100)  # of 100 robot-hours
    assert row["tips_per_robot_hour"] == 0.0 and math.isnan(row["tip_mean_steps"])


def test_the_cells_are_the_plans() -> None:
    cells = {c.name: c for c in study_cells()}
    assert {n: c.methods for n, c in cells.items()} == {
        "t": ("ee",), "tc": ("ee",), "bc": ("ee",), "tw": ("ce", "medea"), "bw": ("ce", "medea"),
    }  # fmt: skip
    assert cells["t"].settings["evolution.spare_list"] == "position"
    assert cells["tc"].settings["evolution.spare_list"] == "colony"
    assert cells["t"].settings["world.arenas"] == 25
    assert cells["bc"].settings["world.field_size"] == 11.5
    assert GROUP["EE-P"].cell is None and GROUP["CE-P"].cell is None
    spec = study_spec()
    spec.check()  # every cell's settings are valid
    assert len(spec.runs) == 8 * 7


def test_a_bad_argument_exits_2_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--run", "--workers", "0", "--out", "/nonexistent/never"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--workers" in err[0]


def _finished_tables(path: Path, generations: int, target: int) -> None:
    path.mkdir(parents=True)
    (path / "run.json").write_text(json.dumps({"target_generations": target}))
    pd.DataFrame({"generation": range(generations)}).to_csv(path / "statistics.csv", index=False)


def test_a_published_run_is_not_run_again(tmp_path: Path) -> None:
    spec = study_spec(seeds=(0, 1), generations=3)
    out, published = tmp_path / "runs", tmp_path / "results"
    first, second = spec.runs[0], spec.runs[1]
    _finished_tables(run_dir(published, *first), generations=3, target=3)  # finished
    _finished_tables(run_dir(published, *second), generations=2, target=3)  # one short
    todo = pending(spec, out, published)
    assert first not in todo and second in todo
    assert todo == [m for m in spec.runs if m != first]  # the study's order is kept
    # --groups: only the chosen groups' runs, still in the study's order
    only = pending(spec, out, published, groups=("mEDEA-B", "EE-T"))
    assert only == [m for m in todo if (m.cell, m.method) in {("bw", "medea"), ("t", "ee")}]
    assert only and all(m in todo for m in only)


def test_groups_name_the_studys_own_cells() -> None:
    assert parse_groups("mEDEA-B, EE-T,EE-T") == ("mEDEA-B", "EE-T")
    for bad in ("EE-P", "EE-X", ""):  # P runs in Fig. 6; unknown; none at all
        with pytest.raises(ValueError, match="--groups"):
            parse_groups(bad)


def test_a_bad_group_exits_2_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--run", "--groups", "EE-Q", "--out", "/nonexistent/never"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--groups" in err[0] and "mEDEA-B" in err[0]
