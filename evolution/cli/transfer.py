"""``cyber-rodent transfer``: seed a hardware-like colony with a run's fittest agents and keep
evolving (the paper's Fig. 7)."""

from __future__ import annotations

import argparse
from pathlib import Path

from evolution.cli.options import NO_PROGRESS
from evolution.cli.parsing import CliError, int_arg

HELP = "seed a hardware-like colony with a run's fittest agents and keep evolving (Fig. 7)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Take the fittest individuals of one generation of a run (its checkpoint: "
        "evolve it with --keep-checkpoints 0), put them on --robots robots with "
        "--agents-per-robot virtual agents each, and continue embodied evolution, by default "
        "in the hardware-like profile (noisy IR and vision, per-robot motors, 3 robots and 6 "
        "packs). Writes a run directory with per-robot statistics and a Fig. 7-style figure."
    )
    parser.add_argument("--from", dest="source", required=True, help="source run directory")
    parser.add_argument(
        "--generation", type=int_arg("--generation"), default=40, help="source generation"
    )
    parser.add_argument("--top", type=int_arg("--top"), default=5, help="fittest individuals")
    parser.add_argument(
        "--robots", type=int_arg("--robots"), default=3, help="robots of the new colony"
    )
    parser.add_argument(
        "--agents-per-robot",
        type=int_arg("--agents-per-robot"),
        default=5,
        help="virtual agents per robot",
    )
    parser.add_argument(
        "--generations", type=int_arg("--generations"), default=10, help="generations after"
    )
    parser.add_argument(
        "--profile",
        default="hardware",
        help="world profile: hardware, sim or a profile file fitted by 'cyber-rodent sysid'",
    )
    parser.add_argument("--seed", type=int_arg("--seed"), default=0, help="the new run's seed")
    parser.add_argument("--out", required=True, help="new run directory")
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS)


def run(args: argparse.Namespace) -> int:
    from cyber_rodent.profiles import profile_from_arg
    from cyber_rodent.validation import check_integer
    from cyber_rodent.world import MAX_ROBOTS
    from evolution.config import MAX_GENERATIONS, MAX_POPULATION
    from evolution.lab.api import RunOutput
    from evolution.lab.transfer import ROBOT_STATISTICS_FILE, TransferSpec, transfer

    # The numbers and paths first: transfer() reads the source checkpoint before its own checks.
    check_integer("--generation", args.generation, 0, MAX_GENERATIONS)
    check_integer("--top", args.top, 1, MAX_POPULATION)
    check_integer("--robots", args.robots, 1, MAX_ROBOTS)
    check_integer("--agents-per-robot", args.agents_per_robot, 1, MAX_POPULATION // args.robots)
    check_integer("--generations", args.generations, 1, MAX_GENERATIONS)
    check_integer("--seed", args.seed, 0)
    source, out = Path(args.source), Path(args.out)
    if not source.is_dir():
        what = "is a file, not a run directory" if source.exists() else "no such run directory"
        raise CliError(f"--from {source}: {what}")
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out} is a file, not a directory")
    spec = TransferSpec(
        args.source,
        generation=args.generation,
        top=args.top,
        robots=args.robots,
        agents_per_robot=args.agents_per_robot,
        generations=args.generations,
        profile=profile_from_arg(args.profile),
        seed=args.seed,
    )
    result = transfer(spec, RunOutput(args.out, progress=not args.no_progress))
    table = result.per_robot
    if len(table):
        first = table[table["generation"] == table["generation"].min()]
        last = table[table["generation"] == table["generation"].max()]
        for robot in sorted(table["robot"].unique()):
            a = first.loc[first["robot"] == robot, "batteries_mean"]
            b = last.loc[last["robot"] == robot, "batteries_mean"]
            print(
                f"CR {robot + 1}: batteries per agent {a.iloc[0] if len(a) else float('nan'):.2f}"
                f" -> {b.iloc[0] if len(b) else float('nan'):.2f}"
            )
    print(
        f"transfer run: {result.out}  (statistics.csv, {ROBOT_STATISTICS_FILE}, transfer.json, "
        "figures/fig7.png)"
    )
    return 0
