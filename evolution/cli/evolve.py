"""``cyber-rodent evolve``: one EE, CE or mEDEA run in a run directory, and what a finished run
reports (shared with ``resume``)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from evolution.cli import options
from evolution.cli.parsing import CliError, int_arg

if TYPE_CHECKING:  # pandas is slow to import; ``--help`` must stay fast
    import pandas as pd

    from evolution.runner.config import RunConfig

HELP = "run embodied evolution (EE) or the centralised GA (CE) in a run directory"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Run EE or CE on the physics world. Writes a run directory (config, "
        "versions, statistics.csv, events.csv, checkpoints, figures). With no arguments: a "
        "short EE run (5 generations) that finishes in minutes."
    )
    parser.add_argument(
        "--method",
        default="ee",
        help="the evolution scheme: ee, embodied evolution; ce, the centralised GA (the "
        "paper's baseline); medea, mEDEA (one agent per robot); or one a plugin registered",
    )
    parser.add_argument(
        "--generations",
        type=int_arg("--generations"),
        default=5,
        help="generations to complete (default 5; the paper: 120)",
    )
    parser.add_argument("--seed", type=int_arg("--seed"), default=0, help="the run's seed")
    parser.add_argument(
        "--out", default=None, help="run directory (default: runs/<method>-seed<S>-<timestamp>)"
    )
    parser.add_argument(
        "--checkpoint-every",
        type=int_arg("--checkpoint-every"),
        default=1,
        help="generations between checkpoints",
    )
    parser.add_argument(
        "--keep-checkpoints",
        type=int_arg("--keep-checkpoints"),
        default=3,
        help="newest checkpoints to keep (default 3; 0 keeps every generation, which "
        "'transfer --generation' needs)",
    )
    parser.add_argument(
        "--profile",
        default=None,
        help="evolve in a hardware-like world: hardware, or a profile file fitted by "
        "'cyber-rodent sysid' (its robots, packs, noise and drives); default: the plain "
        "simulation",
    )
    options.add_max_steps(parser)
    options.add_tensorboard(parser, "in DIR/<name of --out>")
    options.add_plugin_option(parser, "run.json records each one's name and content hash")
    options.add_run_options(parser)


def run(args: argparse.Namespace) -> int:
    from evolution.lab import experiment
    from evolution.lab.api import RunOutput, RunSpec

    plugins = options.load_plugins(args)  # before the settings, which may name what they add
    base = _profiled_config(args)
    spec = RunSpec(
        args.method,
        args.generations,
        args.seed,
        config=base,
        overrides=options.read_settings(args),
        policies=args.policies,
        max_steps=args.max_steps,
        plugins=plugins,
    )
    out = args.out if args.out is not None else experiment.default_out_dir(args.method, args.seed)
    output = RunOutput(
        out,
        checkpoint_every=args.checkpoint_every,
        keep_checkpoints=args.keep_checkpoints,
        tensorboard=args.tensorboard,
        progress=not args.no_progress,
    )
    try:
        path, table = experiment.evolve(
            spec, output, resume=args.resume, force=args.force, argv=sys.argv
        )
    except KeyboardInterrupt:
        return interrupted(out)
    report_run(path, table)
    if args.generations < 120:
        print(
            f"This was a short run ({_count(args.generations, 'generation')}). The paper's "
            "Fig. 6 experiment (20 seeds x EE and CE x 120 generations):\n  "
            f"{experiment.PAPER_COMMAND}"
        )
    return 0


def _profiled_config(args: argparse.Namespace) -> RunConfig | None:
    """The run's base config in the world of ``--profile`` (None without one)."""
    from cyber_rodent.profiles import profile_from_arg
    from evolution.lab.api import make_config
    from evolution.lab.transfer import hardware_run_config

    if args.profile is None:
        return None
    if args.resume:
        raise CliError("--profile starts a run; --resume continues one with its own profile")
    profile = profile_from_arg(args.profile)
    return hardware_run_config(make_config(args.method), profile)


def interrupted(run_dir: str | os.PathLike[str]) -> int:
    """Say how to continue the run in ``run_dir``; the exit status of an interrupted run."""
    print(
        f"cyber-rodent: interrupted; continue with: cyber-rodent resume {run_dir}",
        file=sys.stderr,
    )
    return 130


def report_run(path: Path, table: pd.DataFrame) -> None:
    """What a finished run did, in three lines: its last generation, the watchdog, its files."""
    if len(table):
        last = table.iloc[-1]
        print(
            f"{_count(len(table), 'generation')}; last generation: {int(last['completed'])} agents "
            f"completed the survival task, batteries {last['batteries_mean']:.1f}, "
            f"matings {last['matings_mean']:.2f}"
        )
    print(_watchdog_line(path))
    print(f"run directory: {path}  (statistics.csv, events.csv, figures/, checkpoints/)")


def _count(n: int, noun: str) -> str:
    """``1 generation``, ``2 generations``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _watchdog_line(path: Path) -> str:
    """What the watchdog saw in the run, in one line, naming the robots (from run.json)."""
    try:
        summary = json.loads((path / "run.json").read_text()).get("summary", {})
    except (OSError, ValueError):
        return "watchdog: no record"
    tips, jams = int(summary.get("tips", 0)), int(summary.get("jams", 0))
    if not tips and not jams:
        return "watchdog: no robot tipped over or got stuck"
    robots = ", ".join(map(str, summary.get("troubled_robots", [])))
    rescues = int(summary.get("rescues", 0))
    return (
        f"watchdog: {_count(tips, 'tip')} and {_count(jams, 'jam')} (robots {robots}), "
        f"{_count(rescues, 'rescue')}; see events.csv and watchdog.csv"
    )
