"""The command table and ``main``: which module serves each sub-command, how the parser is
built from them, and how an error becomes one line with exit status 2."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType

from evolution.cli import (
    config,
    evolve,
    gap,
    plot,
    render,
    resume,
    snapshot,
    sweep,
    sysid,
    train_behaviours,
    transfer,
)
from evolution.cli.parsing import EXIT_USAGE, CliError, CliParser, UsageError, one_line


@dataclass(frozen=True)
class Command:
    """A sub-command: the module that holds its ``add_arguments(parser)`` (its options, and
    its description where it has a longer one) and its ``run(args) -> int``."""

    help: str
    """its line in ``cyber-rodent --help``, and its description unless the module sets one"""
    module: ModuleType | str
    """the module, or the name of one imported only when its command runs (torch, OpenGL)"""

    def load(self) -> ModuleType:
        """The module (imported here where the table names it)."""
        if isinstance(self.module, str):
            return importlib.import_module(self.module)
        return self.module


#: The sub-commands, in the order ``cyber-rodent --help`` lists them.
COMMANDS: dict[str, Command] = {
    "snapshot": Command(snapshot.HELP, snapshot),
    "train-behaviours": Command(train_behaviours.HELP, train_behaviours),
    "evolve": Command(evolve.HELP, evolve),
    "resume": Command(resume.HELP, resume),
    "sweep": Command(sweep.HELP, sweep),
    "config": Command(config.HELP, config),
    "plot": Command(plot.HELP, plot),
    "render": Command(render.HELP, render),
    "transfer": Command(transfer.HELP, transfer),
    "sysid": Command(sysid.HELP, sysid),
    "gap": Command(gap.HELP, gap),
    "view": Command(
        "watch a run, a checkpoint or a task live in MuJoCo's interactive viewer",
        "evolution.lab.viewer",
    ),
    "deploy": Command(
        "write a deployment bundle of a run's fittest mated agents for a real robot",
        "evolution.lab.deploy.__main__",
    ),
    "export": Command(
        "export the learned behaviours as torch.export programs (.pt2)", "behaviours.export"
    ),
}


def _command_of(argv: Sequence[str]) -> str | None:
    """The sub-command of a command line: its first word that is not an option."""
    return next((word for word in argv if not word.startswith("-")), None)


def build_parser(command: str | None = None) -> CliParser:
    """The command-line parser with every command's options, except those of a command whose
    module is imported only when it runs: ``command`` (the one being run) gets its options."""
    parser = CliParser(
        prog="cyber-rodent",
        description="Cyber Rodent colony simulation: embodied evolution of survival in MuJoCo.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    parser.commands = sub.choices
    for name, entry in COMMANDS.items():
        p = sub.add_parser(name, help=entry.help, description=entry.help)
        if isinstance(entry.module, str) and name != command:
            continue
        module = entry.load()
        module.add_arguments(p)
        p.set_defaults(func=module.run)
    return parser


def _user_errors() -> tuple[type[Exception], ...]:
    """Errors that are the user's to fix (one line, exit 2), a failed sweep's included once
    the sweep is loaded (called when an error is caught, so lazily imported modules count)."""
    from cyber_rodent.assets import AssetNotFoundError

    # A CheckpointError is a ValueError.
    errors: tuple[type[Exception], ...] = (CliError, ValueError, AssetNotFoundError)
    if "evolution.lab.sweep" not in sys.modules:
        return errors
    from evolution.lab.sweep import SweepFailed

    return (*errors, SweepFailed)


def _print_error(prog: str, message: object) -> int:
    """Print ``PROG: error: MESSAGE`` as one line on stderr; the usage exit status."""
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr, flush=True)
    return EXIT_USAGE


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); its exit status."""
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command_of(words))
    try:
        args, extra = parser.parse_known_args(words)
    except UsageError as err:
        return _print_error(err.prog, err)
    prog = f"{parser.prog} {args.command}"
    if extra:
        return _print_error(prog, f"unrecognized arguments: {' '.join(extra)}")
    command: Callable[[argparse.Namespace], int] = args.func
    try:
        return command(args)
    except _user_errors() as err:
        return _print_error(prog, err)
    except OSError as err:
        where = f": {err.filename}" if err.filename else ""
        return _print_error(prog, f"{err.strerror or err}{where}")
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
