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

P and CE-P are the Fig. 6 re-run's runs (``results/fig6``, the same config and seeds), read
up to generation :data:`GENERATIONS` - 1: a run's first 60 generations do not depend on how
many it is set to run.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

PROG = "colony_toggles"

# --- the plan ------------------------------------------------------------------------------------
#: Generations per run, and the seeds of the cells this study runs (P's come from Fig. 6).
GENERATIONS = 60
SEEDS = tuple(range(8))
P_SEEDS = tuple(range(20))
#: The primary measure per life: batteries per completed life, the run's mean over these
#: generations (inclusive).
GENERATION_WINDOW = (50, 59)
#: The primary measure per robot-hour: the same quantity, the run's mean over the generations
#: that closed within these simulated robot-hours (lower bound excluded, upper included): the
#: level each configuration has reached after the same robot time.
ROBOT_HOUR_WINDOW = (96.0, 120.0)
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--power", action="store_true", help="print the power estimate")
    parser.add_argument("--first", type=Path, default=Path("results/colony_scale/runs.csv"),
                        help="the first study's per-run table")  # fmt: skip
    args = parser.parse_args(argv)
    if args.power:
        first = pd.read_csv(args.first)
        for spread in ("largest", "ends"):
            for n_a in (len(P_SEEDS), len(SEEDS)):
                table = power_table(first, n_a=n_a, spread=spread)
                print(f"spread {spread}, {n_a} runs against {len(SEEDS)}:")
                print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        return 0
    parser.print_help()
    return 0


if __name__ == "__main__":
    sys.exit(main())
