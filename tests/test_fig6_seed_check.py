"""The check of one seed's new Fig. 6 runs against the published ones, on hand-made tables."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmarks.fig6_seed_check import check, main


def _run(path: Path, batteries: float, matings: float) -> None:
    path.mkdir(parents=True)
    generations = range(120)
    pd.DataFrame({
        "generation": generations, "seed": 0,
        "batteries_mean": [batteries if g >= 100 else 0.0 for g in generations],
        "matings_mean": [matings] * 120, "completed": [80] * 120,
    }).to_csv(path / "statistics.csv", index=False)  # fmt: skip
    (path / "run.json").write_text(json.dumps({"versions": {"git_commit": "abc"}}))


def test_a_mean_that_moved_more_than_the_spread_is_flagged(tmp_path: Path) -> None:
    published = pd.DataFrame({
        "method": ["ee"] * 3, "seed": [0, 1, 2], "generations": "100-119",
        "batteries": [19.0, 20.0, 21.0], "matings": [4.0, 4.0, 4.0], "completed": [80.0] * 3,
    })  # fmt: skip
    # The window's mean is 23 batteries (generations 100-119 only), 4 matings.
    _run(tmp_path / "runs" / "ee-seed000", 23.0, 4.0)
    table = check(tmp_path / "runs", published).set_index("quantity")
    # batteries: 23 - 19 = 4 > std(19, 20, 21) = 1: moved; matings: 0 within a spread of 0.
    assert table.loc["batteries", "difference"] == pytest.approx(4.0)
    assert table.loc["batteries", "published_std"] == pytest.approx(1.0)
    assert bool(table.loc["batteries", "moved"])
    assert not bool(table.loc["matings", "moved"])
    assert table.loc["batteries", "commit"] == "abc"
    published.to_csv(tmp_path / "published.csv", index=False)
    out = tmp_path / "check.csv"
    main([str(tmp_path / "runs"), "--published", str(tmp_path / "published.csv"), "--table",
          str(out)])  # fmt: skip
    assert len(pd.read_csv(out)) == 3


def test_the_rerun_is_compared_with_the_published_runs_as_sets(tmp_path: Path) -> None:
    published = pd.DataFrame({
        "method": ["ee"] * 3, "seed": [0, 1, 2], "generations": "100-119",
        "batteries": [1.0, 2.0, 3.0], "matings": [4.0, 5.0, 6.0], "completed": [80.0] * 3,
    })  # fmt: skip
    for seed, batteries in enumerate((4.0, 5.0, 6.0)):
        _run(tmp_path / "runs" / f"ee-seed{seed:03d}", batteries, 5.5 - seed)
    published.to_csv(tmp_path / "published.csv", index=False)
    out = tmp_path / "sets.csv"
    main([str(tmp_path / "runs"), "--published", str(tmp_path / "published.csv"), "--sets",
          str(out)])  # fmt: skip
    table = pd.read_csv(out).set_index("quantity")
    # Batteries: every new run (4, 5, 6) above every published one (1, 2, 3): U = 9, the
    # rank-biserial effect is +1, and the exact two-sided p is 2 / C(6, 3) = 0.1.
    assert table.loc["batteries", "new_mean"] == pytest.approx(5.0)
    assert table.loc["batteries", "difference"] == pytest.approx(3.0)
    assert table.loc["batteries", "rank_biserial"] == pytest.approx(1.0)
    assert table.loc["batteries", "p"] == pytest.approx(0.1)
    assert table.loc["batteries", "test"] == "exact"
    # Matings: new 5.5, 4.5, 3.5 against 4, 5, 6: U = 3 of 9, effect 2 * 3 / 9 - 1 = -1/3.
    assert table.loc["matings", "rank_biserial"] == pytest.approx(-1 / 3, abs=1e-5)  # 5 decimals
    assert table.loc["matings", "new_std"] == pytest.approx(1.0)
