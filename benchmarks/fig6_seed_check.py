"""Did a change to the simulation move Fig. 6? One seed's new runs against the published ones.

A change that alters what the robots do (a new vision model, say) leaves ``results/fig6``
stale. Re-running all 40 runs costs hours, so this checks first: the new EE and CE runs of one
seed (120 generations, made with the current code), their means over Fig. 6's late window
(generations 100-119, as ``fig6_runs.csv``), beside the same seed's published means and the
spread of the 20 published runs of each method. If a mean moved by more than one between-seed
standard deviation, Fig. 6 must be re-run::

    cyber-rodent evolve --method ee --seed 0 --generations 120 --out runs/check/ee-seed000
    cyber-rodent evolve --method ce --seed 0 --generations 120 --out runs/check/ce-seed000
    .venv/bin/python -m benchmarks.fig6_seed_check runs/check --table results/fig6_seed_check.csv

Writes one row per (method, quantity): the published mean of the seed, the new one, their
difference, the published runs' mean and standard deviation, and whether the difference
exceeds that deviation.

When the check calls for the re-run, ``--sets`` compares the re-run's runs as a set with the
published ones (per method and quantity: each set's mean and standard deviation over runs, and
the two-sided Mann-Whitney U test of new against published, exact up to 20 runs a side)::

    .venv/bin/python -m benchmarks.fig6_seed_check runs/fig6 --sets results/fig6_rerun.csv
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from benchmarks.paper_fig6 import QUANTITIES  # noqa: E402
from cyber_rodent.atomic import atomic_output  # noqa: E402
from evolution.lab.comparison import LATE_WINDOW, rank_test, run_means  # noqa: E402

PUBLISHED_RUNS = Path("results/fig6_runs.csv")


def window_means(runs: Path) -> pd.DataFrame:
    """Per ``<method>-seed<NNN>`` run in ``runs``: method, seed, its commit and its mean of each
    quantity over the late window (the columns of ``fig6_runs.csv``)."""
    rows = []
    for path in sorted(runs.glob("*-seed*")):
        stats = pd.read_csv(path / "statistics.csv")
        method, seed = path.name.split("-seed")[0], int(path.name.split("-seed")[1])
        if stats["generation"].max() < LATE_WINDOW[1]:
            raise ValueError(f"{path} has not reached generation {LATE_WINDOW[1]}")
        versions = json.loads((path / "run.json").read_text()).get("versions", {})
        row: dict[str, object] = {"method": method, "seed": seed,
                                  "commit": str(versions.get("git_commit", ""))}  # fmt: skip
        for quantity, column in QUANTITIES.items():
            row[quantity] = float(run_means([stats], column, *LATE_WINDOW)[0])
        rows.append(row)
    return pd.DataFrame(rows)


def compare_sets(runs: Path, published: pd.DataFrame) -> pd.DataFrame:
    """The runs in ``runs`` against the published runs, per (method, quantity): each set's
    size, mean and standard deviation over runs, the difference of the means, and the two-sided
    Mann-Whitney U test of new against published (p, rank-biserial effect: +1 when every new
    run is higher)."""
    new = window_means(runs)
    rows = []
    for method in sorted(set(new["method"])):
        ours, old = new[new["method"] == method], published[published["method"] == method]
        for quantity in QUANTITIES:
            a, b = ours[quantity].to_numpy(float), old[quantity].to_numpy(float)
            _, p, effect, test = rank_test(a, b)
            rows.append({
                "method": method, "quantity": quantity,
                "generations": f"{LATE_WINDOW[0]}-{LATE_WINDOW[1]}",
                "published_runs": len(b), "published_mean": b.mean(),
                "published_std": b.std(ddof=1), "new_runs": len(a), "new_mean": a.mean(),
                "new_std": a.std(ddof=1), "difference": a.mean() - b.mean(), "p": p,
                "rank_biserial": effect, "test": test,
            })  # fmt: skip
    return pd.DataFrame(rows)


def check(runs: Path, published: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, quantity) of every ``<method>-seed<NNN>`` run in ``runs``."""
    window = f"{LATE_WINDOW[0]}-{LATE_WINDOW[1]}"
    rows = []
    for run in window_means(runs).itertuples(index=False):
        method, seed, commit = str(run.method), int(run.seed), str(run.commit)
        ours = published[published["method"] == method]
        old = ours[ours["seed"] == seed]
        for quantity in QUANTITIES:
            new = float(getattr(run, quantity))
            before = float(old[quantity].iloc[0]) if len(old) else float("nan")
            spread = float(ours[quantity].std(ddof=1))
            rows.append({
                "method": method, "seed": seed, "quantity": quantity, "generations": window,
                "published": before, "new": new, "difference": new - before,
                "published_mean": float(ours[quantity].mean()), "published_std": spread,
                "published_runs": len(ours), "moved": abs(new - before) > spread,
                "commit": commit,
            })  # fmt: skip
    return pd.DataFrame(rows)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", type=Path, help="directory of <method>-seed<NNN> run directories")
    ap.add_argument("--published", type=Path, default=PUBLISHED_RUNS)
    ap.add_argument("--table", type=Path, default=None, help="write the comparison here (CSV)")
    ap.add_argument("--sets", type=Path, default=None,
                    help="compare every run in RUNS with the published runs as sets; write the "
                         "table here (CSV)")  # fmt: skip
    args = ap.parse_args(argv)
    published = pd.read_csv(args.published)
    if args.sets is not None:
        sets = compare_sets(args.runs, published)
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print(sets.round(3).to_string(index=False))
        with atomic_output(args.sets) as tmp:
            sets.round(5).to_csv(tmp, index=False)
        return sets
    table = check(args.runs, published)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.drop(columns=["commit"]).round(3).to_string(index=False))
    moved = table[table["moved"]]
    print(
        "\nmoved by more than the published runs' spread: "
        + (", ".join(f"{m} {q}" for m, q in zip(moved["method"], moved["quantity"], strict=True))
           or "nothing")
    )  # fmt: skip
    if args.table is not None:
        with atomic_output(args.table) as tmp:
            table.round(5).to_csv(tmp, index=False)
    return table


if __name__ == "__main__":
    main()
