"""Learning mode's figures and tables, from hand-made learning records."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from evolution.lab.learning_figures import (
    age_bins,
    label_colours,
    lifetime_table,
    load_learning,
    meta_table,
    write_learning_report,
)


def record(generations: int, alpha: float, batteries_late: float, closed: int) -> pd.DataFrame:
    """A learning.csv of ``generations`` rows: two age bins, α constant at ``alpha`` (std 0.1),
    one capture per bin early and ``batteries_late`` from generation 10 on."""
    rows = []
    for g in range(generations):
        row: dict[str, object] = {"generation": g, "lives": 4, "closed": g < closed}
        for low in (0, 100):
            row[f"batteries_age_{low}_{low + 100}"] = 1.0 if g < 10 else batteries_late
            row[f"matings_age_{low}_{low + 100}"] = 0.5
        for name in ("alpha", "gamma", "lam", "epsilon"):
            row[f"{name}_mean"] = alpha if name == "alpha" else 0.5
            row[f"{name}_std"] = 0.1
        rows.append(row)
    return pd.DataFrame(rows)


def test_meta_table_by_hand() -> None:
    """Two runs with α 0.2 and 0.4: mean 0.3, std over runs 0.1, mean population std 0.1."""
    table = meta_table({"modes": [record(20, 0.2, 2.0, 20), record(20, 0.4, 2.0, 20)]})
    first = table.iloc[0]
    assert (first["runs"], first["generation"]) == (2, 0)
    assert first["alpha_mean"] == pytest.approx(0.3)
    assert first["alpha_between_runs"] == pytest.approx(0.1)
    assert first["alpha_within"] == pytest.approx(0.1)


def test_lifetime_table_early_and_late_by_hand() -> None:
    """Early (0-9): one capture per bin; late (the last 10 both runs reached, 10-19): 2 and 3
    captures, mean 2.5 and std 0.5 over the runs."""
    runs = [record(20, 0.2, 2.0, 20), record(25, 0.2, 3.0, 25)]
    table = lifetime_table({"modes": runs})
    assert age_bins(runs[0]) == [(0, 100), (100, 200)]
    early = table[(table["phase"] == "early") & (table["age_from"] == 0)].iloc[0]
    late = table[(table["phase"] == "late") & (table["age_from"] == 100)].iloc[0]
    assert early["batteries_mean"] == 1.0 and early["generations"] == "0-9"
    assert late["generations"] == "10-19"
    assert late["batteries_mean"] == pytest.approx(2.5)
    assert late["batteries_std"] == pytest.approx(0.5)
    assert late["matings_mean"] == pytest.approx(0.5)


def test_lifetime_phases_never_overlap_in_short_runs() -> None:
    """A run that closed 5 generations has an early phase 0-4 and no late one; one of 13 has a
    late phase of 10-12 only, never repeating early generations."""
    short = lifetime_table({"short": [record(5, 0.2, 2.0, 5)]})
    assert set(short["phase"]) == {"early"} and set(short["generations"]) == {"0-4"}
    medium = lifetime_table({"medium": [record(13, 0.2, 2.0, 13)]})
    late = medium[medium["phase"] == "late"]
    assert set(late["generations"]) == {"10-12"}
    assert late["batteries_mean"].tolist() == [2.0, 2.0]


def test_load_keeps_closed_generations_and_report_writes_figures(tmp_path: Path) -> None:
    for seed, closed in ((0, 12), (1, 0)):
        run = tmp_path / f"ee-seed{seed:03d}"
        run.mkdir()
        record(15, 0.2, 2.0, closed).to_csv(run / "learning.csv", index=False)
    tables = load_learning(tmp_path)
    assert [len(t) for t in tables] == [12, 15]  # a run that closed none keeps every row
    written = write_learning_report({"modes": tables}, tmp_path / "figures")
    names = sorted(path.name for path in written)
    assert names == sorted(
        f"learning_{kind}.{ext}" for kind in ("meta", "lifetime") for ext in ("csv", "png", "pdf")
    )
    assert write_learning_report({"none": []}, tmp_path / "empty") == []


def test_closed_generations_from_the_statistics_when_the_record_has_no_column(
    tmp_path: Path,
) -> None:
    run = tmp_path / "ee-seed000"
    run.mkdir()
    record(15, 0.2, 2.0, 0).drop(columns="closed").to_csv(run / "learning.csv", index=False)
    pd.DataFrame({"generation": range(6)}).to_csv(run / "statistics.csv", index=False)
    assert [len(t) for t in load_learning(tmp_path)] == [6]


def test_given_colours_are_kept_and_the_rest_take_unused_palette_colours() -> None:
    colours = label_colours(["a", "b", "c"], {"b": "#1f4fd1", "unused": "#555555"})
    # "#1f4fd1" (the palette's first) belongs to b, so a and c take the next two unused ones.
    assert colours == {"a": "#d1261f", "b": "#1f4fd1", "c": "#2a9d3a"}
    assert label_colours(["x", "y"]) == {"x": "#1f4fd1", "y": "#d1261f"}
