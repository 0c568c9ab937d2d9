"""Progress output: a bar on a terminal, at most a plain line a minute without one."""

from __future__ import annotations

import io
import os
import sys

import pytest

from cyber_rodent.progress import LINE_INTERVAL, LineProgress, progress_bar


def test_without_a_terminal_progress_is_plain_lines(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # a log file, not a terminal
    bar = progress_bar(total=5, desc="EE seed 0", unit="gen", dynamic_ncols=True)
    assert isinstance(bar, LineProgress) and bar.interval == LINE_INTERVAL == 60.0
    for _ in range(1000):  # a fast loop of updates prints nothing within the minute
        bar.update(0.001)
        bar.set_postfix({"steps": 10}, refresh=False)
        bar.refresh()
    bar.close()
    assert sys.stderr.getvalue() == ""


def test_a_line_says_where_the_work_is() -> None:
    out = io.StringIO()
    bar = LineProgress(10, desc="sweep (4 runs)", unit="gen", initial=2, file=out, interval=0.0)
    bar.n = 6
    bar.set_postfix(batteries="14.2", matings="3.10")
    lines = out.getvalue().splitlines()
    assert len(lines) == 1 and "\r" not in out.getvalue()
    assert lines[0].startswith("sweep (4 runs): 6/10 gen (60%), ")
    assert "elapsed" in lines[0] and "left" in lines[0]
    assert lines[0].endswith("batteries=14.2, matings=3.10")
    bar.close()
    bar.update()
    assert len(out.getvalue().splitlines()) == 1  # nothing after close


def test_lines_are_at_most_one_per_interval() -> None:
    out = io.StringIO()
    bar = LineProgress(100, desc="x", file=out, interval=3600.0)
    for _ in range(100):
        bar.update()
    assert out.getvalue() == ""


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_on_a_terminal_progress_is_a_tqdm_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    from tqdm import tqdm

    leader, follower = os.openpty()
    with open(follower, "w") as terminal:
        monkeypatch.setattr(sys, "stderr", terminal)
        bar = progress_bar(total=3, desc="render", unit="frame")
        try:
            assert isinstance(bar, tqdm)
        finally:
            bar.close()
    os.close(leader)
