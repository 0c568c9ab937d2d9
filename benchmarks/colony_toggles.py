"""The colony study, round two: time sharing, the replacement rule and world size, one at a time.

The first colony study (``benchmarks/colony_study.py``) compared the paper's colony, 4 robots
time-sharing 100 agents, with 100 robots carrying one agent each in one 11.5 m field. That step
changed three things at once: time sharing (25 agents per robot, or 1), the world (one 2.3 m
arena, or one 11.5 m field) and the replacement rule (a spare list fed by 25 slots, or by 1).
This study toggles them one at a time. Every cell has the paper's 100 agents, Tables 1 and 2,
the shipped behaviours and the robot as fixed (docs/design.md §9.35):

======  =============  ===============  =========================  =================
cell    arenas         agents/robot     spare list shared by       against
======  =============  ===============  =========================  =================
P       1 x 4, 2.3 m   25               each robot's 25 agents     (the paper)
T       25 x 4, 2.3 m  1                the 25 robots at one       P: time sharing
                                        position in each arena
TC      25 x 4, 2.3 m  1                the whole colony           T: the rule
BC      1 x 100, 11.5  1                the whole colony           TC: world size
======  =============  ===============  =========================  =================

and, as secondary cells, CE in P, T and B (the big field) and mEDEA in T and B. Where a robot
carries one agent, its slot is the agent's whole 400-step life (as in the first study).

The analysis plan (hypotheses, measures, tests, correction, effect sizes) is in
docs/results.md and was committed before the first run; this module implements it:
:data:`PRIMARY` and :data:`SECONDARY` are its comparisons, :data:`GENERATION_WINDOW` and
:data:`ROBOT_HOUR_WINDOW` its two measures' windows.

    .venv/bin/python -m benchmarks.colony_toggles --power   # the power estimate (the plan's)
    .venv/bin/python -m benchmarks.colony_toggles --run [--workers 2]   # run or resume
    .venv/bin/python -m benchmarks.colony_toggles           # the analysis, from published tables

``--run`` runs the study as one sweep (:mod:`evolution.lab.sweep`, an explicit cell list, seed
by seed so that partial results cover every cell), or resumes it: finished runs are skipped
(runs already published too, so a new machine resumes from the repository), interrupted runs
continue from their checkpoints, a study directory holding another plan is refused.
``--groups`` runs only some groups' runs: two invocations on one ``--out`` can split the groups
(a long group on one core, the rest on the other). Every setting is checked before anything
starts (a bad one exits with status 2 and one line). As each run finishes its small tables are
published to ``--published``
(``results/colony_toggles/<cell>/<method>-seed<NNN>/``: statistics, per-robot and per-arena
statistics, the watchdog's table, ``run.json`` with the run's commit).

The analysis reads the published tables only (and P's, ``--p-published``) and writes
``runs.csv`` (one row per run: both measures and the descriptive quantities), ``groups.csv``
(mean and standard deviation per group) and ``tests.csv`` (every comparison: U, raw and Holm
p, the difference in means and Cliff's delta with their bootstrap intervals) into
``--published``, a figure per toggle (``docs/images/colony_toggle_<toggle>.png``), and prints
Markdown tables.

P and CE-P are the Fig. 6 re-run's runs (``results/fig6``, the same config and seeds), read
up to generation :data:`GENERATIONS` - 1: a run's first 60 generations do not depend on how
many it is set to run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from benchmarks.colony_study import StudyError, check_study_dir, run_finished  # noqa: E402
from benchmarks.publish_runs import finished, publish_run  # noqa: E402
from cyber_rodent.atomic import atomic_output, write_text  # noqa: E402
from evolution.lab.api import RunOutput  # noqa: E402
from evolution.lab.comparison import rank_test  # noqa: E402
from evolution.lab.grid import Cell  # noqa: E402
from evolution.lab.sweep import (  # noqa: E402
    Execution,
    SweepFailed,
    SweepRun,
    SweepSpec,
    check_ray_address,
    run_dir,
    sweep,
)

PROG = "colony_toggles"
#: The study's record in ``--out``: a resumed study must have the same plan.
STUDY_FILE = "study.json"
WATCHDOG_FILE = "watchdog.csv"
#: The Fig. 6 runs (on the fixed robot), whose first 60 generations are P and CE-P.
P_PUBLISHED = Path("results/fig6")

# --- the plan ------------------------------------------------------------------------------------
#: Generations per run, and the seeds of the cells this study runs (P's come from Fig. 6).
GENERATIONS = 60
SEEDS = tuple(range(8))
P_SEEDS = tuple(range(20))
#: The primary measure per life: batteries per completed life, the run's mean over these
#: generations (inclusive).
GENERATION_WINDOW = (50, 59)
#: The primary measure per robot-hour: the same quantity, the run's mean over the generations
#: that closed within these simulated robot-hours (lower bound excluded, upper included), of
#: every generation the run has (P's runs have 120): the level each configuration has reached
#: after the same robot time.
ROBOT_HOUR_WINDOW = (72.0, 96.0)
#: Family-wise error rate of each family (Holm).
ALPHA = 0.05
#: Bootstrap resamples of the effect sizes' confidence intervals, and their seed.
BOOTSTRAP = 20_000
BOOTSTRAP_SEED = 0

#: The worlds, as settings. The tiled world: 25 copies of the paper's arena, 4 robots and 5
#: packs each. The big field: the first study's N = 100 (the paper's density).
ONE_AGENT = {"evolution.population_size": 100, "evolution.n_robots": 100,
             "evolution.time_sharing_steps": 400, "world.n_packs": 125}  # fmt: skip
TILED = {**ONE_AGENT, "world.arenas": 25, "world.field_size": 2.3}
BIG = {**ONE_AGENT, "world.field_size": 11.5}


@dataclass(frozen=True)
class Group:
    """One cell and method: ``label`` as reported, the run directory's cell name (``None``:
    the Fig. 6 re-run's runs), the method and the settings beyond the defaults."""

    label: str
    cell: str | None
    method: str
    settings: dict[str, Any]


GROUPS: tuple[Group, ...] = (
    Group("EE-P", None, "ee", {}),
    Group("EE-T", "t", "ee", {**TILED, "evolution.spare_list": "position"}),
    Group("EE-TC", "tc", "ee", {**TILED, "evolution.spare_list": "colony"}),
    Group("EE-BC", "bc", "ee", {**BIG, "evolution.spare_list": "colony"}),
    Group("CE-P", None, "ce", {}),
    Group("CE-T", "tw", "ce", TILED),
    Group("CE-B", "bw", "ce", BIG),
    Group("mEDEA-T", "tw", "medea", TILED),
    Group("mEDEA-B", "bw", "medea", BIG),
)
GROUP = {g.label: g for g in GROUPS}


@dataclass(frozen=True)
class Comparison:
    """Two groups that differ in one toggle."""

    toggle: str
    a: str
    b: str


#: The primary family: each of EE's three toggles, on both measures (6 tests, Holm).
PRIMARY = (
    Comparison("time sharing", "EE-P", "EE-T"),
    Comparison("replacement rule", "EE-T", "EE-TC"),
    Comparison("world size", "EE-TC", "EE-BC"),
)
#: The secondary family (10 tests, Holm within it): the toggles under CE and mEDEA, and EE's
#: colony-wide spare list against mEDEA's broadcast in both worlds.
SECONDARY = (
    Comparison("time sharing (CE)", "CE-P", "CE-T"),
    Comparison("world size (CE)", "CE-T", "CE-B"),
    Comparison("world size (mEDEA)", "mEDEA-T", "mEDEA-B"),
    Comparison("EE against mEDEA, tiled", "EE-TC", "mEDEA-T"),
    Comparison("EE against mEDEA, big field", "EE-BC", "mEDEA-B"),
)
MEASURES = ("per_life", "per_robot_hour")


# --- the power estimate ------------------------------------------------------------------------
def power_table(
    first_runs: pd.DataFrame,
    n_a: int = len(P_SEEDS),
    n_b: int = len(SEEDS),
    shares: Sequence[float] = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5),
    draws: int = 2000,
    seed: int = 0,
    spread: str = "largest",
) -> pd.DataFrame:
    """The power of one primary test, from the first study's spreads (``first_runs``: its
    ``runs.csv``). The gap to split is EE's N = 4 mean minus its N = 100 mean (window
    batteries); the spread (``spread="largest"``) is the largest standard deviation of any EE
    cell's run means (a bimodal cell's included), so that the estimate errs low, or
    (``"ends"``) the pooled one of the N = 4 and N = 100 cells. For each share of the gap a
    toggle might carry, ``draws`` simulated studies of ``n_a`` and ``n_b`` normal run means
    that far apart: the share of two-sided Mann-Whitney tests below Holm's first threshold
    (``ALPHA / 6``) and below ``ALPHA``."""
    from scipy.stats import mannwhitneyu

    ee = first_runs[first_runs["method"] == "ee"]
    means = ee.groupby("n_robots")["batteries"].mean()
    gap = float(means.loc[means.index.min()] - means.loc[means.index.max()])
    sds = ee.groupby("n_robots")["batteries"].std(ddof=1)
    ends = [sds.index.min(), sds.index.max()]
    sd = float(sds.max() if spread == "largest" else math.sqrt((sds.loc[ends] ** 2).mean()))
    rng = np.random.default_rng(seed)
    first = ALPHA / (len(PRIMARY) * len(MEASURES))
    rows = []
    for share in shares:
        shift = share * gap
        p = np.array([
            mannwhitneyu(rng.normal(shift, sd, n_a), rng.normal(0.0, sd, n_b),
                         alternative="two-sided", method="exact").pvalue
            for _ in range(draws)
        ])  # fmt: skip
        rows.append({
            "share_of_gap": share, "shift": shift, "shift_in_sd": shift / sd, "n_a": n_a,
            "n_b": n_b, "power_holm_first": float((p < first).mean()),
            "power_alpha": float((p < ALPHA).mean()), "gap": gap, "sd": sd,
        })  # fmt: skip
    return pd.DataFrame(rows)


# --- the runs ------------------------------------------------------------------------------------
def study_cells() -> tuple[Cell, ...]:
    """The sweep's cells: one per run directory, with the methods of its groups."""
    cells: dict[str, Cell] = {}
    for group in GROUPS:
        if group.cell is None:
            continue
        known = cells.get(group.cell)
        if known is not None and dict(known.settings) != group.settings:
            raise StudyError(f"cell {group.cell}: its groups disagree on the settings")
        methods = (*(known.methods if known else ()), group.method)
        cells[group.cell] = Cell(group.cell, dict(group.settings), methods)
    return tuple(cells.values())


def study_spec(seeds: Sequence[int] = SEEDS, generations: int = GENERATIONS) -> SweepSpec:
    """The study's runs beyond P as one sweep, seed by seed."""
    methods = tuple(dict.fromkeys(g.method for g in GROUPS if g.cell is not None))
    return SweepSpec(
        methods=methods,
        seeds=tuple(seeds),
        generations=generations,
        cell_list=study_cells(),
        order="seed",
    )


def study_record(spec: SweepSpec) -> dict[str, Any]:
    """What ``study.json`` holds: the plan a resumed study must share."""
    return {
        "study": PROG,
        "seeds": list(spec.seeds),
        "generations": spec.generations,
        "cells": [
            {"name": c.name, "settings": dict(c.settings), "methods": list(spec.methods_of(c))}
            for c in spec.cells
        ],
    }


def publish_finished(out: Path, published: Path, spec: SweepSpec) -> list[SweepRun]:
    """Publish every finished run of ``spec`` in ``out`` not yet published as it stands."""
    done = []
    for member in spec.runs if out.is_dir() else []:
        source = run_dir(out, *member)
        if run_finished(source) and publish_run(source, run_dir(published, *member)):
            done.append(member)
    return done


def pending(
    spec: SweepSpec, out: Path, published: Path, groups: Sequence[str] | None = None
) -> list[SweepRun]:
    """The runs of ``spec`` still to run, in the study's order: neither finished in ``out``
    nor published in ``published`` (so that a new machine, whose ``out`` is empty, resumes
    from the published tables instead of running a finished run again); only those of
    ``groups`` (labels) where given."""
    chosen = None if groups is None else {(GROUP[g].cell, GROUP[g].method) for g in groups}
    return [
        m for m in spec.runs
        if (chosen is None or (m.cell, m.method) in chosen)
        and not run_finished(run_dir(out, *m)) and not finished(run_dir(published, *m))
    ]  # fmt: skip


def parse_groups(text: str) -> tuple[str, ...]:
    """``--groups``: comma-separated labels of the groups this study runs (P's run elsewhere).

    Raises:
        ValueError: one line naming the first unknown or P group and the allowed ones.
    """
    allowed = [g.label for g in GROUPS if g.cell is not None]
    labels = tuple(dict.fromkeys(part.strip() for part in text.split(",") if part.strip()))
    for label in labels or ("",):
        if label not in allowed:
            raise ValueError(f"--groups: {label!r} is not one of {', '.join(allowed)}")
    return labels


def run_study(args: argparse.Namespace, spec: SweepSpec) -> bool:
    """Run or resume the study in ``args.out``, publishing each run as it finishes; False if
    a run failed (the others finished and were published)."""
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / STUDY_FILE, json.dumps(study_record(spec), indent=2) + "\n")
    for member in publish_finished(args.out, args.published, spec):
        print(f"published {run_dir('', *member)}")
    todo = pending(spec, args.out, args.published, args.groups)
    print(f"{PROG}: {len(spec.runs)} runs, {len(pending(spec, args.out, args.published))} "
          f"to run, {len(todo)} of them here", flush=True)  # fmt: skip
    if not todo:
        return True

    def publish_one(member: SweepRun) -> None:
        source = run_dir(args.out, *member)
        try:
            if publish_run(source, run_dir(args.published, *member)):
                print(f"published {run_dir('', *member)}", flush=True)
        except OSError as err:
            print(f"{PROG}: could not publish {source}: {err}", file=sys.stderr)

    try:
        executor = "ray" if args.ray is not None else "local"
        sweep(
            dataclasses.replace(spec, members=tuple(todo)), RunOutput(args.out, progress=True),
            Execution(executor, args.workers, args.ray or "local"), on_run_done=publish_one,
        )  # fmt: skip
    except SweepFailed as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return False
    return True


# --- the analysis --------------------------------------------------------------------------------
@dataclass
class Run:
    """One published run of a group, cut at the study's generations."""

    group: str
    seed: int
    n_robots: int
    control_dt: float
    statistics: pd.DataFrame
    watchdog: pd.DataFrame | None
    #: Every generation the run closed, also past the study's (the per-robot-hour measure).
    every_generation: pd.DataFrame

    def robot_hours(self, every: bool = False) -> pd.Series:
        """Simulated robot-hours until each generation closed, by generation (``every``: of
        every generation the run closed)."""
        table = (self.every_generation if every else self.statistics).set_index("generation")
        return table["closed_at_step"] * self.n_robots * self.control_dt / 3600.0


def load_run(group: Group, path: Path, generations: int = GENERATIONS) -> Run:
    record = json.loads((path / "run.json").read_text())
    config = record["config"]
    every = pd.read_csv(path / "statistics.csv")
    stats = every[every["generation"] < generations].reset_index(drop=True)
    watchdog = path / WATCHDOG_FILE
    table = pd.read_csv(watchdog) if watchdog.is_file() else None
    if table is not None:
        table = table[table["generation"] < generations].reset_index(drop=True)
    return Run(group.label, int(record["seed"]), int(config["evolution"]["n_robots"]),
               float(config["survival"]["control_dt"]), stats, table, every)  # fmt: skip


def load_runs(published: Path, p_published: Path, generations: int = GENERATIONS) -> list[Run]:
    """Every finished published run of every group (P's from ``p_published``)."""
    runs = []
    for group in GROUPS:
        root, cell = (p_published, "") if group.cell is None else (published, group.cell)
        for seed in P_SEEDS if group.cell is None else SEEDS:
            path = run_dir(root, group.method, seed, cell)
            stats = path / "statistics.csv"
            if not stats.is_file():
                continue
            done = pd.read_csv(stats)["generation"]
            if len(done) and int(done.max()) >= generations - 1:
                runs.append(load_run(group, path, generations))
    return runs


def per_life(run: Run, window: tuple[int, int] = GENERATION_WINDOW) -> float:
    """Batteries per completed life, the run's mean over the generations of ``window``."""
    rows = run.statistics["generation"].between(*window)
    values = run.statistics.loc[rows, "batteries_mean"].astype(float).dropna()
    return float(values.mean()) if len(values) else math.nan


def per_robot_hour(run: Run, window: tuple[float, float] = ROBOT_HOUR_WINDOW) -> float:
    """Batteries per completed life, the run's mean over the generations (any it closed) that
    closed within ``window`` robot-hours; NaN if the run never reached its end."""
    hours = run.robot_hours(every=True)
    if hours.max() < window[1]:
        return math.nan
    inside = hours[(hours > window[0]) & (hours <= window[1])].index
    values = run.every_generation.set_index("generation").loc[inside, "batteries_mean"].dropna()
    return float(values.astype(float).mean()) if len(values) else math.nan


def run_row(run: Run) -> dict[str, Any]:
    stats = run.statistics
    late = stats[stats["generation"].between(*GENERATION_WINDOW)]
    hours = float(run.robot_hours().max())
    row: dict[str, Any] = {
        "group": run.group, "seed": run.seed, "per_life": per_life(run),
        "per_robot_hour": per_robot_hour(run), "robot_hours": hours,
        "completed": float(late["completed"].mean()), "deaths": float(late["deaths"].mean()),
        "matings": float(late["matings_mean"].mean()),
        "random_share": float(late["random_share"].mean()),
    }  # fmt: skip
    dog = run.watchdog
    if dog is not None:
        tips, jams = float(dog["tips"].sum()), float(dog["jams"].sum())
        tipped, stuck = float(dog["tipped_steps"].sum()), float(dog["stuck_steps"].sum())
        row.update({
            "tips_per_robot_hour": tips / hours, "jams_per_robot_hour": jams / hours,
            "tipped_share": tipped * run.control_dt / 3600 / hours,
            "stuck_share": stuck * run.control_dt / 3600 / hours,
            # how long each lasted, on average: the robot-steps spent tipped (stuck) per tip (jam)
            "tip_mean_steps": tipped / tips if tips else math.nan,
            "jam_mean_steps": stuck / jams if jams else math.nan,
            "rescues": int(dog["rescues"].sum()),
        })  # fmt: skip
    return row


def cliff_delta(a: np.ndarray, b: np.ndarray) -> float:
    """P(a > b) - P(a < b) over all pairs: the rank-biserial 2U / (n_a n_b) - 1 of ``a``."""
    diff = a[:, None] - b[None, :]
    return float((np.sign(diff)).mean())


def bootstrap_ci(
    a: np.ndarray, b: np.ndarray, resamples: int = BOOTSTRAP, seed: int = BOOTSTRAP_SEED
) -> tuple[tuple[float, float], tuple[float, float]]:
    """95 % percentile intervals of mean(b) - mean(a) and of Cliff's delta of b against a,
    resampling runs within each group."""
    rng = np.random.default_rng(seed)
    ia = rng.integers(0, len(a), (resamples, len(a)))
    ib = rng.integers(0, len(b), (resamples, len(b)))
    diff = b[ib].mean(axis=1) - a[ia].mean(axis=1)
    deltas = np.array([cliff_delta(b[j], a[i]) for i, j in zip(ia, ib, strict=True)])
    low, high = np.percentile(diff, [2.5, 97.5]), np.percentile(deltas, [2.5, 97.5])
    return (float(low[0]), float(low[1])), (float(high[0]), float(high[1]))


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (NaN stays NaN and counts as no test)."""
    p = np.asarray(p_values, dtype=float)
    valid = np.flatnonzero(~np.isnan(p))
    order = valid[np.argsort(p[valid], kind="stable")]
    adjusted = np.full(len(p), math.nan)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (len(order) - rank) * p[i])
        adjusted[i] = min(1.0, running)
    return [float(x) for x in adjusted]


def test_table(runs_table: pd.DataFrame) -> pd.DataFrame:
    """Every comparison of both families on both measures, with Holm within each family."""
    rows: list[dict[str, Any]] = []
    for family, comparisons in (("primary", PRIMARY), ("secondary", SECONDARY)):
        first = len(rows)
        for comparison in comparisons:
            for measure in MEASURES:
                values = {
                    g: runs_table.loc[runs_table["group"] == g, measure].dropna().to_numpy()
                    for g in (comparison.a, comparison.b)
                }
                a, b = values[comparison.a], values[comparison.b]
                u, p, _, test = rank_test(b, a)
                ready = len(a) > 1 and len(b) > 1
                (dl, dh), (cl, ch) = bootstrap_ci(a, b) if ready else ((math.nan,) * 2,) * 2
                rows.append({
                    "family": family, "toggle": comparison.toggle, "measure": measure,
                    "a": comparison.a, "b": comparison.b, "n_a": len(a), "n_b": len(b),
                    "mean_a": a.mean() if len(a) else math.nan,
                    "mean_b": b.mean() if len(b) else math.nan,
                    "difference": (b.mean() - a.mean()) if len(a) and len(b) else math.nan,
                    "difference_low": dl, "difference_high": dh,
                    "cliff_delta": cliff_delta(b, a) if len(a) and len(b) else math.nan,
                    "cliff_low": cl, "cliff_high": ch, "U": u, "test": test, "p": p,
                })  # fmt: skip
        adjusted = holm([float(r["p"]) for r in rows[first:]])
        for row, q in zip(rows[first:], adjusted, strict=True):
            row["p_holm"] = q
    return pd.DataFrame(rows)


def group_table(runs_table: pd.DataFrame) -> pd.DataFrame:
    """Mean and standard deviation of every per-run quantity, per group, in the plan's order."""
    numeric = [c for c in runs_table.columns if c not in ("group", "seed")]
    rows = []
    for group in GROUPS:
        part = runs_table[runs_table["group"] == group.label]
        row: dict[str, Any] = {"group": group.label, "runs": len(part)}
        for column in numeric:
            values = part[column].dropna()
            row[column] = values.mean() if len(values) else math.nan
            row[f"{column}_sd"] = values.std(ddof=1) if len(values) > 1 else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def plot_toggle(runs: Sequence[Run], comparison: Comparison, path: Path) -> Path:
    """One toggle: its two groups' batteries per completed life per generation (each run thin,
    the mean over runs thick) and per robot-hour (each run, every generation it closed), and
    the run means of both measures, the windows shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), gridspec_kw={"width_ratios": [3, 3, 2]})
    colours = {comparison.a: "tab:blue", comparison.b: "tab:orange"}
    for label, colour in colours.items():
        mine = [r for r in runs if r.group == label]
        if not mine:
            continue
        curves = [r.statistics.set_index("generation")["batteries_mean"] for r in mine]
        for run, curve in zip(mine, curves, strict=True):
            axes[0].plot(curve.index, curve.to_numpy(), color=colour, alpha=0.15, lw=0.8)
            every = run.every_generation["batteries_mean"].to_numpy()
            axes[1].plot(run.robot_hours(every=True).to_numpy(), every, color=colour,
                         alpha=0.15, lw=0.8)  # fmt: skip
        mean = pd.concat(curves, axis=1).mean(axis=1)
        axes[0].plot(mean.index, mean.to_numpy(), color=colour, lw=2,
                     label=f"{label} ({len(mine)} runs)")  # fmt: skip
    axes[0].axvspan(*GENERATION_WINDOW, color="grey", alpha=0.15)
    axes[1].axvspan(*ROBOT_HOUR_WINDOW, color="grey", alpha=0.15)
    axes[0].set(xlabel="generation", ylabel="batteries per completed life",
                title=f"{comparison.toggle}: per generation")  # fmt: skip
    axes[1].set(xlabel="simulated robot-hours", title="per robot-hour")
    axes[0].legend(loc="lower right", fontsize=8)
    table = pd.DataFrame([run_row(r) for r in runs if r.group in colours])
    for k, measure in enumerate(MEASURES):
        for j, label in enumerate(colours):
            values = table.loc[table["group"] == label, measure].dropna() if len(table) else []
            x = k + (j - 0.5) * 0.35 + np.linspace(-0.06, 0.06, max(len(values), 1))[: len(values)]
            axes[2].scatter(x, values, color=colours[label], s=14)
    ticks = [f"per life\n(gen. {GENERATION_WINDOW[0]}-{GENERATION_WINDOW[1]})",
             f"per robot-hour\n({ROBOT_HOUR_WINDOW[0]:g}-{ROBOT_HOUR_WINDOW[1]:g} h)"]  # fmt: skip
    axes[2].set_xticks(range(len(MEASURES)), ticks)
    axes[2].set(title="run means")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        fig.savefig(temp, format="png", dpi=110)
    plt.close(fig)
    return path


def _fmt(value: float, digits: int = 2) -> str:
    return (
        "—"
        if value is None or (isinstance(value, float) and math.isnan(value))
        else f"{value:.{digits}f}"
    )


def markdown(groups: pd.DataFrame, tests: pd.DataFrame) -> str:
    lines = ["| group | runs | per life | per robot-hour | completed | deaths | random share "
             "| tips / robot-h | jams / robot-h | steps per jam |",
             "|" + " --- |" * 10]  # fmt: skip
    for _, g in groups.iterrows():
        cells = [f"{_fmt(g[c])} ± {_fmt(g[c + '_sd'])}" for c in MEASURES]
        extra = [_fmt(g.get(c, math.nan), d) for c, d in (
            ("completed", 1), ("deaths", 1), ("random_share", 2), ("tips_per_robot_hour", 3),
            ("jams_per_robot_hour", 2), ("jam_mean_steps", 1))]  # fmt: skip
        lines.append(f"| {g['group']} | {g['runs']} | " + " | ".join(cells + extra) + " |")
    head = "| family | toggle | measure | a → b | difference [95 % CI] | Cliff's δ [95 % CI] |"
    lines += ["", head + " p | p (Holm) |", "|" + " --- |" * 8]
    for _, t in tests.iterrows():
        lines.append(
            f"| {t['family']} | {t['toggle']} | {t['measure']} | {t['a']} → {t['b']} "
            f"({t['n_a']}, {t['n_b']}) | {_fmt(t['difference'])} [{_fmt(t['difference_low'])}, "
            f"{_fmt(t['difference_high'])}] | {_fmt(t['cliff_delta'])} [{_fmt(t['cliff_low'])}, "
            f"{_fmt(t['cliff_high'])}] | {t['p']:.2g} | {t['p_holm']:.2g} |"
        )
    return "\n".join(lines)


def write_csv(table: pd.DataFrame, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        table.to_csv(temp, index=False, float_format="%.6g")
    return path


def analyse(published: Path, p_published: Path, figures: Path) -> tuple[list[Path], str]:
    """The plan's analysis of every published run (see the module docstring)."""
    runs = load_runs(published, p_published)
    if not runs:
        raise StudyError(f"no finished run in {published} or {p_published}")
    runs_table = pd.DataFrame([run_row(r) for r in runs])
    groups, tests = group_table(runs_table), test_table(runs_table)
    written = [
        write_csv(runs_table, published / "runs.csv"),
        write_csv(groups, published / "groups.csv"),
        write_csv(tests, published / "tests.csv"),
    ]
    for comparison in PRIMARY:
        slug = comparison.toggle.replace(" ", "_")
        written.append(plot_toggle(runs, comparison, figures / f"colony_toggle_{slug}.png"))
    return written, markdown(groups, tests)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--power", action="store_true", help="print the power estimate")
    parser.add_argument("--first", type=Path, default=Path("results/colony_scale/runs.csv"),
                        help="the first study's per-run table")  # fmt: skip
    parser.add_argument("--run", action="store_true", help="run or resume the study first")
    parser.add_argument("--out", type=Path, default=Path("runs/colony_toggles"))
    parser.add_argument("--workers", type=int, default=2, help="runs at a time")
    parser.add_argument(
        "--groups",
        metavar="LABELS",
        default=None,
        help="with --run: run only these groups' runs (comma-separated, e.g. mEDEA-B), so that "
        "two invocations on one --out can split the groups between them (default: all)",
    )
    parser.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="run on Ray: auto, HOST:PORT or local (default: local processes)",
    )
    parser.add_argument("--published", type=Path, default=Path("results/colony_toggles"))
    parser.add_argument(
        "--p-published",
        type=Path,
        default=P_PUBLISHED,
        help="the Fig. 6 re-run's published runs (P and CE-P)",
    )
    parser.add_argument("--figures", type=Path, default=Path("docs/images"))
    args = parser.parse_args(argv)
    if args.power:
        first = pd.read_csv(args.first)
        for spread in ("largest", "ends"):
            for n_a in (len(P_SEEDS), len(SEEDS)):
                table = power_table(first, n_a=n_a, spread=spread)
                print(f"spread {spread}, {n_a} runs against {len(SEEDS)}:")
                print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        return 0
    try:
        from cyber_rodent.validation import check_integer

        check_integer("--workers", args.workers, 1, 4096)
        if args.groups is not None:
            args.groups = parse_groups(args.groups)
        if args.ray is not None:
            check_ray_address(args.ray)
        spec = study_spec()
        spec.check()
        if args.run:
            check_study_dir(args.out, json.loads(json.dumps(study_record(spec))))
    except ValueError as err:  # StudyError too: one line, status 2, before anything starts
        print(f"{PROG}: error: {str(err).splitlines()[0]}", file=sys.stderr)
        return 2
    ok = run_study(args, spec) if args.run else True
    for member in publish_finished(args.out, args.published, spec):
        print(f"published {run_dir('', *member)}")
    try:
        written, text = analyse(args.published, args.p_published, args.figures)
    except StudyError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 1
    for path in written:
        print(f"wrote {path}")
    print(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
