"""``cyber-rodent resume``: continue an interrupted run from its newest checkpoint."""

from __future__ import annotations

import argparse

from evolution.cli import options
from evolution.cli.evolve import interrupted, report_run
from evolution.cli.parsing import CliError, int_arg

HELP = "continue an interrupted run from its checkpoint"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Continue a run directory's run from its newest "
        "checkpoint; the result is identical to an uninterrupted run."
    )
    parser.add_argument("dir", help="the run directory")
    parser.add_argument(
        "--generations",
        type=int_arg("--generations"),
        default=None,
        help="new target (default: the run's own)",
    )
    options.add_tensorboard(parser, "in DIR/<name of the run directory>")
    options.add_plugin_option(
        parser,
        "resume loads the plugins run.json records by itself (refusing one that is missing or "
        "changed); where given, these must be the same",
    )
    parser.add_argument("--no-progress", action="store_true", help=options.NO_PROGRESS)


def run(args: argparse.Namespace) -> int:
    from cyber_rodent.plugins import PluginError, identify
    from evolution.lab import experiment

    given = None
    if args.plugin:  # found and hashed, not run: resume loads the run's recorded plugins
        try:
            given = [identify(spec) for spec in args.plugin]
        except PluginError as err:
            raise CliError(f"--plugin {err}") from None
    try:
        path, table = experiment.resume_run(
            args.dir,
            progress=not args.no_progress,
            generations=args.generations,
            tensorboard=args.tensorboard,
            plugins=given,
        )
    except KeyboardInterrupt:
        return interrupted(args.dir)
    report_run(path, table)
    return 0
