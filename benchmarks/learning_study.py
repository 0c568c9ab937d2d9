"""Learning mode against the paper's fixed behaviours: the experiments, their tables and figures.

Usage::

    .venv/bin/python -m benchmarks.learning_study --run [--workers 2]   # the sweeps (resumable)
    .venv/bin/python -m benchmarks.learning_study --publish             # results/ + docs/images/

``--run`` runs five sweeps into ``runs/learning`` (each resumes where it stopped), all EE, 60
generations and a budget of :data:`MAX_STEPS` control steps per run (60 generations of the fixed
behaviours take 760,000-770,000 steps: a population that cannot complete its generations stops
after the robot time of about 80 of theirs):

* ``fixed``: the shipped behaviours, unchanged during life (the paper), seeds 0-4;
* ``modes``: learning mode, a grid of ``learning.init`` (shipped, zero) × ``learning.inheritance``
  (darwinian, lamarckian), seeds 0-4;
* ``energy_dependent`` and ``pack_reactivation``: one variant each against the fixed default,
  seed 0 (``reproduction.energy_dependent``; ``world.pack_reactivation_steps`` =
  :data:`REACTIVATION_STEPS`);
* ``frozen``: the within-life baseline, seeds 0-4: learning mode from the shipped values with
  its learning switched off (:data:`FROZEN`: α of 1e-9, ε of 0, so every agent acts greedily on
  the shipped values, as the fixed behaviours do). Fixed runs keep no record by age; this one
  does, so the within-life curves of the learners have a curve without learning to stand
  beside.

``--publish`` copies the finished runs' tables to ``results/learning/`` (statistics,
learning records, ``run.json``: :mod:`benchmarks.publish_runs`) and draws from them:

* ``results/learning/modes.csv``: per mode, the runs, generations closed, events per 1,000
  control steps (dockings, matings, deaths: comparable whether or not generations closed),
  batteries and matings over :data:`WINDOW` (or the last generations every run of the mode
  reached; column ``window``), mean ± sample std over runs, and, against ``fixed`` over the
  same generations, its mean, the two-sided Mann-Whitney p-value and the rank-biserial effect;
* ``results/learning/meta.csv`` and ``lifetime.csv``: the evolved learning parameters per
  generation and the within-life curves (:mod:`evolution.lab.learning_figures`);
* ``results/learning/inheritance.csv``: Lamarckian against Darwinian inheritance for each
  initial value, on the early generations (:data:`EARLY_WINDOW`) and on the generations a run
  needs to reach :data:`THRESHOLD_SHARE` of the fixed behaviours' batteries over
  :data:`WINDOW` (:func:`inheritance_table`);
* ``results/learning/meta_convergence.csv``: where each evolved learning parameter started and
  ended, and whether it settled (:func:`meta_convergence`);
* ``results/learning/variants.csv``: the two variants against the default, seed 0;
* ``results/learning/drift.csv`` (from each run's newest checkpoint, while ``runs/`` holds it):
  how far the learned values of the colony's 100 agents have moved from their initial values
  (:func:`table_drift`);
* ``docs/images/learning_modes.png``, ``learning_meta.png``, ``learning_lifetime.png``,
  ``learning_variants.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from behaviours.policies import BehaviourPolicies
from benchmarks.publish_runs import publish
from cyber_rodent.atomic import atomic_output
from evolution.checkpoint import load_checkpoint
from evolution.lab.comparison import available_window, compare_methods, rank_test, run_means
from evolution.lab.figures import aggregate_runs, save_figure, styled_pyplot
from evolution.lab.learning_figures import (
    META_LABELS,
    label_colours,
    lifetime_table,
    load_learning,
    meta_table,
    plot_lifetime,
    plot_meta_parameters,
)

RUNS = Path("runs/learning")
RESULTS = Path("results/learning")
IMAGES = Path("docs/images")
GENERATIONS = 60
SEEDS = "0-4"
#: Control steps per run: 60 generations of the fixed behaviours take about 770,000
#: (``results/fig6_published_contacts``: 758,576 and 768,115 for EE seeds 0 and 1).
MAX_STEPS = 1_000_000
#: ``world.pack_reactivation_steps`` of the variant: 20 s, a pack's worth of absence.
REACTIVATION_STEPS = 100
#: Generations each run's batteries and matings are averaged over.
WINDOW = (50, 59)
#: Learning mode with learning switched off: the within-life baseline.
FROZEN = (
    "learning.enabled=true", "learning.init=shipped", "learning.alpha_low=1e-9",
    "learning.alpha_high=1e-9", "learning.epsilon_low=0", "learning.epsilon_high=0",
)  # fmt: skip
#: Its label in the within-life table and figure.
FROZEN_LABEL = "shipped, learning off"
#: Early generations, where a faster evolution shows first.
EARLY_WINDOW = (10, 19)
#: Share of the fixed behaviours' batteries over :data:`WINDOW` whose first reaching is timed.
THRESHOLD_SHARE = 0.9
#: Generations in the trailing mean whose first reaching of the threshold is timed.
SMOOTHING = 5
#: The modes, in table order: label -> (sweep, cell).
MODES = {
    "fixed": ("fixed", ""),
    "shipped, Darwinian": ("modes", "init=shipped,inheritance=darwinian"),
    "shipped, Lamarckian": ("modes", "init=shipped,inheritance=lamarckian"),
    "zero, Darwinian": ("modes", "init=zero,inheritance=darwinian"),
    "zero, Lamarckian": ("modes", "init=zero,inheritance=lamarckian"),
}
#: One colour per mode in every figure of the study; the learning-off baseline shares the fixed
#: behaviours' grey, since it acts as they do.
COLOURS = {
    "fixed": "#555555",
    "shipped, Darwinian": "#1f4fd1",
    "shipped, Lamarckian": "#d1261f",
    "zero, Darwinian": "#2a9d3a",
    "zero, Lamarckian": "#e08a00",
    FROZEN_LABEL: "#555555",
}
VARIANTS = {
    "default": ("fixed", "", 0),
    "energy-dependent reproduction": ("energy_dependent", "", 0),
    f"pack reactivation {REACTIVATION_STEPS} steps": ("pack_reactivation", "", 0),
}


def sweep_commands(workers: int) -> list[tuple[str, list[str]]]:
    """The five sweeps: (name, ``cyber-rodent`` arguments)."""
    common = ["--methods", "ee", "--generations", str(GENERATIONS), "--max-steps",
              str(MAX_STEPS), "--workers", str(workers), "--no-progress"]  # fmt: skip
    return [
        ("fixed", ["sweep", "--seeds", SEEDS, *common]),
        ("modes", ["sweep", "--seeds", SEEDS, *common, "--set", "learning.enabled=true",
                   "--grid", "learning.init=shipped,zero",
                   "--grid", "learning.inheritance=darwinian,lamarckian"]),
        ("energy_dependent", ["sweep", "--seeds", "0", *common,
                              "--set", "reproduction.energy_dependent=true"]),
        ("pack_reactivation", ["sweep", "--seeds", "0", *common,
                               "--set", f"world.pack_reactivation_steps={REACTIVATION_STEPS}"]),
        ("frozen", ["sweep", "--seeds", SEEDS, *common,
                    *(item for setting in FROZEN for item in ("--set", setting))]),
    ]  # fmt: skip


def run_sweeps(workers: int) -> None:
    """Run (or resume) every sweep, one after another."""
    for name, args in sweep_commands(workers):
        out = RUNS / name
        resume = ["--resume"] if (out / "sweep.json").exists() else []
        command = [sys.executable, "-m", "evolution.cli", *args, "--out", str(out), *resume]
        print(" ".join(command[2:]), flush=True)
        subprocess.run(command, check=True)


# --- publishing -------------------------------------------------------------------------------
def publish_all() -> list[str]:
    """Copy every finished run's tables into ``results/learning`` (same layout as the runs)."""
    copied = []
    for sweep in ("fixed", "modes", "energy_dependent", "pack_reactivation", "frozen"):
        root = RUNS / sweep
        if not root.is_dir():
            continue
        cells = [p for p in root.iterdir() if p.is_dir() and "=" in p.name] or [root]
        for cell in cells:
            where = cell.name if cell != root else ""
            target = RESULTS / sweep / where
            copied += [f"{sweep}/{where + '/' if where else ''}{name}"
                       for name in publish(cell, target)]  # fmt: skip
    return copied


def run_dirs(sweep: str, cell: str, seeds: Sequence[int] | None = None) -> list[Path]:
    """The published run directories of a sweep cell (EE runs, seed order)."""
    root = RESULTS / sweep / cell if cell else RESULTS / sweep
    if not root.is_dir():
        return []
    runs = sorted(p for p in root.iterdir() if p.is_dir() and p.name.startswith("ee-seed"))
    if seeds is not None:
        runs = [p for p in runs if int(p.name.removeprefix("ee-seed")) in seeds]
    return runs


def _statistics(runs: Sequence[Path]) -> list[pd.DataFrame]:
    return [pd.read_csv(run / "statistics.csv") for run in runs]


def _events_per_thousand(runs: Sequence[Path]) -> dict[str, tuple[float, float]]:
    """Dockings, matings and deaths per 1,000 control steps: mean and sample std over runs."""
    rates: dict[str, list[float]] = {"dockings": [], "matings": [], "deaths": []}
    for run in runs:
        summary = json.loads((run / "run.json").read_text())["summary"]
        steps = max(1, int(summary["control_steps"]))
        for name in rates:
            rates[name].append(1000.0 * float(summary[name]) / steps)
    return {name: _mean_std(values) for name, values in rates.items()}


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    finite = np.array([v for v in values if math.isfinite(v)], dtype=float)
    if not len(finite):
        return math.nan, math.nan
    return float(finite.mean()), float(finite.std(ddof=1)) if len(finite) > 1 else math.nan


def modes_table() -> pd.DataFrame:
    """One row per mode (see the module docstring)."""
    fixed = _statistics(run_dirs(*MODES["fixed"]))
    rows = []
    for label, (sweep, cell) in MODES.items():
        runs = run_dirs(sweep, cell)
        if not runs:
            continue
        tables = _statistics(runs)
        closed = [len(t) for t in tables]
        steps = [json.loads((r / "run.json").read_text())["summary"]["control_steps"]
                 for r in runs]  # fmt: skip
        row: dict[str, object] = {
            "mode": label,
            "runs": len(runs),
            "generations_closed_mean": float(np.mean(closed)),
            "generations_closed_min": int(min(closed)),
            "control_steps_mean": float(np.mean(steps)),
        }
        for name, (mean, std) in _events_per_thousand(runs).items():
            row[f"{name}_per_1000_steps_mean"] = mean
            row[f"{name}_per_1000_steps_std"] = std
        # The window, or the last generations every run of the mode reached (then the fixed
        # behaviours are compared over the same generations).
        window = available_window([t for t in tables if len(t)], WINDOW)
        row["window"] = "" if window is None else f"{window[0]}-{window[1]}"
        for quantity, column in (("batteries", "batteries_mean"), ("matings", "matings_mean")):
            if window is None:
                continue
            mean, std = _mean_std(list(run_means(tables, column, *window)))
            row[f"{quantity}_mean"] = mean
            row[f"{quantity}_std"] = std
            if label != "fixed" and fixed:
                test = compare_methods(tables, fixed, column, window)
                row[f"{quantity}_fixed_mean"] = test.ce_mean
                row[f"{quantity}_p_vs_fixed"] = test.p_value
                row[f"{quantity}_rank_biserial_vs_fixed"] = test.rank_biserial
        rows.append(row)
    return pd.DataFrame(rows)


def generations_to_reach(table: pd.DataFrame, level: float, smoothing: int = SMOOTHING) -> float:
    """The first generation at which the trailing ``smoothing``-generation mean of a run's
    batteries per life reaches ``level``; the run's generation count if it never does (a
    censored value that ranks it slowest), NaN for a run that closed none."""
    if not len(table):
        return math.nan
    trailing = table["batteries_mean"].rolling(smoothing, min_periods=smoothing).mean()
    reached = table["generation"][trailing >= level]
    return float(reached.iloc[0]) if len(reached) else float(len(table))


def _compare(darwinian: Sequence[float], lamarckian: Sequence[float]) -> dict[str, float]:
    """Means, sample stds, two-sided Mann-Whitney p (:func:`evolution.lab.comparison.rank_test`) and
    rank-biserial effect (positive when Lamarckian is higher) of two samples of per-run values."""
    d = np.array([v for v in darwinian if math.isfinite(v)], dtype=float)
    lam = np.array([v for v in lamarckian if math.isfinite(v)], dtype=float)
    out = {"darwinian_runs": float(len(d)), "lamarckian_runs": float(len(lam))}
    for name, values in (("darwinian", d), ("lamarckian", lam)):
        out[f"{name}_mean"], out[f"{name}_std"] = _mean_std(list(values))
    _, out["p_value"], out["rank_biserial"], _ = rank_test(lam, d)
    return out


def inheritance_table(
    groups: Mapping[str, Sequence[pd.DataFrame]], fixed: Sequence[pd.DataFrame]
) -> pd.DataFrame:
    """Lamarckian against Darwinian inheritance, for each initial value with runs of both.

    Rows per init: batteries and matings over :data:`EARLY_WINDOW`, each run's mean; and the
    generations to reach :data:`THRESHOLD_SHARE` of the fixed behaviours' mean batteries over
    :data:`WINDOW` (:func:`generations_to_reach`). Lamarckian evolution is faster if its early
    values are higher and its generations to the threshold fewer.

    Args:
        groups: statistics tables by mode label (``"shipped, Darwinian"``, ...).
        fixed: the fixed behaviours' statistics tables, which set the threshold.
    """
    fixed_means = list(run_means(fixed, "batteries_mean", *WINDOW)) if fixed else []
    level = THRESHOLD_SHARE * _mean_std(fixed_means)[0]
    rows = []
    for init in ("shipped", "zero"):
        darwinian = [t for t in groups.get(f"{init}, Darwinian", ()) if len(t)]
        lamarckian = [t for t in groups.get(f"{init}, Lamarckian", ()) if len(t)]
        if not darwinian or not lamarckian:
            continue
        window = available_window(darwinian + lamarckian, EARLY_WINDOW)
        measures: list[tuple[str, list[float], list[float]]] = []
        if window is not None:
            for quantity, column in (("batteries", "batteries_mean"), ("matings", "matings_mean")):
                measures.append((
                    f"{quantity} {window[0]}-{window[1]}",
                    list(run_means(darwinian, column, *window)),
                    list(run_means(lamarckian, column, *window)),
                ))  # fmt: skip
        if math.isfinite(level):
            measures.append((
                f"generations to {THRESHOLD_SHARE:.0%} of fixed ({level:.2f} batteries)",
                [generations_to_reach(t, level) for t in darwinian],
                [generations_to_reach(t, level) for t in lamarckian],
            ))  # fmt: skip
        for measure, d_values, l_values in measures:
            rows.append({"init": init, "measure": measure, **_compare(d_values, l_values)})
    return pd.DataFrame(rows)


def _span_mean(table: pd.DataFrame, first: int, last: int, column: str) -> float:
    """The mean of ``column`` over generations ``first..last``; NaN if there are none."""
    values = table.loc[table["generation"].between(first, last), column]
    return float(values.mean()) if len(values) else math.nan


def meta_convergence(meta: pd.DataFrame) -> pd.DataFrame:
    """Per mode and learning parameter: the population mean (mean over runs) over generations
    0-9, 40-49 and 50-59, the std of the run means and the within-population std over 50-59,
    and ``settled``: the mean moved by less than the between-run std from 40-49 to 50-59 (a
    stated rule; NaN where a mode lacks those generations)."""
    rows = []
    for label, table in meta.groupby("label", sort=False):
        for name in META_LABELS:
            start, middle, end = (
                _span_mean(table, first, last, f"{name}_mean")
                for first, last in ((0, 9), (40, 49), (50, 59))
            )
            between = _span_mean(table, 50, 59, f"{name}_between_runs")
            settled: object = math.nan
            if all(math.isfinite(v) for v in (middle, end, between)):
                settled = bool(abs(end - middle) < between)
            rows.append({
                "label": label, "parameter": name, "mean_0_9": start, "mean_40_49": middle,
                "mean_50_59": end, "between_runs_50_59": between,
                "within_population_50_59": _span_mean(table, 50, 59, f"{name}_within"),
                "settled": settled,
            })  # fmt: skip
    return pd.DataFrame(rows)


def table_drift(
    changed_rows: np.ndarray, changed_values: np.ndarray, initial: np.ndarray, n_tables: int
) -> dict[str, float]:
    """How far learned values have moved from a newborn's initial values.

    A checkpoint stores only the rows of the stacked tables that differ from the initial values
    (``docs/design.md`` §10), as flat indices over ``n_tables`` tables of ``initial``'s rows.
    Returns the changed rows per table, the share of them whose greedy action differs from the
    initial one, and their mean absolute change. The greedy share counts only rows whose initial
    values have a single best action (NaN if none has): where actions tie, as in every row of
    zero values, the policy picks at random and there is no greedy action to change.
    """
    rows = np.asarray(changed_rows, dtype=np.int64)
    values = np.asarray(changed_values, dtype=np.float64)
    if not rows.size:
        return {"changed_rows_per_table": 0.0, "greedy_changed": 0.0, "mean_abs_change": 0.0}
    base = np.asarray(initial, dtype=np.float64)[rows % initial.shape[0]]
    single = (base == base.max(axis=1, keepdims=True)).sum(axis=1) == 1
    flipped = values[single].argmax(axis=1) != base[single].argmax(axis=1)
    return {
        "changed_rows_per_table": rows.size / n_tables,
        "greedy_changed": float(flipped.mean()) if single.any() else math.nan,
        "mean_abs_change": float(np.mean(np.abs(values - base))),
    }


def drift_table() -> pd.DataFrame:
    """:func:`table_drift` of each learning run's newest checkpoint under :data:`RUNS`."""
    tables = BehaviourPolicies.load_default().tables
    if tables is None:
        raise RuntimeError("the shipped behaviours are not stacked tile-coded tables")
    rows = []
    for label, (sweep, cell) in MODES.items():
        if sweep != "modes":
            continue
        init = label.split(",")[0]
        for run in sorted((RUNS / sweep / cell).glob("ee-seed*")):
            found = sorted((run / "checkpoints").glob("*.ckpt"))
            if not found:
                continue
            state = load_checkpoint(found[-1])
            learned = state["learning"]
            n_tables = len(learned["parameters"]["alpha"])
            initial = tables.table if init == "shipped" else np.zeros_like(tables.table)
            rows.append({"mode": label, "run": run.name, "checkpoint": found[-1].stem,
                         **table_drift(learned["changed_rows"], learned["changed_values"],
                                       initial, n_tables)})  # fmt: skip
    return pd.DataFrame(rows)


def variants_table() -> pd.DataFrame:
    rows = []
    for label, (sweep, cell, seed) in VARIANTS.items():
        runs = run_dirs(sweep, cell, [seed])
        if not runs:
            continue
        table = _statistics(runs)[0]
        row: dict[str, object] = {"variant": label, "seed": seed, "generations_closed": len(table)}
        for name, (mean, _) in _events_per_thousand(runs).items():
            row[f"{name}_per_1000_steps"] = mean
        for quantity, column in (("batteries", "batteries_mean"), ("matings", "matings_mean"),
                                 ("completed", "completed")):  # fmt: skip
            row[f"{quantity}_{WINDOW[0]}_{WINDOW[1]}"] = float(run_means([table], column,
                                                                         *WINDOW)[0])  # fmt: skip
        rows.append(row)
    return pd.DataFrame(rows)


def plot_curves(
    groups: Mapping[str, Sequence[pd.DataFrame]],
    rates: Mapping[str, Mapping[str, tuple[float, float]]],
    out_base: Path,
    title: str,
    colours: Mapping[str, str] | None = None,
) -> list[Path]:
    """Batteries and matings per generation, mean ± std over runs, one line per group; and
    each group's dockings, matings and deaths per 1,000 control steps (equal robot time).
    ``colours`` fixes a group's colour (the others: :func:`label_colours`)."""
    plt = styled_pyplot()
    palette = list(label_colours(list(groups), colours).values())
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.4), gridspec_kw={"width_ratios": [1, 1, 1.1]})
    bars = axes[2]
    kinds = ("dockings", "matings", "deaths")
    width = 0.8 / max(1, len(groups))
    for g, (colour, label) in enumerate(zip(palette, groups, strict=False)):
        if label not in rates:
            continue
        means = [rates[label][kind][0] for kind in kinds]
        stds = [rates[label][kind][1] for kind in kinds]
        x = np.arange(len(kinds)) + (g - (len(groups) - 1) / 2) * width
        bars.bar(x, means, width, yerr=np.nan_to_num(stds), color=colour, capsize=2)
    bars.set_xticks(np.arange(len(kinds)), kinds)
    bars.set_ylabel("per 1,000 control steps (all agents)")
    bars.grid(alpha=0.3, axis="y")
    for ax, (column, name) in zip(
        axes[:2], (("batteries_mean", "batteries captured"), ("matings_mean", "matings")),
        strict=True,
    ):  # fmt: skip
        for colour, (label, tables) in zip(palette, groups.items(), strict=False):
            tables = [t for t in tables if len(t)]
            if not tables:
                ax.plot([], [], color=colour, label=f"{label}: no generation closed")
                continue
            stats = aggregate_runs(tables, column)
            x = stats.index.to_numpy()
            runs = f"{len(tables)} run{'' if len(tables) == 1 else 's'}"
            ax.plot(x, stats["mean"], color=colour, label=f"{label} ({runs})")
            ax.fill_between(x, stats["mean"] - stats["std"], stats["mean"] + stats["std"],
                            color=colour, alpha=0.12)  # fmt: skip
        ax.set_xlabel("generation")
        ax.set_ylabel(f"{name} per life")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    paths = save_figure(fig, out_base)
    plt.close(fig)
    return paths


def _write_csv(table: pd.DataFrame, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        table.to_csv(temp, index=False, float_format="%.5g")
    return path


def publish_results() -> list[Path]:
    """Tables and figures from the published runs."""
    written = [_write_csv(modes_table(), RESULTS / "modes.csv")]
    learning = {
        label: [t for run in run_dirs(sweep, cell) for t in load_learning(run)]
        for label, (sweep, cell) in MODES.items()
        if label != "fixed"
    }
    meta = meta_table(learning)
    lifetime = lifetime_table({**learning, FROZEN_LABEL: [
        t for run in run_dirs("frozen", "") for t in load_learning(run)]})  # fmt: skip
    written.append(_write_csv(meta, RESULTS / "meta.csv"))
    written.append(_write_csv(meta_convergence(meta), RESULTS / "meta_convergence.csv"))
    written.append(_write_csv(lifetime, RESULTS / "lifetime.csv"))
    written += plot_meta_parameters(meta, IMAGES / "learning_meta", COLOURS)
    written += plot_lifetime(lifetime, IMAGES / "learning_lifetime", COLOURS)
    groups = {label: _statistics(run_dirs(sweep, cell)) for label, (sweep, cell) in MODES.items()}
    inheritance = inheritance_table(groups, groups["fixed"])
    if len(inheritance):
        written.append(_write_csv(inheritance, RESULTS / "inheritance.csv"))
    rates = {label: _events_per_thousand(run_dirs(sweep, cell))
             for label, (sweep, cell) in MODES.items() if run_dirs(sweep, cell)}  # fmt: skip
    written += plot_curves(
        groups, rates, IMAGES / "learning_modes",
        f"EE with fixed and learned behaviours ({GENERATIONS} generations or "
        f"{MAX_STEPS:,} control steps; mean ± std over seeds)", COLOURS,
    )  # fmt: skip
    drift = drift_table()
    if len(drift):
        written.append(_write_csv(drift, RESULTS / "drift.csv"))
    variants = variants_table()
    if len(variants):
        written.append(_write_csv(variants, RESULTS / "variants.csv"))
        runs = {label: run_dirs(sweep, cell, [seed])
                for label, (sweep, cell, seed) in VARIANTS.items()}  # fmt: skip
        written += plot_curves(
            {label: _statistics(found) for label, found in runs.items()},
            {label: _events_per_thousand(found) for label, found in runs.items() if found},
            IMAGES / "learning_variants",
            "Variants from the Cyber Rodent literature against the default (EE, seed 0)",
            {"default": COLOURS["fixed"]},
        )  # fmt: skip
    return [p for p in written if p.suffix != ".pdf" or p.parent != IMAGES]


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", action="store_true", help="run (or resume) the sweeps")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--publish", action="store_true", help="publish tables and figures")
    args = parser.parse_args(argv)
    if not (args.run or args.publish):
        parser.error("choose --run, --publish or both")
    if args.run:
        run_sweeps(args.workers)
    if args.publish:
        for name in publish_all():
            print(f"published {name}")
        for path in publish_results():
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
