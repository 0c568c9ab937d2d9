"""Copy the small tables of a sweep's finished runs into ``results/`` (to be committed).

A paper-scale sweep (Fig. 6: 40 runs of 120 generations) outlasts a working day, and a run
directory holds checkpoints and event logs that never belong in the repository. As each run
finishes, its statistics tables and its ``run.json`` (resolved config, seed, package version,
git commit) are copied to ``<to>/<method>-seed<NNN>/``, so no finished run is lost if the
machine changes, and ``cyber-rodent plot <to>`` draws the figures from the published tables.

    .venv/bin/python -m benchmarks.publish_runs --from runs/fig6 --to results/fig6

A run counts as finished when its statistics cover generations 0 to its target - 1, or when it
spent its step budget (``--max-steps``). Where a run has them, its watchdog table
(``watchdog.csv``), its per-arena statistics and a learning-mode run's ``learning.csv`` are
published with it. Runs already published with identical files are left alone; the names of newly
published runs are printed.
"""

from __future__ import annotations

import argparse
import json
import shutil
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

#: What a published run holds: its per-generation tables and its record.
PUBLISHED_FILES = ("statistics.csv", "statistics_per_robot.csv", "run.json")
#: Published too where a run has them (the watchdog's table, several arenas, learning mode).
OPTIONAL_FILES = ("learning.csv", "watchdog.csv", "statistics_per_arena.csv")


def finished(run: Path) -> bool:
    """Has the run in ``run`` completed its target generations or spent its step budget?"""
    try:
        record = json.loads((run / "run.json").read_text())
        table = pd.read_csv(run / "statistics.csv")
    except (OSError, ValueError, pd.errors.EmptyDataError):
        return False
    budget = record.get("max_steps")
    steps = record.get("summary", {}).get("control_steps", 0)
    if budget is not None and int(steps) >= int(budget):
        return True
    target = int(record.get("target_generations", 0))
    generations = set(table["generation"].astype(int)) if "generation" in table else set()
    return target > 0 and set(range(target)) <= generations


def publish_run(run: Path, target: Path) -> bool:
    """Copy one run's tables into ``target`` (each file atomically); False if ``target``
    already held identical copies."""
    names = PUBLISHED_FILES + tuple(n for n in OPTIONAL_FILES if (run / n).is_file())
    same = all(
        (target / name).exists() and (target / name).read_bytes() == (run / name).read_bytes()
        for name in names
    )
    if same:
        return False
    target.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copyfile(run / name, target / f".{name}.partial")
        (target / f".{name}.partial").replace(target / name)
    return True


def publish(source: Path, destination: Path) -> list[str]:
    """Copy every finished run's tables; return the names of runs copied now."""
    copied = []
    for run in sorted(p for p in source.iterdir() if p.is_dir()):
        if finished(run) and publish_run(run, destination / run.name):
            copied.append(run.name)
    return copied


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--from", dest="source", type=Path, required=True)
    parser.add_argument("--to", dest="destination", type=Path, required=True)
    args = parser.parse_args(argv)
    for name in publish(args.source, args.destination):
        print(name)


if __name__ == "__main__":
    main()
