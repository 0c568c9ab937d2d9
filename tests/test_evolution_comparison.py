"""EE against CE: window means, the rank test, effect sizes, convergence and rise, by hand."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import linregress, mannwhitneyu

from evolution.lab.comparison import (
    EXACT_MAX_RUNS,
    available_window,
    compare_methods,
    completions,
    completions_by_method,
    convergence_generation,
    early_rise,
    run_means,
    summary_table,
    write_report,
)


def run(**columns: object) -> pd.DataFrame:
    """A statistics table: lists are per generation, scalars the same in every generation."""
    lengths = {len(v) for v in columns.values() if isinstance(v, list | np.ndarray)}
    (n,) = lengths
    values = {k: (v if isinstance(v, list | np.ndarray) else [v] * n) for k, v in columns.items()}
    return pd.DataFrame({"generation": np.arange(n), **values})


def curve(values: list[float], column: str = "batteries_mean") -> pd.DataFrame:
    return pd.DataFrame({"generation": np.arange(len(values)), column: values})


def cliffs_delta(x: np.ndarray, y: np.ndarray) -> float:
    """P(x > y) - P(x < y) over all pairs, by brute force."""
    pairs = list(itertools.product(x, y))
    return float(sum(a > b for a, b in pairs) - sum(a < b for a, b in pairs)) / len(pairs)


def test_run_means_window_and_nan() -> None:
    a = curve([100.0, np.nan, 3.0, 5.0, 7.0])  # generation 1 has no completed agent: skipped
    b = curve([1.0, 8.0])  # reaches generation 1 only
    c = curve([1.0, np.nan, np.nan, np.nan])  # no value in the window
    means = run_means([a, b, c], "batteries_mean", first=1, last=3)
    assert means[0] == 4.0  # (3 + 5) / 2
    assert means[1] == 8.0
    assert math.isnan(means[2])
    with pytest.raises(ValueError, match="lacks"):
        run_means([a], "matings_mean")
    with pytest.raises(ValueError, match="window"):
        run_means([a], "batteries_mean", first=3, last=1)


def late_runs(values: list[float], wild: float = 1000.0) -> list[pd.DataFrame]:
    """One run per value: ``value`` over generations 100-119, ``wild`` before (outside)."""
    return [curve([wild] * 100 + [v] * 20) for v in values]


def test_compare_methods_exact_hand_computed() -> None:
    ee, ce = late_runs([3.0, 5.0, 7.0]), late_runs([1.0, 2.0, 4.0], wild=-1000.0)
    result = compare_methods(ee, ce, "batteries_mean", (100, 119))
    assert (result.ee_runs, result.ce_runs) == (3, 3)
    assert result.ee_mean == 5.0 and result.ee_std == 2.0  # variance (4 + 0 + 4) / 2
    assert result.ce_mean == pytest.approx(7 / 3)
    assert result.ce_std == pytest.approx(math.sqrt(21) / 3)  # variance (16 + 1 + 25) / 9 / 2
    assert result.difference == pytest.approx(8 / 3) and result.higher == "ee"
    # EE wins 8 of the 9 pairs (only 3 < 4 loses).
    assert result.u_statistic == 8.0
    # Exact null: the 20 equally likely rank sets of EE; U >= 8 only for {4,5,6} and {3,5,6}:
    # one-sided 2/20, two-sided 0.2.
    assert result.test == "exact" and result.p_value == pytest.approx(0.2)
    assert result.common_language == pytest.approx(8 / 9)
    assert result.rank_biserial == pytest.approx(7 / 9)  # 2 U / 9 - 1
    brute = cliffs_delta(np.array([3, 5, 7]), np.array([1, 2, 4]))
    assert result.rank_biserial == pytest.approx(brute)
    assert result.window == (100, 119) and result.column == "batteries_mean"


def test_compare_methods_ties_use_the_asymptotic_test() -> None:
    ee_values, ce_values = [1.0, 2.0, 2.0, 3.0], [2.0, 2.0, 4.0]
    result = compare_methods(late_runs(ee_values), late_runs(ce_values), "batteries_mean")
    # Pairs: 1 loses 3; each 2 ties two (1/2 each) and loses one; 3 wins two -> U = 0 + 2 + 2.
    assert result.u_statistic == 4.0
    assert result.rank_biserial == pytest.approx(-1 / 3)  # 2 * 4 / 12 - 1
    assert result.rank_biserial == pytest.approx(
        cliffs_delta(np.array(ee_values), np.array(ce_values))
    )
    assert result.test == "asymptotic"
    expected = mannwhitneyu(ee_values, ce_values, alternative="two-sided", method="asymptotic")
    assert result.p_value == pytest.approx(expected.pvalue)
    assert result.higher == "ce"  # 2 < 8/3


def test_compare_methods_scipy_cross_check() -> None:
    rng = np.random.default_rng(3)
    ee_values, ce_values = rng.normal(22, 2, 20), rng.normal(25, 2, 20)
    ee, ce = late_runs(list(ee_values)), late_runs(list(ce_values))
    result = compare_methods(ee, ce, "batteries_mean")
    expected = mannwhitneyu(ee_values, ce_values, alternative="two-sided", method="exact")
    assert result.test == "exact"
    assert result.u_statistic == expected.statistic
    assert result.p_value == pytest.approx(expected.pvalue)
    assert result.rank_biserial == pytest.approx(cliffs_delta(ee_values, ce_values))
    assert result.ee_std == pytest.approx(np.std(ee_values, ddof=1))
    many = EXACT_MAX_RUNS + 1  # beyond it the normal approximation, even without ties
    big = compare_methods(
        late_runs(list(rng.normal(0, 1, many))), late_runs(list(rng.normal(0, 1, many))),
        "batteries_mean",
    )
    assert big.test == "asymptotic" and big.ee_runs == many


def test_compare_methods_missing_method_and_nan_runs() -> None:
    ee = late_runs([3.0]) + [curve([1.0] * 100)]  # the second ends before the window
    result = compare_methods(ee, [], "batteries_mean")
    assert result.ee_runs == 1 and result.ee_mean == 3.0 and math.isnan(result.ee_std)
    assert result.ce_runs == 0 and math.isnan(result.ce_mean)
    assert result.test == "none" and math.isnan(result.p_value)
    assert math.isnan(result.rank_biserial) and result.higher == ""


def test_available_window() -> None:
    assert available_window([curve([0.0] * 120)], (100, 119)) == (100, 119)
    assert available_window([curve([0.0] * 2)], (100, 119)) == (0, 1)  # min(20, 2) generations
    assert available_window([curve([0.0] * 31)], (100, 119)) == (11, 30)  # the last 20
    # The shortest run decides; empty tables do not count.
    tables = [curve([0.0] * 150), curve([0.0] * 40), curve([])]
    assert available_window(tables, (100, 119)) == (20, 39)
    assert available_window([curve([])], (100, 119)) is None


def test_convergence_generation_hand_computed() -> None:
    a = curve([0.0, 10.0, 19.0, 20.0, 21.0, 20.0])
    b = curve([0.0, 10.0, 21.0, 20.0, 19.0, 20.0])
    # Mean over runs 0, 10, 20, 20, 20, 20; final level (last 2) 20; within 5 %: [19, 21].
    assert convergence_generation([a, b], smoothing=1, final=2) == 2
    # Trailing 3: 0, 5, 10, 16.7, 20, 20 -> from generation 4.
    assert convergence_generation([a, b], smoothing=3, final=2, centred=False) == 4
    # Centred 3 (edges over what exists): 5, 10, 16.7, 20, 20, 20 -> from generation 3.
    assert convergence_generation([a, b], smoothing=3, final=2) == 3
    # Leaving the band later restarts the count; ending outside it never converges.
    dip = curve([20.0, 20.0, 10.0, 20.0, 20.0])
    assert convergence_generation([dip], smoothing=1, final=2) == 3
    assert convergence_generation([curve([0.0, 10.0, 30.0])], smoothing=1, final=2) is None
    # A generation with no value anywhere counts as outside.
    assert convergence_generation([curve([20.0, np.nan, 20.0, 20.0])], smoothing=1, final=2) == 2
    assert convergence_generation([curve([20.0] * 5)], final=20) is None  # too short to tell


def test_convergence_generation_defaults_on_a_step() -> None:
    # 0 until generation 29, then 25: a 10-generation window is within 5 % of 25 only if it
    # holds no 0. Centred (g-5..g+4): from 35; trailing (g-9..g): from 39.
    step = curve([0.0] * 30 + [25.0] * 90)
    assert convergence_generation([step, step]) == 35
    assert convergence_generation([step], centred=False) == 39
    # Runs of different lengths: only the generations every run reached count.
    assert convergence_generation([step, curve([0.0] * 30 + [25.0] * 20)]) == 35


def test_early_rise_hand_computed() -> None:
    a = curve([1.0, 2.0, 3.0, 4.0, 5.0, 99.0])  # generation 5 is outside the window
    b = curve([0.0, 0.0, 0.0, 0.0, 4.0])
    rise = early_rise([a, b], first=0, last=4, block=2)
    # Slopes: a 1; b sum((x-2)(y-0.8)) / sum((x-2)^2) = 8 / 10.
    assert rise.slopes == pytest.approx((1.0, 0.8))
    assert rise.slopes[1] == pytest.approx(linregress(np.arange(5), [0, 0, 0, 0, 4]).slope)
    # Differences (generations 3-4 minus 0-1): a 4.5 - 1.5, b 2 - 0.
    assert rise.differences == pytest.approx((3.0, 2.0))
    assert rise.runs == 2
    assert rise.slope_mean == pytest.approx(0.9)
    assert rise.slope_std == pytest.approx(0.2 / math.sqrt(2))
    assert rise.difference_mean == pytest.approx(2.5)
    assert rise.difference_std == pytest.approx(1 / math.sqrt(2))
    # NaN generations are skipped; one generation gives no slope.
    gappy = early_rise([curve([1.0, np.nan, 3.0]), curve([5.0])], first=0, last=2, block=1)
    assert gappy.slopes[0] == pytest.approx(1.0) and math.isnan(gappy.slopes[1])
    # Run b has no generation 2: its end block is empty, so no difference either.
    assert gappy.differences[0] == 2.0 and math.isnan(gappy.differences[1])
    assert gappy.runs == 1 and math.isnan(gappy.slope_std)


def test_completions_hand_computed() -> None:
    a = run(completed=[2, 4], full_lifetimes=[4, 4])
    b = run(completed=[4], full_lifetimes=[8])
    c = completions([a, b]).set_index("generation")
    assert c.loc[0, "runs"] == 2 and c.loc[1, "runs"] == 1
    assert c.loc[0, "completed_mean"] == 3.0
    assert c.loc[0, "completed_std"] == pytest.approx(math.sqrt(2))  # ddof = 1 over (2, 4)
    assert c.loc[0, "full_lifetimes_mean"] == 6.0
    assert c.loc[0, "full_lifetimes_std"] == pytest.approx(math.sqrt(8))
    assert c.loc[0, "completed_share_mean"] == 0.5 and c.loc[0, "completed_share_std"] == 0.0
    assert c.loc[1, "completed_mean"] == 4.0 and math.isnan(c.loc[1, "completed_std"])
    assert c.loc[1, "completed_share_mean"] == 1.0
    none_lived = completions([run(completed=[0], full_lifetimes=[0])])
    assert math.isnan(none_lived["completed_share_mean"].iloc[0])  # no full lifetime: no share
    assert completions([]).empty
    stacked = completions_by_method({"ee": [a], "ce": [b]})
    assert stacked.columns[0] == "method" and stacked["method"].tolist() == ["ee", "ee", "ce"]


def sweep_run(batteries: np.ndarray, matings: float, completed: int) -> pd.DataFrame:
    return run(batteries_mean=list(batteries), matings_mean=matings, completed=completed,
               full_lifetimes=2 * completed)  # fmt: skip


def test_summary_table_hand_computed() -> None:
    g = np.arange(120)
    # EE rises linearly to c at generation 20, then stays; CE is 0 until 29, then c.
    ee = [sweep_run(c * np.minimum(g, 20) / 20, m, 10) for c, m in ((3, 3), (5, 4), (7, 5))]
    ce = [sweep_run(np.where(g < 30, 0.0, c), m, 20) for c, m in ((1, 1), (2, 2), (4, 3))]
    table = summary_table({"ee": ee, "ce": ce}).set_index("quantity")
    batteries = table.loc["batteries"]
    assert batteries["generations"] == "100-119"
    assert (batteries["ee_runs"], batteries["ce_runs"]) == (3, 3)
    assert (batteries["ee_mean"], batteries["ee_std"]) == (5.0, 2.0)
    assert batteries["u_statistic"] == 8.0 and batteries["p_value"] == pytest.approx(0.2)
    assert batteries["test"] == "exact" and batteries["higher"] == "ee"
    assert batteries["rank_biserial"] == pytest.approx(7 / 9)
    matings = table.loc["matings"]  # EE 3, 4, 5 against CE 1, 2, 3: one tie
    assert matings["test"] == "asymptotic" and matings["u_statistic"] == 8.5
    expected = mannwhitneyu([3, 4, 5], [1, 2, 3], alternative="two-sided", method="asymptotic")
    assert matings["p_value"] == pytest.approx(expected.pvalue)
    completed = table.loc["completed"]
    assert (completed["ee_mean"], completed["ce_mean"], completed["higher"]) == (10, 20, "ce")
    assert completed["rank_biserial"] == -1.0 and completed["ee_std"] == 0.0
    converged = table.loc["convergence_generation"]
    assert converged["generations"] == "0-119" and converged["ce_mean"] == 35.0
    assert converged["ee_mean"] == convergence_generation(ee)
    slope, difference = table.loc["rise_slope"], table.loc["rise_difference"]
    assert slope["generations"] == "0-20" and difference["generations"] == "0-20"
    # EE slopes c / 20 = 0.15, 0.25, 0.35; differences c (18 - 2) / 20 = 2.4, 4, 5.6.
    assert slope["ee_mean"] == pytest.approx(0.25) and slope["ee_std"] == pytest.approx(0.1)
    assert difference["ee_mean"] == pytest.approx(4.0)
    assert difference["ee_std"] == pytest.approx(1.6)
    assert slope["ce_mean"] == 0.0 and difference["ce_mean"] == 0.0  # CE flat over 0-20
    assert set(table["rule"].str.len()) != {0}


def short_sweep() -> dict[str, list[pd.DataFrame]]:
    """Two generations, as the CLI tests run; CE has no agent complete the task."""
    ee = [run(batteries_mean=[1.0, 2.0], matings_mean=[1.0, 1.0], completed=[1, 2],
              full_lifetimes=[4, 4]) for _ in range(2)]  # fmt: skip
    ce = [run(batteries_mean=[np.nan, np.nan], matings_mean=[np.nan, np.nan], completed=0,
              full_lifetimes=4)]  # fmt: skip
    return {"ee": ee, "ce": ce}


def test_summary_table_short_and_one_method_sweeps() -> None:
    runs = short_sweep()
    table = summary_table(runs).set_index("quantity")
    assert set(table["generations"]) == {"0-1"}  # the last min(20, 2) generations
    assert table.loc["batteries", "ee_mean"] == 1.5 and table.loc["batteries", "ce_runs"] == 0
    assert table.loc["batteries", "test"] == "none"
    assert table.loc["completed", "ce_runs"] == 1  # CE completed 0 agents: a value, not NaN
    assert math.isnan(table.loc["convergence_generation", "ee_mean"])  # too few generations
    assert table.loc["rise_slope", "ee_mean"] == 1.0
    only_ee = summary_table({"ee": runs["ee"]}).set_index("quantity")
    assert only_ee.loc["batteries", "ce_runs"] == 0 and only_ee.loc["batteries", "higher"] == ""
    assert only_ee.loc["rise_slope", "ee_runs"] == 2
    with pytest.raises(ValueError, match="at least one run"):
        summary_table({"ee": [], "ce": [curve([])]})


def test_write_report(tmp_path: Path) -> None:
    runs = short_sweep()
    paths = write_report(runs, tmp_path / "figures")
    assert [p.name for p in paths] == ["comparison.csv", "completions.csv"]
    comparison = pd.read_csv(paths[0])
    assert comparison["quantity"].tolist() == [
        "batteries", "matings", "completed", "convergence_generation", "rise_slope",
        "rise_difference",
    ]  # fmt: skip
    expected = summary_table(runs)
    assert comparison["ee_mean"].tolist() == pytest.approx(expected["ee_mean"].tolist(),
                                                           nan_ok=True)  # fmt: skip
    completions_csv = pd.read_csv(paths[1])
    assert completions_csv["method"].tolist() == ["ee", "ee", "ce", "ce"]
    assert not list((tmp_path / "figures").glob(".*"))  # no temporaries left behind
    assert write_report({"ee": [curve([])]}, tmp_path / "empty") == []
