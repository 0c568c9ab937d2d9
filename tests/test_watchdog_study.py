"""The watchdog study's counting, on hand-built event logs."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from benchmarks.watchdog_study import episodes, main, merged, share_within


def _events(rows: list[tuple[int, int, str, int]]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["step", "robot", "kind", "value"])


def test_spells_close_at_their_end_event_or_at_the_run_end() -> None:
    events = _events([(100, 0, "stuck", 0), (130, 0, "stuck_end", 30), (500, 1, "stuck", 0)])
    found = episodes(events, "stuck", "stuck_end", last_step=999)
    assert found.values.tolist() == [[0, 100, 30], [1, 500, 500]]


def test_spells_of_one_robot_closer_than_the_gap_are_one_trouble() -> None:
    # Robot 0: 100-130, then 30 steps free (130-160), then 160-200: one trouble of 100 steps
    # with a gap of 50, two with a gap of 30 (a gap of exactly 30 is not "fewer than 30").
    # Robot 1 is 10 steps from robot 0's spell but is another robot: never joined.
    spells = pd.DataFrame([(0, 100, 30), (0, 160, 40), (1, 140, 5)],
                          columns=["robot", "step", "steps"])  # fmt: skip
    assert merged(spells, 50).values.tolist() == [[0, 100, 100], [1, 140, 5]]
    assert merged(spells, 30).values.tolist() == [[0, 100, 30], [0, 160, 40], [1, 140, 5]]
    assert merged(spells.iloc[:0], 50).empty


def test_the_share_within_a_window_counts_only_its_steps() -> None:
    # Steps 111..200 (after step 110, up to 200) for 2 robots: 180 robot-steps. Robot 0's spell
    # covers steps 100..129, 19 of them inside; robot 1's covers 190..219, 11 inside.
    spells = pd.DataFrame([(0, 100, 30), (1, 190, 30)], columns=["robot", "step", "steps"])
    assert share_within(spells, 110, 200, robots=2) == (19 + 11) / 180
    assert share_within(spells.iloc[:0], 110, 200, robots=2) == 0.0


def test_bad_options_exit_2_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for bad in (["--window", "5-2"], ["--lagging", "40"], ["--merge-gap", "0"]):
        assert main([str(tmp_path), *bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and bad[0] in err[0]
