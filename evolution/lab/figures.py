"""Publication figures from statistics tables: the paper's Fig. 6, and a Fig. 7-style plot.

Figures are written as PNG (for READMEs and slides) and PDF (vector, for papers), with
readable fonts, axis labels with units, and the paper's colours (EE blue, CE red). Matplotlib
runs on the non-interactive Agg backend, so this works on headless machines.

Fig. 6 aggregates like the paper: each run contributes its per-generation mean over the agents
that completed the survival task (``batteries_mean``, ``matings_mean`` of
:class:`evolution.stats.GenerationStats`); the figure shows the mean over runs (thick line) and
± one standard deviation over runs (thin dotted lines), per method. A generation in which a run
had no agent complete the task contributes nothing for that run (NaN is skipped).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output
from evolution.lab.comparison import completions

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Method name → (label, colour), the paper's colours.
METHOD_STYLE = {
    "ee": ("Embodied evolution (EE)", "#1f4fd1"),
    "ce": ("Centralised evolution (CE)", "#d1261f"),
    "medea": ("mEDEA", "#2a9d4b"),
}
FIGURE_FORMATS = ("png", "pdf")


def styled_pyplot() -> ModuleType:
    """Matplotlib's pyplot on the headless Agg backend, in the package's figure style."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "font.size": 11,
            "axes.titlesize": 12,
            "axes.labelsize": 11,
            "legend.fontsize": 10,
            "figure.dpi": 110,
            "savefig.dpi": 200,
            "axes.spines.top": False,
            "axes.spines.right": False,
        }
    )
    return plt


def aggregate_runs(tables: Sequence[pd.DataFrame], column: str) -> pd.DataFrame:
    """Mean and std over runs of ``column``, per generation.

    Args:
        tables: one statistics table per run (columns ``generation`` and ``column``).
        column: the per-run quantity, e.g. ``batteries_mean``.

    Returns:
        A frame indexed by generation with columns ``mean``, ``std`` (population std over the
        runs that have a value) and ``runs`` (how many runs contributed).
    """
    if not tables:
        raise ValueError("aggregate_runs needs at least one statistics table")
    for t in tables:
        missing = {"generation", column} - set(t.columns)
        if missing:
            raise ValueError(f"statistics table lacks column(s) {sorted(missing)}")
    wide = pd.concat(
        [t.set_index("generation")[column].rename(i) for i, t in enumerate(tables)], axis=1
    )
    values = wide.to_numpy(dtype=float)
    counts = np.sum(~np.isnan(values), axis=1)
    with warnings.catch_warnings():  # 'mean of empty slice' where no run has a value
        warnings.simplefilter("ignore", category=RuntimeWarning)
        mean = np.nanmean(values, axis=1)
        std = np.nanstd(values, axis=1)
    return pd.DataFrame({"mean": mean, "std": std, "runs": counts}, index=wide.index)


def summarise_runs(
    runs_by_method: Mapping[str, Sequence[pd.DataFrame]], window: int = 5
) -> pd.DataFrame:
    """The numbers a results table quotes: per method, at the last generation every run
    reached and averaged over the last ``window`` such generations.

    Each run's own mean first (over its generations in the window), then mean and population
    std over runs, so a run counts once whatever its length.

    Args:
        runs_by_method: e.g. ``{"ee": [table_seed0, ...], "ce": [...]}``.
        window: generations in the late average (the paper's curves are noisy per generation).

    Returns:
        One row per method and ``span`` (``"last"`` or ``"last {window}"``) with columns
        ``method``, ``span``, ``generations`` (e.g. ``"35-39"``), ``runs``, and mean/std over
        runs of ``batteries_mean``, ``matings_mean`` and ``completed``.
    """
    if isinstance(window, bool) or not isinstance(window, int) or window < 1:
        raise ValueError(f"window must be an integer in [1, ∞), got {window!r}")
    rows = []
    for method, tables in runs_by_method.items():
        tables = [t for t in tables if len(t)]
        if not tables:
            continue
        last = min(int(t["generation"].max()) for t in tables)
        for span, first in (("last", last), (f"last {window}", max(0, last - window + 1))):
            row: dict[str, object] = {
                "method": method,
                "span": span,
                "generations": f"{first}" if first == last else f"{first}-{last}",
                "runs": len(tables),
            }
            for column in ("batteries_mean", "matings_mean", "completed"):
                per_run = [
                    _mean_or_nan(t.loc[t["generation"].between(first, last), column])
                    for t in tables
                    if column in t.columns
                ]
                row[f"{column}_mean"] = float(np.mean(per_run)) if per_run else math.nan
                row[f"{column}_std"] = float(np.std(per_run)) if per_run else math.nan
            rows.append(row)
    return pd.DataFrame(rows)


def _mean_or_nan(values: pd.Series) -> float:
    """The mean of the non-NaN values; NaN (without numpy's warning) when there are none."""
    finite = values.dropna()
    return float(finite.mean()) if len(finite) else math.nan


def save_figure(fig: Figure, out_base: Path) -> list[Path]:
    out_base.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in FIGURE_FORMATS:
        path = out_base.with_suffix(f".{ext}")
        with atomic_output(path) as temp:  # keeps the suffix that picks the format
            fig.savefig(temp, bbox_inches="tight")
        paths.append(path)
    return paths


def plot_fig6(
    runs_by_method: Mapping[str, Sequence[pd.DataFrame]], out_base: str | Path
) -> list[Path]:
    """Fig. 6 (a) batteries and (b) matings per generation, mean ± std over runs, per method.

    Args:
        runs_by_method: e.g. ``{"ee": [table_seed0, ...], "ce": [...]}``; any subset of methods.
        out_base: output path without extension; ``.png`` and ``.pdf`` are written.

    Returns:
        The written file paths.
    """
    if not runs_by_method or not any(runs_by_method.values()):
        raise ValueError("plot_fig6 needs at least one run")
    plt = styled_pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.0))
    panels = (
        ("batteries_mean", "Captured batteries per agent", "(a) Captured batteries"),
        ("matings_mean", "Matings per agent", "(b) Matings"),
    )
    for ax, (column, ylabel, title) in zip(axes, panels, strict=True):
        for method, tables in runs_by_method.items():
            if not tables:
                continue
            label, colour = METHOD_STYLE.get(method, (method.upper(), None))
            agg = aggregate_runs(tables, column)
            gen = agg.index.to_numpy()
            n = int(agg["runs"].max())
            ax.plot(gen, agg["mean"], color=colour, lw=2.2, label=f"{label}, {n} runs")
            ax.plot(gen, agg["mean"] + agg["std"], color=colour, lw=0.9, ls=":")
            ax.plot(gen, agg["mean"] - agg["std"], color=colour, lw=0.9, ls=":")
        ax.set_xlabel("Generation")
        ax.set_ylabel(ylabel)
        ax.set_title(title, loc="left")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="lower right", frameon=False)
    fig.suptitle(
        "Agents that completed the survival task (full lifetime, ≥ 1 mating); "
        "mean over runs (thick) ± std (dotted)",
        fontsize=10,
    )
    fig.tight_layout()
    paths = save_figure(fig, Path(out_base))
    plt.close(fig)
    return paths


def pool_per_robot(tables: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """Mean and population std over runs of each robot's ``batteries_mean`` per generation.

    For several transfer runs (seeds) of the same colony: robot ``r`` is the same robot in
    each (e.g. the weak one), so its curves can be pooled. Generations a run lacks are left
    out of that generation's mean (``runs`` counts the contributors).

    Returns:
        Columns ``generation``, ``robot``, ``batteries_mean``, ``batteries_std``, ``runs``,
        ready for :func:`plot_per_robot`.
    """
    if not tables:
        raise ValueError("pool_per_robot needs at least one per-robot table")
    frames = []
    for k, t in enumerate(tables):
        missing = {"generation", "robot", "batteries_mean"} - set(t.columns)
        if missing:
            raise ValueError(f"per-robot table lacks column(s) {sorted(missing)}")
        frames.append(t[["generation", "robot", "batteries_mean"]].assign(run=k))
    grouped = pd.concat(frames).groupby(["generation", "robot"])["batteries_mean"]
    pooled = grouped.agg(batteries_mean="mean", batteries_std=lambda x: float(np.std(x)))
    pooled["runs"] = grouped.size()
    return pooled.reset_index()


def plot_per_robot(
    per_robot: pd.DataFrame, out_base: str | Path, title: str | None = None
) -> list[Path]:
    """A Fig. 7-style plot: mean captured batteries per generation, one line per robot.

    Args:
        per_robot: columns ``generation``, ``robot``, ``batteries_mean`` (the mean over the
            robot's agents that lived a full lifetime, unmated agents scored 0, as the paper's
            Fig. 7 caption says), optionally ``batteries_std``.
        out_base: output path without extension.
        title: optional figure title.
    """
    missing = {"generation", "robot", "batteries_mean"} - set(per_robot.columns)
    if missing:
        raise ValueError(f"per-robot table lacks column(s) {sorted(missing)}")
    if per_robot.empty:
        raise ValueError("per-robot table is empty")
    plt = styled_pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    for robot, rows in per_robot.sort_values("generation").groupby("robot"):
        (line,) = ax.plot(
            rows["generation"],
            rows["batteries_mean"],
            marker="o",
            ms=3.5,
            lw=1.8,
            label=f"CR {int(robot) + 1}",
        )
        if "batteries_std" in rows.columns:  # e.g. a mean over transfer runs: ± std band
            ax.fill_between(
                rows["generation"],
                rows["batteries_mean"] - rows["batteries_std"],
                rows["batteries_mean"] + rows["batteries_std"],
                color=line.get_color(),
                alpha=0.12,
                lw=0,
            )
    ax.set_xlabel("Generation")
    ax.set_ylabel("Captured batteries per agent")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(frameon=False)
    ax.set_title(title or "Captured batteries per robot (unmated agents scored 0)", fontsize=11)
    fig.tight_layout()
    paths = save_figure(fig, Path(out_base))
    plt.close(fig)
    return paths


def plot_completions(
    runs: Mapping[str, Sequence[pd.DataFrame]], out_base: str | Path
) -> list[Path]:
    """Agents that completed the survival task per generation: mean over runs ± std band.

    Fig. 6 averages over these agents only, so their number says how much each of its points
    rests on; the dashed line is the full lifetimes they are a share of. Statistics as in
    :func:`evolution.lab.comparison.completions` (standard deviation over runs with ``ddof=1``).

    Args:
        runs: statistics tables by method, e.g. ``{"ee": [...], "ce": [...]}``.
        out_base: output path without extension; ``.png`` and ``.pdf`` are written.

    Returns:
        The written file paths.
    """

    order = [m for m in METHOD_STYLE if m in runs] + [m for m in runs if m not in METHOD_STYLE]
    per_method = {m: completions(runs[m]) for m in order}
    per_method = {m: c for m, c in per_method.items() if len(c)}
    if not per_method:
        raise ValueError("plot_completions needs at least one run with a closed generation")
    plt = styled_pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    for method, table in per_method.items():
        label, colour = METHOD_STYLE.get(method, (method.upper(), None))
        gen = table["generation"].to_numpy()
        mean = table["completed_mean"].to_numpy(dtype=float)
        std = np.nan_to_num(table["completed_std"].to_numpy(dtype=float))  # one run: no band
        n = int(table["runs"].max())
        (line,) = ax.plot(gen, mean, color=colour, lw=2.0, label=f"{label}, {n} runs")
        ax.fill_between(gen, mean - std, mean + std, color=line.get_color(), alpha=0.15, lw=0)
        ax.plot(gen, table["full_lifetimes_mean"], color=line.get_color(), lw=1.0, ls="--")
    ax.set_xlabel("Generation")
    ax.set_ylabel("Agents per generation")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(frameon=False)
    ax.set_title(
        "Completed the survival task (solid, ± std over runs) of full lifetimes (dashed)",
        fontsize=10,
    )
    fig.tight_layout()
    paths = save_figure(fig, Path(out_base))
    plt.close(fig)
    return paths
