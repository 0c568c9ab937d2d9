"""Reproduce the paper's Fig. 7 (sim-to-real transfer) end to end; rerun to continue.

The 5 fittest individuals of generation 40 of a simulated EE run seed a hardware-like colony of
3 robots x 5 agents (the ``"hardware"`` profile of :mod:`cyber_rodent.profiles`), which evolves
10 more generations, once per transfer seed (:func:`evolution.lab.transfer.transfer`)::

    .venv/bin/python -m benchmarks.paper_fig7 --out runs/fig7 [--source-seed 0] [--seeds 0-4] \
        [--generations 10] [--source-generations 40] [--table-dir results/fig7] \
        [--figure-dir docs/images]

1. ``<out>/source``: the source run, every checkpoint kept; a finished one is reused, an
   interrupted one resumed (:func:`evolution.lab.experiment.evolve`);
2. ``<out>/transfer-seed<N>``: one transfer per seed; a finished one is reused, an interrupted
   one is run again (a transfer cannot be resumed; it is deterministic for its seed);
3. ``--table-dir``: the small tables (never checkpoints): ``source/statistics.csv`` and
   ``source/run.json``, each ``transfer-seed<N>/statistics_per_robot.csv`` and
   ``transfer.json``, ``fig7_pooled.csv`` (per robot and generation, mean and std over seeds)
   and ``fig7_summary.csv`` (per seed and robot: batteries per agent over the first and the
   last 3 generations, deaths over the transfer), which is also printed;
4. ``--figure-dir``: ``fig7_seed<first seed>`` (one transfer, per robot) and ``fig7_pooled``
   (mean ± std over seeds), PNG and PDF.

``--set KEY=VALUE`` changes a setting of the source run (as ``cyber-rodent evolve --set``), e.g.
for a quick check with a small population; the transfers inherit it.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from cyber_rodent.atomic import write_bytes
from cyber_rodent.profiles import profile_by_name
from evolution.checkpoint import CheckpointError
from evolution.lab.api import (
    EVENTS_FILE,
    ROBOT_STATISTICS_FILE,
    RUN_FILE,
    STATISTICS_FILE,
    RunOutput,
    RunSpec,
    holds_a_run,
    make_config,
)
from evolution.lab.experiment import evolve, read_run_record
from evolution.lab.figures import plot_per_robot, pool_per_robot
from evolution.lab.sweep import parse_seeds
from evolution.lab.transfer import TRANSFER_FILE, TransferSpec, transfer
from evolution.runner.settings import parse_set

#: The paper's transfer: the 5 fittest individuals onto 3 robots with 5 virtual agents each.
TOP, ROBOTS, AGENTS_PER_ROBOT = 5, 3, 5
PROFILE = "hardware"
#: Generations averaged at the start and at the end of a transfer in the summary.
WINDOW = 3


def covers(run: Path, generations: int) -> bool:
    """Does the run's ``statistics.csv`` hold generations 0 to ``generations`` - 1?"""
    try:
        table = pd.read_csv(run / STATISTICS_FILE)
    except (OSError, ValueError):
        return False
    return set(range(generations)) <= set(table["generation"].astype(int))


def transfer_finished(run: Path, generations: int, source_generation: int) -> bool:
    """Has the transfer in ``run`` completed ``generations`` from ``source_generation``?
    (``events.csv`` is written only once every generation has closed.)"""
    try:
        target = read_run_record(run).get("target_generations")
        source = json.loads((run / TRANSFER_FILE).read_text()).get("source_generation")
    except (OSError, ValueError):
        return False
    return (
        (target, source) == (generations, source_generation)
        and (run / EVENTS_FILE).exists()
        and covers(run, generations)
    )


def run_source(
    out: Path, generations: int, seed: int, overrides: dict[str, Any], progress: bool
) -> str:
    """Evolve, resume or reuse the source run in ``out``; say which."""
    if covers(out, generations):
        record = read_run_record(out)
        if (record["config"]["method"], record["seed"]) != ("ee", seed):
            raise ValueError(f"{out} holds a {record['config']['method']} run of seed "
                             f"{record['seed']}, not the EE run of seed {seed}")  # fmt: skip
        return "reused"
    resume = holds_a_run(out)
    spec = RunSpec("ee", generations, seed, overrides=overrides)
    evolve(spec, RunOutput(out, keep_checkpoints=0, progress=progress), resume=resume)
    return "resumed" if resume else "evolved"


def run_transfer(
    source: Path, out: Path, seed: int, generations: int, source_generation: int, progress: bool
) -> str:
    """Run (or reuse) one transfer into ``out``; say which."""
    if transfer_finished(out, generations, source_generation):
        return "reused"
    if (out / TRANSFER_FILE).exists():  # an interrupted transfer: start it again
        shutil.rmtree(out)
    spec = TransferSpec(source, generation=source_generation, top=TOP, robots=ROBOTS,
                        agents_per_robot=AGENTS_PER_ROBOT, generations=generations,
                        profile=profile_by_name(PROFILE), seed=seed)  # fmt: skip
    transfer(spec, RunOutput(out, progress=progress))
    return "transferred"


def summarise(per_robot: pd.DataFrame, events: pd.DataFrame, window: int = WINDOW) -> pd.DataFrame:
    """Per robot of one transfer: mean batteries per agent over the first and the last
    ``window`` generations (generations without a full lifetime skipped), and its deaths."""
    generations = sorted(per_robot["generation"].unique())
    first, last = generations[:window], generations[-window:]
    deaths = events.loc[events["kind"] == "death", "robot"].value_counts()
    rows = []
    for robot, table in per_robot.groupby("robot"):
        batteries = table.set_index("generation")["batteries_mean"]
        rows.append({
            "robot": int(robot),
            f"batteries_first{window}": batteries[batteries.index.isin(first)].mean(),
            f"batteries_last{window}": batteries[batteries.index.isin(last)].mean(),
            "deaths": int(deaths.get(robot, 0)),
        })  # fmt: skip
    return pd.DataFrame(rows)


def write_results(
    source: Path, transfers: Mapping[int, Path], table_dir: Path, figure_dir: Path
) -> pd.DataFrame:
    """Copy the small tables, write the pooled and summary tables and the figures; return the
    summary."""
    copies = {source: (STATISTICS_FILE, RUN_FILE)}
    copies.update({run: (ROBOT_STATISTICS_FILE, TRANSFER_FILE) for run in transfers.values()})
    for run, names in copies.items():
        (table_dir / run.name).mkdir(parents=True, exist_ok=True)
        for name in names:
            write_bytes(table_dir / run.name / name, (run / name).read_bytes())
    per_robot = {s: pd.read_csv(run / ROBOT_STATISTICS_FILE) for s, run in transfers.items()}
    summary = pd.concat(
        [
            summarise(per_robot[s], pd.read_csv(run / EVENTS_FILE)).assign(seed=s)
            for s, run in transfers.items()
        ],
        ignore_index=True,
    )
    summary.insert(0, "seed", summary.pop("seed"))
    pooled = pool_per_robot(list(per_robot.values()))
    for name, table in (("fig7_pooled.csv", pooled), ("fig7_summary.csv", summary)):
        write_bytes(table_dir / name, table.to_csv(index=False, float_format="%.4g").encode())
    first = next(iter(transfers))
    plot_per_robot(per_robot[first], figure_dir / f"fig7_seed{first}",
                   title=f"After transfer (hardware-like profile), seed {first}")  # fmt: skip
    plot_per_robot(pooled, figure_dir / "fig7_pooled",
                   title=f"After transfer (hardware-like profile): mean ± std over "
                   f"{len(transfers)} seeds")  # fmt: skip
    return summary


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.paper_fig7", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--out", type=Path, required=True, help="directory of the runs")
    parser.add_argument("--source-seed", type=int, default=0)
    parser.add_argument("--seeds", default="0-4", help="transfer seeds: N, A-B or a comma list")
    parser.add_argument("--generations", type=int, default=10, help="generations after transfer")
    parser.add_argument("--source-generations", type=int, default=40)
    parser.add_argument("--table-dir", type=Path, default=Path("results/fig7"))
    parser.add_argument("--figure-dir", type=Path, default=Path("docs/images"))
    parser.add_argument("--set", action="append", metavar="KEY=VALUE", default=[],
                        help="a setting of the source run (repeatable)")  # fmt: skip
    parser.add_argument("--no-progress", action="store_true", help="hide progress bars")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        overrides = parse_set(args.set)
        make_config("ee", **overrides)
    except ValueError as err:
        parser.error(str(err))
    for name in ("generations", "source_generations"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.source_seed < 0:
        parser.error(f"--source-seed must be >= 0, got {args.source_seed}")
    for name in ("out", "table_dir", "figure_dir"):
        if getattr(args, name).is_file():
            parser.error(f"--{name.replace('_', '-')} {getattr(args, name)} is a file")

    progress = not args.no_progress
    source = args.out / "source"
    transfers = {s: args.out / f"transfer-seed{s}" for s in seeds}
    try:
        done = run_source(source, args.source_generations, args.source_seed, overrides, progress)
        print(f"source ({args.source_generations} generations): {done} {source}")
        for seed, run in transfers.items():
            done = run_transfer(source, run, seed, args.generations, args.source_generations,
                                progress)  # fmt: skip
            print(f"transfer seed {seed}: {done} {run}")
        summary = write_results(source, transfers, args.table_dir, args.figure_dir)
    except (ValueError, CheckpointError) as err:
        print(f"paper_fig7: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("paper_fig7: interrupted; run the same command again to continue", file=sys.stderr)
        return 130
    print(summary.to_string(index=False, float_format=lambda x: f"{x:.2f}"))
    print(f"tables: {args.table_dir}  figures: {args.figure_dir}/fig7_seed{seeds[0]}.png, "
          f"{args.figure_dir}/fig7_pooled.png")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
