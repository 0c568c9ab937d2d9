"""Figures and tables of learning mode, drawn from the runs' ``learning.csv``.

Every learning run writes, per generation, the agents that lived their full lifetime: their
captures and matings per ``fitness_time_unit`` (100) steps of age and their evolved learning
parameters (:meth:`evolution.learning.LifetimeLearning.record_rows`). From any set of such runs,
grouped under labels (a sweep's cells, or the modes of a study), this module draws:

* :func:`plot_meta_parameters`: the evolved learning rate, discount, trace decay and ε over
  generations: per label the mean over runs of the population mean, with a band of ± the
  population's own standard deviation (averaged over runs): a band that narrows is a
  population converging;
* :func:`plot_lifetime`: within-life learning curves: captures and matings per 100 steps of
  age, in the first generations (:data:`EARLY`) and in the last ones every run reached
  (:data:`LATE_SPAN` generations), mean over runs.

:func:`write_learning_report` writes both figures and their tables for one directory (a run,
a sweep or a cell) or for the cells of a grid; ``cyber-rodent plot`` calls it whenever the runs
it plots have learning records.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output
from evolution.lab.api import LEARNING_FILE, STATISTICS_FILE
from evolution.lab.figures import save_figure, styled_pyplot

#: The learning parameters drawn, with their axis labels.
META_LABELS = {
    "alpha": "learning rate α",
    "gamma": "discount γ",
    "lam": "trace decay λ",
    "epsilon": "exploration ε",
}
#: Generations of the early within-life curve.
EARLY = (0, 9)
#: Generations of the late within-life curve: the last this many every run reached.
LATE_SPAN = 10
_AGE_COLUMN = re.compile(r"^(batteries|matings)_age_(\d+)_(\d+)$")


def load_learning(directory: str | Path) -> list[pd.DataFrame]:
    """The ``learning.csv`` tables of a run directory or of the run directories in a sweep
    directory (or a cell), in name order, each cut to the generations its run closed (all of
    its rows if it closed none); empty if there are none."""
    root = Path(directory)
    if (root / LEARNING_FILE).is_file():
        paths = [root / LEARNING_FILE]
    elif root.is_dir():
        paths = sorted(p / LEARNING_FILE for p in root.iterdir() if (p / LEARNING_FILE).is_file())
    else:
        paths = []
    tables = []
    for path in paths:
        table = pd.read_csv(path)
        statistics = path.parent / STATISTICS_FILE
        if "closed" not in table.columns and statistics.is_file():
            table["closed"] = table["generation"] < len(pd.read_csv(statistics))
        if "closed" in table.columns and table["closed"].any():
            # The generations the run closed; a run that closed none (a population that never
            # completes a generation) shows every life it recorded.
            table = table[table["closed"].astype(bool)]
        if len(table):
            tables.append(table.reset_index(drop=True))
    return tables


def age_bins(table: pd.DataFrame) -> list[tuple[int, int]]:
    """The age bins of a learning table, ``[(0, 100), (100, 200), ...]``."""
    bins = set()
    for column in table.columns:
        match = _AGE_COLUMN.match(column)
        if match:
            bins.add((int(match.group(2)), int(match.group(3))))
    return sorted(bins)


def meta_table(groups: Mapping[str, Sequence[pd.DataFrame]]) -> pd.DataFrame:
    """Per label and generation: runs, and for each learning parameter the mean over runs of
    the population mean (``<p>_mean``), its std over runs (``<p>_between_runs``) and the mean
    over runs of the population std (``<p>_within``)."""
    rows = []
    for label, tables in groups.items():
        if not tables:
            continue
        generations = sorted(set().union(*(set(t["generation"]) for t in tables)))
        indexed = [t.set_index("generation") for t in tables]
        for generation in generations:
            present = [t.loc[generation] for t in indexed if generation in t.index]
            row: dict[str, object] = {
                "label": label, "generation": int(generation), "runs": len(present),
            }  # fmt: skip
            for name in META_LABELS:
                means = np.array([float(p[f"{name}_mean"]) for p in present])
                stds = np.array([float(p[f"{name}_std"]) for p in present])
                row[f"{name}_mean"] = float(means.mean())
                row[f"{name}_between_runs"] = float(means.std())
                row[f"{name}_within"] = float(stds.mean())
            rows.append(row)
    return pd.DataFrame(rows)


def lifetime_table(groups: Mapping[str, Sequence[pd.DataFrame]]) -> pd.DataFrame:
    """Per label, phase (early, late) and age bin: captures and matings per agent in that bin,
    mean and std over runs (each run's own mean over the phase's generations first)."""
    rows = []
    for label, tables in groups.items():
        if not tables:
            continue
        last = min(int(t["generation"].max()) for t in tables)
        early = (EARLY[0], min(EARLY[1], last))
        # the late phase never repeats early generations: a run that closed few has none
        phases = {"early": early, "late": (max(early[1] + 1, last - LATE_SPAN + 1), last)}
        for phase, (first, final) in phases.items():
            if first > final:
                continue
            chosen = [t[t["generation"].between(first, final)] for t in tables]
            chosen = [t for t in chosen if len(t)]
            if not chosen:
                continue
            for low, high in age_bins(chosen[0]):
                row: dict[str, object] = {
                    "label": label, "phase": phase, "generations": f"{first}-{final}",
                    "runs": len(chosen), "age_from": low, "age_to": high,
                }  # fmt: skip
                for quantity in ("batteries", "matings"):
                    column = f"{quantity}_age_{low}_{high}"
                    per_run = np.array(
                        [np.average(t[column], weights=t["lives"]) for t in chosen]
                    )
                    row[f"{quantity}_mean"] = float(per_run.mean())
                    row[f"{quantity}_std"] = float(per_run.std())
                rows.append(row)
    return pd.DataFrame(rows)


def label_colours(labels: Sequence[str], given: Mapping[str, str] | None = None) -> dict[str, str]:
    """One colour per label: ``given`` where it names the label (so a study's figures agree),
    else the next of a fixed palette."""
    palette = ["#1f4fd1", "#d1261f", "#2a9d3a", "#9b36c9", "#e08a00", "#555555", "#00a0b0"]
    chosen = dict(given or {})
    spare = iter(c for c in palette if c not in chosen.values())
    return {label: chosen[label] if label in chosen else next(spare, "#000000")
            for label in labels}  # fmt: skip


def plot_meta_parameters(
    table: pd.DataFrame, out_base: str | Path, colours: Mapping[str, str] | None = None
) -> list[Path]:
    """The four learning parameters over generations (see the module docstring); ``colours``
    fixes a label's colour."""
    plt = styled_pyplot()
    labels = list(dict.fromkeys(table["label"]))
    colours = label_colours(labels, colours)
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.4), sharex=True)
    for ax, (name, title) in zip(axes.flat, META_LABELS.items(), strict=True):
        for label in labels:
            part = table[table["label"] == label]
            x = part["generation"].to_numpy()
            mean = part[f"{name}_mean"].to_numpy()
            within = part[f"{name}_within"].to_numpy()
            ax.plot(x, mean, color=colours[label], label=label, lw=1.6)
            ax.fill_between(x, mean - within, mean + within, color=colours[label], alpha=0.15)
        ax.set_title(title)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("generation")
    axes[0, 0].legend(loc="best", fontsize=9)
    fig.suptitle("Evolved learning parameters: population mean (line) ± population std (band)")
    fig.tight_layout()
    paths = save_figure(fig, Path(out_base))
    plt.close(fig)
    return paths


def plot_lifetime(
    table: pd.DataFrame, out_base: str | Path, colours: Mapping[str, str] | None = None
) -> list[Path]:
    """Within-life curves, early (dashed) and late (solid) generations, per label; ``colours``
    fixes a label's colour."""
    plt = styled_pyplot()
    labels = list(dict.fromkeys(table["label"]))
    colours = label_colours(labels, colours)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, quantity in zip(axes, ("batteries", "matings"), strict=True):
        for label in labels:
            for phase, style in (("early", "--"), ("late", "-")):
                part = table[(table["label"] == label) & (table["phase"] == phase)]
                if not len(part):
                    continue
                centre = (part["age_from"] + part["age_to"]) / 2
                ax.errorbar(
                    centre, part[f"{quantity}_mean"], yerr=part[f"{quantity}_std"],
                    color=colours[label], ls=style, marker="o", ms=4, capsize=3,
                    label=f"{label}, generations {part['generations'].iloc[0]}",
                )  # fmt: skip
        ax.set_xlabel("age (control steps)")
        ax.set_ylabel(f"{'captures' if quantity == 'batteries' else 'matings'} per 100 steps")
        ax.grid(alpha=0.3)
    axes[1].legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize=8)
    fig.suptitle(
        "Within-life curves of agents that lived their full lifetime (mean ± std over runs)"
    )
    fig.tight_layout()
    paths = save_figure(fig, Path(out_base))
    plt.close(fig)
    return paths


def write_learning_report(
    groups: Mapping[str, Sequence[pd.DataFrame]], figures: str | Path, prefix: str = "learning"
) -> list[Path]:
    """Both figures and their tables (``<prefix>_meta``, ``<prefix>_lifetime``) into
    ``figures``; nothing if no group has a learning record."""
    groups = {label: tables for label, tables in groups.items() if tables}
    if not groups:
        return []
    out = Path(figures)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    meta, lifetime = meta_table(groups), lifetime_table(groups)
    for name, table in ((f"{prefix}_meta", meta), (f"{prefix}_lifetime", lifetime)):
        path = out / f"{name}.csv"
        with atomic_output(path) as temp:
            table.to_csv(temp, index=False, float_format="%.5g")
        written.append(path)
    written += plot_meta_parameters(meta, out / f"{prefix}_meta")
    if len(lifetime):
        written += plot_lifetime(lifetime, out / f"{prefix}_lifetime")
    return written


__all__ = [
    "EARLY",
    "LATE_SPAN",
    "META_LABELS",
    "age_bins",
    "label_colours",
    "lifetime_table",
    "load_learning",
    "meta_table",
    "plot_lifetime",
    "plot_meta_parameters",
    "write_learning_report",
]
