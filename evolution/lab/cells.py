"""How the cells of a grid sweep compare, on their final generations.

Each run contributes its mean over its last ``window`` generations (one generation's mean over a
handful of completed agents is noisy), and a cell reports the mean and standard deviation of
those run means over its seeds, per method (``cells.csv``, ``cells.{png,pdf}``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output
from evolution.lab.figures import METHOD_STYLE, save_figure, styled_pyplot
from evolution.lab.grid import GRID_FILE, cells, read_grid
from evolution.lab.sweep import load_sweep

#: Generations at the end of each run that a cell comparison averages over, by default.
DEFAULT_WINDOW = 10
#: The per-run quantities a cell comparison reports.
COMPARED_COLUMNS = ("batteries_mean", "matings_mean", "completed")


def load_cells(
    path: str | os.PathLike[str],
) -> dict[str, tuple[Mapping[str, Any], dict[str, list[pd.DataFrame]]]]:
    """Per cell name: its settings and its runs' statistics tables grouped by method."""
    root = Path(path)
    grid = read_grid(root)
    if grid is None:
        raise ValueError(f"{root} is not a grid sweep (no {GRID_FILE})")
    return {c.name: (c.settings, load_sweep(root / c.name)) for c in cells(grid)}


def run_final_means(table: pd.DataFrame, column: str, window: int) -> float:
    """A run's mean of ``column`` over its last ``window`` generations (NaN rows skipped)."""
    values = table.sort_values("generation")[column].to_numpy(dtype=float)[-window:]
    values = values[~np.isnan(values)]
    return float(values.mean()) if len(values) else math.nan


def compare_cells(
    loaded: Mapping[str, tuple[Mapping[str, Any], Mapping[str, Sequence[pd.DataFrame]]]],
    window: int = DEFAULT_WINDOW,
) -> pd.DataFrame:
    """One row per cell and method: mean ± std over seeds of each run's final-window mean.

    Columns: ``cell``, one per grid key, ``method``, ``runs``, ``generations`` (the window, as
    "first–last" of the shortest run), then ``<quantity>`` and ``<quantity>_std`` for batteries,
    matings and completed agents. Standard deviations are over runs (ddof = 1; NaN for one run).
    """
    rows: list[dict[str, Any]] = []
    for name, (settings, by_method) in loaded.items():
        for method, tables in by_method.items():
            tables = [t for t in tables if len(t)]
            if not tables:
                continue
            last = min(int(t["generation"].max()) for t in tables)
            row: dict[str, Any] = {"cell": name, **settings, "method": method}
            row["runs"] = len(tables)
            row["generations"] = f"{max(0, last - window + 1)}-{last}"
            for column in COMPARED_COLUMNS:
                means = np.array([run_final_means(t, column, window) for t in tables])
                means = means[~np.isnan(means)]
                short = column.removesuffix("_mean")
                row[short] = float(means.mean()) if len(means) else math.nan
                row[f"{short}_std"] = float(means.std(ddof=1)) if len(means) > 1 else math.nan
            rows.append(row)
    return pd.DataFrame(rows)


def plot_cells(table: pd.DataFrame, out_base: str | os.PathLike[str]) -> list[Path]:
    """Batteries, matings and completed agents per cell and method (mean ± std over seeds)."""
    plt = styled_pyplot()
    names = list(dict.fromkeys(table["cell"]))
    quantities = [("batteries", "batteries per life"), ("matings", "matings per life"),
                  ("completed", "agents completing the task")]  # fmt: skip
    width = max(6.0, 1.1 * len(names) + 2.0)
    fig, axes = plt.subplots(1, 3, figsize=(min(width * 1.6, 24.0), 4.2), squeeze=False)
    methods = [m for m in METHOD_STYLE if m in set(table["method"])]
    x = np.arange(len(names))
    offsets = np.linspace(-0.15, 0.15, len(methods)) if len(methods) > 1 else np.zeros(1)
    for ax, (column, label) in zip(axes[0], quantities, strict=True):
        for offset, method in zip(offsets, methods, strict=True):
            rows = table[table["method"] == method].set_index("cell").reindex(names)
            legend, colour = METHOD_STYLE[method]
            ax.errorbar(
                x + offset, rows[column], yerr=rows[f"{column}_std"], fmt="o", color=colour,
                capsize=3, label=legend.split(" (")[0],
            )  # fmt: skip
        ax.set_xticks(x, names, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    window = table["generations"].iloc[0] if len(table) else ""
    axes[0][0].legend(frameon=False)
    fig.suptitle(f"Grid cells: mean ± std over seeds of each run's mean, generations {window}")
    fig.tight_layout()
    return save_figure(fig, Path(out_base))


def write_cell_comparison(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    window: int = DEFAULT_WINDOW,
) -> list[Path]:
    """``cells.csv`` and ``cells.{png,pdf}`` for the grid sweep at ``path``, into ``out``
    (default ``<path>/figures``)."""
    root = Path(path)
    table = compare_cells(load_cells(root), window)
    if table.empty:
        return []
    figures = Path(out) if out is not None else root / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    csv = figures / "cells.csv"
    with atomic_output(csv) as temp:
        table.to_csv(temp, index=False, float_format="%.4g")
    return [csv, *plot_cells(table, figures / "cells")]
