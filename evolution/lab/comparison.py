"""EE against CE in numbers a reviewer accepts: per-run window means, a rank test, effect sizes.

The paper compares the methods on curves (Fig. 6); a claim such as "CE captures more batteries,
EE mates more" needs a test over independent runs. The unit of analysis is therefore the *run*
(one seed): each run contributes one number per quantity (its mean over a window of
generations), and the methods are compared on those numbers, never on pooled generations or
agents, which are not independent.

Conventions, the same in every function here:

- A run's statistics table is one ``statistics.csv`` (:class:`evolution.stats.GenerationStats`
  columns). Generations with NaN (no agent completed the survival task) are skipped; a run with
  no value in a window contributes NaN, and NaN runs are left out of the means, standard
  deviations, counts and tests.
- Standard deviations over runs are sample standard deviations (``ddof=1``; NaN for fewer than
  two runs): the runs are a sample of seeds, not the population.
- Windows are inclusive generation ranges ``(first, last)``. A sweep too short for a requested
  window uses its last generations instead (:func:`available_window`), and the tables say which
  window was used.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output
from evolution.config import METHODS

#: An inclusive range of generations ``(first, last)``.
Window = tuple[int, int]
#: The paper's late window: generations 100-119 of 120.
LATE_WINDOW: Window = (100, 119)
#: The paper's early window, over which EE's curves rise.
EARLY_WINDOW: Window = (0, 20)
#: The exact Mann-Whitney distribution is used up to this many runs per method (its cost grows
#: steeply beyond); larger samples use the normal approximation.
EXACT_MAX_RUNS = 50
#: Quantities compared over the late window: (row name, statistics column).
COMPARED = (
    ("batteries", "batteries_mean"),
    ("matings", "matings_mean"),
    ("completed", "completed"),
)
#: The convergence rule's defaults (:func:`convergence_generation`): a moving average of this
#: many generations, within this relative tolerance of the mean over this many final ones.
CONVERGENCE_SMOOTHING = 10
CONVERGENCE_TOLERANCE = 0.05
CONVERGENCE_FINAL = 20
#: Generations in each end block of :func:`early_rise`'s difference, by default.
RISE_BLOCK = 5


@dataclass(frozen=True)
class MethodComparison:
    """EE against CE on one quantity: per-run window means, their rank test and effect size.

    Attributes:
        column: the statistics column compared (e.g. ``batteries_mean``).
        window: the generations each run's mean covers (inclusive).
        ee_runs: EE runs with a value in the window.
        ce_runs: CE runs with a value in the window.
        ee_mean: mean over EE runs of the per-run means.
        ee_std: their sample standard deviation (``ddof=1``).
        ce_mean: mean over CE runs of the per-run means.
        ce_std: their sample standard deviation (``ddof=1``).
        difference: ``ee_mean - ce_mean``.
        u_statistic: Mann-Whitney U of EE: the (EE run, CE run) pairs in which EE is higher,
            ties counting one half.
        p_value: two-sided Mann-Whitney p-value (NaN without runs of both methods).
        test: ``"exact"`` (no ties, at most :data:`EXACT_MAX_RUNS` runs per method),
            ``"asymptotic"`` (normal approximation with tie and continuity corrections) or
            ``"none"``.
        common_language: ``U / (n_ee n_ce)``: the probability that a random EE run is higher
            than a random CE run, ties counting one half.
        rank_biserial: ``r = 2U / (n_ee n_ce) - 1`` in [-1, 1]; equal to Cliff's delta
            ``P(EE > CE) - P(EE < CE)`` over all pairs of runs; positive when EE is higher.
    """

    column: str
    window: Window
    ee_runs: int
    ce_runs: int
    ee_mean: float
    ee_std: float
    ce_mean: float
    ce_std: float
    difference: float
    u_statistic: float
    p_value: float
    test: str
    common_language: float
    rank_biserial: float

    @property
    def higher(self) -> str:
        """The method with the higher mean over runs: ``"ee"``, ``"ce"``, ``"equal"`` or ``""``
        when either method has no run with a value."""
        if math.isnan(self.difference):
            return ""
        return "ee" if self.difference > 0 else "ce" if self.difference < 0 else "equal"


@dataclass(frozen=True)
class RiseSummary:
    """How much a quantity rises over early generations, per run and over runs.

    Attributes:
        column: the statistics column.
        window: the generations examined (inclusive).
        block: generations in each end block of the difference.
        slopes: each run's least-squares slope per generation over the window (NaN with fewer
            than two generations with a value).
        differences: each run's mean over the last ``block`` generations of the window minus
            its mean over the first ``block`` (NaN where either block has no value).
        runs: runs with a finite slope.
        slope_mean: mean slope over runs (NaN runs skipped).
        slope_std: its sample standard deviation (``ddof=1``).
        difference_mean: mean difference over runs (NaN runs skipped).
        difference_std: its sample standard deviation (``ddof=1``).
    """

    column: str
    window: Window
    block: int
    slopes: tuple[float, ...]
    differences: tuple[float, ...]
    runs: int
    slope_mean: float
    slope_std: float
    difference_mean: float
    difference_std: float


def _check_columns(tables: Sequence[pd.DataFrame], *columns: str) -> None:
    for t in tables:
        missing = {"generation", *columns} - set(t.columns)
        if missing:
            raise ValueError(f"statistics table lacks column(s) {sorted(missing)}")


def _check_window(window: Window) -> Window:
    first, last = (int(g) for g in window)
    if first < 0 or last < first:
        raise ValueError(f"window must be generations (first, last) with 0 <= first <= last, "
                         f"got {window!r}")  # fmt: skip
    return first, last


def _finite(values: Sequence[float] | np.ndarray) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    finite: np.ndarray = array[~np.isnan(array)]
    return finite


def _mean_std(values: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """Mean and sample std (``ddof=1``) of the finite values; NaN where there are too few."""
    finite = _finite(values)
    mean = float(finite.mean()) if len(finite) else math.nan
    std = float(finite.std(ddof=1)) if len(finite) > 1 else math.nan
    return mean, std


def _window_mean(table: pd.DataFrame, column: str, first: int, last: int) -> float:
    rows = table["generation"].between(first, last)
    values = _finite(table.loc[rows, column].to_numpy(dtype=float))
    return float(values.mean()) if len(values) else math.nan


def _span(window: Window) -> str:
    first, last = window
    return f"{first}" if first == last else f"{first}-{last}"


def run_means(
    tables: Sequence[pd.DataFrame], column: str, first: int = 100, last: int = 119
) -> np.ndarray:
    """Each run's mean of ``column`` over generations ``first..last`` (inclusive).

    One number per run is what makes runs, not generations, the independent samples. Generations
    with NaN are skipped; a run with no value in the window (too short, or no agent completed
    the task there) gives NaN, which the callers leave out.

    Args:
        tables: one statistics table per run.
        column: e.g. ``batteries_mean``.
        first: first generation of the window.
        last: last generation of the window.

    Returns:
        One float per table, in order.
    """
    first, last = _check_window((first, last))
    _check_columns(tables, column)
    return np.array([_window_mean(t, column, first, last) for t in tables], dtype=float)


def last_common_generation(tables: Sequence[pd.DataFrame]) -> int | None:
    """The last generation every non-empty run reached (None if every table is empty)."""
    ends = [int(t["generation"].max()) for t in tables if len(t)]
    return min(ends) if ends else None


def available_window(tables: Sequence[pd.DataFrame], window: Window = LATE_WINDOW) -> Window | None:
    """The window to use for ``tables``: ``window`` itself if every run reached its last
    generation, otherwise the last ``min(width, n)`` generations every run reached, where
    ``width`` is the window's length and ``n`` the generations available.

    Short sweeps (tests run two generations, pilots a few dozen) still get a comparison, over
    their final generations, and never a window with runs missing from its end. None if no run
    closed a generation.
    """
    first, last = _check_window(window)
    end = last_common_generation(tables)
    if end is None:
        return None
    if end >= last:
        return first, last
    width = min(last - first + 1, end + 1)
    return end - width + 1, end


def rank_test(first: np.ndarray, second: np.ndarray) -> tuple[float, float, float, str]:
    """Two-sided Mann-Whitney U of ``first`` against ``second`` (finite values, one per run).

    The exact null distribution when there are no ties and at most :data:`EXACT_MAX_RUNS`
    values per sample, otherwise the normal approximation with tie and continuity corrections.

    Returns:
        ``(U of first, p-value, rank-biserial effect, test)``: the effect is ``2 U / (n1 n2) - 1``
        (+1 when every value of ``first`` is higher); test ``"exact"``, ``"asymptotic"``, or
        ``"none"`` (with NaNs) when either sample is empty.
    """
    if not len(first) or not len(second):
        return math.nan, math.nan, math.nan, "none"
    from scipy.stats import mannwhitneyu  # scipy is slow to import; only this needs it

    pooled = np.concatenate([first, second])
    ties = len(np.unique(pooled)) < len(pooled)
    test = "exact" if not ties and max(len(first), len(second)) <= EXACT_MAX_RUNS else "asymptotic"
    result = mannwhitneyu(first, second, alternative="two-sided", method=test)
    u = float(result.statistic)
    return u, float(result.pvalue), 2.0 * u / (len(first) * len(second)) - 1.0, test


def compare_methods(
    ee_tables: Sequence[pd.DataFrame],
    ce_tables: Sequence[pd.DataFrame],
    column: str,
    window: Window = LATE_WINDOW,
) -> MethodComparison:
    """EE against CE on ``column``: per-run window means, two-sided Mann-Whitney U test, effect.

    Mann-Whitney because a handful of seeds per method gives no ground for normality, and the
    rank-biserial correlation because it says how often EE beats CE, whatever the scale. The
    exact null distribution is used when there are no ties and at most :data:`EXACT_MAX_RUNS`
    runs per method (``scipy.stats.mannwhitneyu(method="exact")``); otherwise the normal
    approximation with tie and continuity corrections (``method="asymptotic"``).

    Args:
        ee_tables: EE runs' statistics tables.
        ce_tables: CE runs' statistics tables.
        column: the compared column, e.g. ``batteries_mean``.
        window: inclusive generations each run's mean covers (used as given).

    Returns:
        The comparison; runs without a value in the window are left out of it.
    """
    window = _check_window(window)
    ee = _finite(run_means(ee_tables, column, *window))
    ce = _finite(run_means(ce_tables, column, *window))
    ee_mean, ee_std = _mean_std(ee)
    ce_mean, ce_std = _mean_std(ce)
    u, p, biserial, test = rank_test(ee, ce)
    common = (biserial + 1.0) / 2.0
    return MethodComparison(
        column=column,
        window=window,
        ee_runs=len(ee),
        ce_runs=len(ce),
        ee_mean=ee_mean,
        ee_std=ee_std,
        ce_mean=ce_mean,
        ce_std=ce_std,
        difference=ee_mean - ce_mean,
        u_statistic=u,
        p_value=p,
        test=test,
        common_language=common,
        rank_biserial=biserial,
    )


def _by_generation(tables: Sequence[pd.DataFrame], column: str) -> pd.DataFrame:
    """Generation × run matrix of ``column`` (NaN where a run lacks the generation)."""
    return pd.concat(
        [t.set_index("generation")[column].rename(k) for k, t in enumerate(tables)], axis=1
    ).sort_index()


def convergence_generation(
    tables: Sequence[pd.DataFrame],
    column: str = "batteries_mean",
    smoothing: int = CONVERGENCE_SMOOTHING,
    tolerance: float = CONVERGENCE_TOLERANCE,
    final: int = CONVERGENCE_FINAL,
    centred: bool = True,
) -> int | None:
    """The generation from which the mean curve over runs stays at its final level.

    The paper says CE "converged" early (by about generation 40); this makes that a rule:

    1. the curve is the mean over runs of ``column`` per generation, over the generations every
       run reached (NaN runs skipped);
    2. it is smoothed by a moving average of ``smoothing`` generations, centred (generations
       ``g - smoothing // 2 .. g + (smoothing - 1) // 2``) or trailing (``g - smoothing + 1 ..
       g``), over the generations available at the ends and skipping NaN;
    3. the final level ``F`` is the unsmoothed curve's mean over its last ``final`` generations;
    4. the convergence generation is the first ``g`` such that the smoothed curve is within
       ``tolerance · |F|`` of ``F`` at ``g`` and at every later generation (a NaN smoothed
       value counts as outside).

    Args:
        tables: one statistics table per run (e.g. the CE runs).
        column: the curve's column.
        smoothing: moving-average length in generations (1: no smoothing).
        tolerance: allowed relative distance from the final level.
        final: generations at the end that define the final level.
        centred: centred (True) or trailing (False) moving average.

    Returns:
        The generation, or None if the curve is shorter than ``final`` generations, has no
        final level, or ends outside the tolerance.
    """
    if smoothing < 1 or final < 1 or not tolerance >= 0:
        raise ValueError("smoothing and final must be >= 1 and tolerance >= 0")
    tables = [t for t in tables if len(t)]
    _check_columns(tables, column)
    end = last_common_generation(tables)
    if end is None:
        return None
    wide = _by_generation(tables, column).loc[:end]
    with warnings.catch_warnings():  # 'mean of empty slice' where no run has a value
        warnings.simplefilter("ignore", category=RuntimeWarning)
        curve = pd.Series(np.nanmean(wide.to_numpy(dtype=float), axis=1), index=wide.index)
    if len(curve) < final:
        return None
    tail = curve.to_numpy()[-final:]
    if np.isnan(tail).all():
        return None
    level = float(np.nanmean(tail))
    smoothed = curve.rolling(smoothing, center=centred, min_periods=1).mean()
    inside = (smoothed - level).abs() <= tolerance * abs(level)  # NaN compares False
    outside = np.flatnonzero(~inside.to_numpy())
    if len(outside) == 0:
        return int(curve.index[0])
    if outside[-1] == len(curve) - 1:
        return None
    return int(curve.index[outside[-1] + 1])


def _rise(
    table: pd.DataFrame, column: str, first: int, last: int, block: int
) -> tuple[float, float]:
    """One run's least-squares slope and end-block difference over ``first..last``."""
    rows = table[table["generation"].between(first, last)]
    x = rows["generation"].to_numpy(dtype=float)
    y = rows[column].to_numpy(dtype=float)
    keep = ~np.isnan(y)
    x, y = x[keep], y[keep]
    if len(np.unique(x)) >= 2:
        centred = x - x.mean()
        slope = float(np.sum(centred * (y - y.mean())) / np.sum(centred * centred))
    else:
        slope = math.nan
    late = _window_mean(table, column, max(first, last - block + 1), last)
    early = _window_mean(table, column, first, min(last, first + block - 1))
    return slope, late - early


def early_rise(
    tables: Sequence[pd.DataFrame],
    column: str = "batteries_mean",
    first: int = 0,
    last: int = 20,
    block: int = RISE_BLOCK,
) -> RiseSummary:
    """How much ``column`` rises over generations ``first..last``, per run and over runs.

    Two measures, because a slope alone hides a late jump and an end difference alone is noisy:
    the least-squares slope per generation, and the mean over generations ``last - block + 1 ..
    last`` minus the mean over ``first .. first + block - 1`` (both blocks clipped to the window).

    Args:
        tables: one statistics table per run (e.g. the EE runs).
        column: the statistics column.
        first: first generation of the window.
        last: last generation of the window.
        block: generations in each end block of the difference.
    """
    first, last = _check_window((first, last))
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block!r}")
    _check_columns(tables, column)
    per_run = [_rise(t, column, first, last, block) for t in tables]
    slopes = tuple(s for s, _ in per_run)
    differences = tuple(d for _, d in per_run)
    slope_mean, slope_std = _mean_std(slopes)
    difference_mean, difference_std = _mean_std(differences)
    return RiseSummary(
        column=column,
        window=(first, last),
        block=block,
        slopes=slopes,
        differences=differences,
        runs=int(np.sum(~np.isnan(np.asarray(slopes, dtype=float)))),
        slope_mean=slope_mean,
        slope_std=slope_std,
        difference_mean=difference_mean,
        difference_std=difference_std,
    )


def completions(tables: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """Per generation, how many agents completed the survival task, over runs.

    Fig. 6 averages over the agents that completed the task, so how many did (and of how many
    full lifetimes) says how much each point of it rests on.

    Args:
        tables: one statistics table per run (columns ``completed`` and ``full_lifetimes``).

    Returns:
        One row per generation any run reached: ``generation``, ``runs`` (runs that reached
        it), the mean and sample std (``ddof=1``) over runs of ``completed``, of
        ``full_lifetimes`` and of each run's ``completed / full_lifetimes`` (NaN for a run with
        no full lifetime): columns ``completed_mean``, ``completed_std``,
        ``full_lifetimes_mean``, ``full_lifetimes_std``, ``completed_share_mean``,
        ``completed_share_std``.
    """
    tables = [t for t in tables if len(t)]
    columns = ["generation", "runs", "completed_mean", "completed_std", "full_lifetimes_mean",
               "full_lifetimes_std", "completed_share_mean", "completed_share_std"]  # fmt: skip
    if not tables:
        return pd.DataFrame(columns=columns)
    _check_columns(tables, "completed", "full_lifetimes")
    completed = _by_generation(tables, "completed")
    full = _by_generation(tables, "full_lifetimes")
    share = completed / full.where(full > 0)  # no full lifetime: no share
    out: dict[str, object] = {
        "generation": completed.index.to_numpy(dtype=int),
        "runs": completed.notna().sum(axis=1).to_numpy(dtype=int),
    }
    for name, wide in (("completed", completed), ("full_lifetimes", full),
                       ("completed_share", share)):  # fmt: skip
        stats = [_mean_std(row) for row in wide.to_numpy(dtype=float)]
        out[f"{name}_mean"] = [m for m, _ in stats]
        out[f"{name}_std"] = [s for _, s in stats]
    return pd.DataFrame(out, columns=columns)


def _row(quantity: str, window: Window | None, rule: str) -> dict[str, object]:
    return {
        "quantity": quantity,
        "generations": _span(window) if window is not None else "",
        "ee_runs": 0,
        "ee_mean": math.nan,
        "ee_std": math.nan,
        "ce_runs": 0,
        "ce_mean": math.nan,
        "ce_std": math.nan,
        "difference": math.nan,
        "higher": "",
        "u_statistic": math.nan,
        "p_value": math.nan,
        "test": "",
        "rank_biserial": math.nan,
        "rule": rule,
    }


def summary_table(
    runs: Mapping[str, Sequence[pd.DataFrame]],
    window: Window = LATE_WINDOW,
    rise: Window = EARLY_WINDOW,
) -> pd.DataFrame:
    """EE against CE in one tidy table a README can print, one row per quantity.

    Rows: ``batteries``, ``matings`` and ``completed`` (per-run means over the late window,
    compared by :func:`compare_methods`), ``convergence_generation`` (per method, by
    :func:`convergence_generation` on ``batteries_mean`` with its defaults), and
    ``rise_slope`` and ``rise_difference`` (per method, :func:`early_rise` on
    ``batteries_mean``). Every row says in ``generations`` which generations it used: a sweep
    too short for ``window`` uses its last generations (:func:`available_window`), and the rise
    window is clipped to the generations every run reached.

    Args:
        runs: statistics tables by method, e.g. :func:`evolution.lab.sweep.load_sweep`'s result; a
            missing method leaves its columns empty (runs 0, NaN).
        window: the late window of the comparison.
        rise: the early window of the rise.

    Returns:
        Columns ``quantity``, ``generations``, ``ee_runs``, ``ee_mean``, ``ee_std``,
        ``ce_runs``, ``ce_mean``, ``ce_std`` (sample std over runs), ``difference``
        (EE - CE), ``higher``, ``u_statistic`` (EE's U), ``p_value`` (two-sided),
        ``test``, ``rank_biserial`` (Cliff's delta, positive when EE is higher) and ``rule``.
    """
    by_method = {m: [t for t in runs.get(m, ()) if len(t)] for m in METHODS}
    every = [t for tables in by_method.values() for t in tables]
    late = available_window(every, window)
    if late is None:
        raise ValueError("summary_table needs at least one run with a closed generation")
    end = last_common_generation(every)
    assert end is not None
    rise_first, rise_last = _check_window(rise)
    early: Window = (min(rise_first, end), min(rise_last, end))
    rows = []
    for quantity, column in COMPARED:
        result = compare_methods(by_method["ee"], by_method["ce"], column, late)
        row = _row(quantity, late, f"each run's mean of {column} over the window; "
                   "Mann-Whitney U over runs, two-sided")  # fmt: skip
        row.update(
            ee_runs=result.ee_runs, ee_mean=result.ee_mean, ee_std=result.ee_std,
            ce_runs=result.ce_runs, ce_mean=result.ce_mean, ce_std=result.ce_std,
            difference=result.difference, higher=result.higher,
            u_statistic=result.u_statistic, p_value=result.p_value, test=result.test,
            rank_biserial=result.rank_biserial,
        )  # fmt: skip
        rows.append(row)
    converged = _row(
        "convergence_generation",
        (0, end),
        f"first generation from which the {CONVERGENCE_SMOOTHING}-generation centred moving "
        f"average of batteries_mean (mean over runs) stays within {CONVERGENCE_TOLERANCE:.0%} "
        f"of its mean over the last {CONVERGENCE_FINAL} generations;"
        " NaN: not converged, or too few generations",
    )
    slope = _row("rise_slope", early, "least-squares slope of batteries_mean per generation")
    difference = _row(
        "rise_difference",
        early,
        f"mean batteries_mean of the last {RISE_BLOCK} generations minus the first {RISE_BLOCK}",
    )
    for method, tables in by_method.items():
        if not tables:
            continue
        generation = convergence_generation([t[t["generation"] <= end] for t in tables])
        converged[f"{method}_runs"] = len(tables)
        converged[f"{method}_mean"] = math.nan if generation is None else float(generation)
        summary = early_rise(tables, "batteries_mean", *early)
        slope.update({f"{method}_runs": summary.runs, f"{method}_mean": summary.slope_mean,
                      f"{method}_std": summary.slope_std})  # fmt: skip
        finite = int(np.sum(~np.isnan(np.asarray(summary.differences, dtype=float))))
        difference.update({f"{method}_runs": finite, f"{method}_mean": summary.difference_mean,
                           f"{method}_std": summary.difference_std})  # fmt: skip
    rows += [converged, slope, difference]
    return pd.DataFrame(rows)


def completions_by_method(runs: Mapping[str, Sequence[pd.DataFrame]]) -> pd.DataFrame:
    """:func:`completions` for each method, stacked with a leading ``method`` column."""
    frames = [completions(tables).assign(method=method) for method, tables in runs.items()]
    frames = [f for f in frames if len(f)]
    if not frames:
        return pd.DataFrame(columns=["method", *completions([]).columns])
    stacked = pd.concat(frames, ignore_index=True)
    return stacked[["method", *[c for c in stacked.columns if c != "method"]]]


def write_report(
    runs: Mapping[str, Sequence[pd.DataFrame]],
    out_dir: str | os.PathLike[str],
    window: Window = LATE_WINDOW,
    rise: Window = EARLY_WINDOW,
) -> list[Path]:
    """Write ``comparison.csv`` (:func:`summary_table`) and ``completions.csv``
    (:func:`completions_by_method`) under ``out_dir``, each atomically.

    Returns:
        The written paths; empty if no run closed a generation (nothing to compare).
    """
    if last_common_generation([t for m in METHODS for t in runs.get(m, ())]) is None:
        return []
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, table in (("comparison.csv", summary_table(runs, window, rise)),
                        ("completions.csv", completions_by_method(runs))):  # fmt: skip
        path = out / name
        with atomic_output(path) as temp:
            table.to_csv(temp, index=False, float_format="%.6g")
        paths.append(path)
    return paths
