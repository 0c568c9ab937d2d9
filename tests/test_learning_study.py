"""The learning study's summaries, on hand-made tables: inheritance and meta-parameter settling."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from benchmarks.learning_study import (
    generations_to_reach,
    inheritance_table,
    meta_convergence,
    table_drift,
)


def statistics(batteries: list[float], matings: float = 3.0) -> pd.DataFrame:
    """A statistics table with the given batteries per generation."""
    n = len(batteries)
    return pd.DataFrame({"generation": range(n), "batteries_mean": batteries,
                         "matings_mean": [matings] * n})  # fmt: skip


def test_generations_to_reach_uses_the_trailing_mean() -> None:
    table = statistics([float(g + 1) for g in range(10)])  # 1, 2, ..., 10
    # trailing 3-generation mean at generation g >= 2 is g: it first reaches 4 at generation 4
    assert generations_to_reach(table, 4.0, smoothing=3) == 4.0
    assert generations_to_reach(table, 9.0, smoothing=3) == 9.0
    # never reached: the run's generation count, which ranks it slowest
    assert generations_to_reach(table, 9.5, smoothing=3) == 10.0
    assert math.isnan(generations_to_reach(statistics([]), 1.0))


def test_inheritance_table_compares_lamarckian_with_darwinian() -> None:
    fixed = [statistics([20.0] * 60), statistics([20.0] * 60)]  # threshold 0.9 * 20 = 18
    ramp = [min(20.0, 10.0 + g) for g in range(60)]  # 10, 11, ... 20 from generation 10 on
    late = [min(20.0, 5.0 + g / 2) for g in range(60)]  # 5, 5.5, ... reaches 20 at generation 30
    groups = {
        "shipped, Darwinian": [statistics(late, 3.0), statistics(late, 3.0)],
        "shipped, Lamarckian": [statistics(ramp, 4.0), statistics(ramp, 4.0)],
        "zero, Darwinian": [statistics([])],  # closed no generation: no row
    }
    table = inheritance_table(groups, fixed).set_index("measure")
    assert list(table["init"].unique()) == ["shipped"]
    early = table.loc["batteries 10-19"]
    # Darwinian over 10-19: 5 + g/2 -> mean of 10..14.5 = 12.25; Lamarckian: min(20, 10 + g) -> 20
    assert early["darwinian_mean"] == pytest.approx(12.25)
    assert early["lamarckian_mean"] == 20.0
    assert early["rank_biserial"] == 1.0
    assert table.loc["matings 10-19", "lamarckian_mean"] == 4.0
    reach = table.loc["generations to 90% of fixed (18.00 batteries)"]
    # 5-generation trailing mean reaches 18: Lamarckian mean of 10+(g-4..g) = 8 + g >= 18 at 10;
    # Darwinian 5 + (g - 2)/2 = 4 + g/2 >= 18 at generation 28
    assert reach["lamarckian_mean"] == 10.0 and reach["darwinian_mean"] == 28.0
    assert reach["rank_biserial"] == -1.0  # Lamarckian needs fewer generations in every pair


def meta(label: str, alpha: list[float], between: float = 0.02) -> pd.DataFrame:
    n = len(alpha)
    frame = pd.DataFrame({"label": [label] * n, "generation": range(n), "runs": [5] * n})
    for name in ("alpha", "gamma", "lam", "epsilon"):
        frame[f"{name}_mean"] = alpha if name == "alpha" else [0.5] * n
        frame[f"{name}_between_runs"] = [between] * n
        frame[f"{name}_within"] = [0.1] * n
    return frame


def test_meta_convergence_settled_rule() -> None:
    settling = [0.3 - 0.005 * min(g, 40) for g in range(60)]  # 0.3 down to 0.1, flat from 40
    drifting = list(np.linspace(0.3, 0.0, 60))  # keeps falling: 0.05 between 40-49 and 50-59
    table = meta_convergence(pd.concat([meta("a", settling), meta("b", drifting)]))
    alpha = table[table["parameter"] == "alpha"].set_index("label")
    assert alpha.loc["a", "mean_0_9"] == pytest.approx(0.3 - 0.005 * 4.5)
    assert alpha.loc["a", "mean_50_59"] == pytest.approx(0.1)
    assert alpha.loc["a", "settled"] and not alpha.loc["b", "settled"]
    assert table[table["parameter"] == "gamma"]["settled"].all()  # constant parameters
    short = meta_convergence(meta("c", [0.2] * 30))  # no generations 40-59: undecided
    assert short["settled"].isna().all()


def test_table_drift_by_hand() -> None:
    initial = np.array([[1.0, 0.0], [0.0, 2.0], [0.5, 0.5]])  # 3 rows; greedy 0, 1, 0
    # two tables of 3 rows: flat rows 1 (table 0, row 1) and 3 (table 1, row 0) changed
    rows = np.array([1, 3])
    values = np.array([[0.0, 1.0], [1.0, 3.0]])  # row 1 keeps greedy 1; row 0 flips 0 -> 1
    drift = table_drift(rows, values, initial, n_tables=2)
    assert drift["changed_rows_per_table"] == 1.0
    assert drift["greedy_changed"] == 0.5
    # |changes|: row 1: 0, 1; row 0: 0, 3 -> mean 4 / 4 = 1
    assert drift["mean_abs_change"] == 1.0
    # a tied initial row (row 2) has no greedy action to change: only rows 0 and 1 count
    tied = table_drift(np.array([2, 4]), np.array([[0.0, 1.0], [0.0, 1.0]]), initial, 2)
    assert tied["greedy_changed"] == 0.0  # row 4 is row 1: greedy 1 before and after
    only_tied = table_drift(np.array([2]), np.array([[0.0, 1.0]]), initial, 1)
    assert math.isnan(only_tied["greedy_changed"])
    assert table_drift(np.array([], dtype=int), np.zeros((0, 2)), initial, 2) == {
        "changed_rows_per_table": 0.0, "greedy_changed": 0.0, "mean_abs_change": 0.0}
