"""The options several commands share (settings, plugins, a step budget, TensorBoard, a run
directory's policies and flags) and how a command reads them."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from evolution.cli.parsing import CliError, int_arg

if TYPE_CHECKING:
    from cyber_rodent.plugins import Plugin

NO_PROGRESS = "no progress output (a bar on a terminal, otherwise a line a minute on stderr)"


def add_setting_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        default=None,
        help="TOML or JSON file of settings, e.g. the output of `cyber-rodent config`",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="change one setting, e.g. --set survival.mate_distance=0.4 (repeatable; "
        "`cyber-rodent config` lists every key)",
    )


def add_plugin_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--plugin",
        action="append",
        metavar="MODULE_OR_FILE",
        default=[],
        help="load your code first: a module (mylab.controllers) or a .py file that registers "
        f"a controller, an input or a task when imported (repeatable); {what}",
    )


def add_max_steps(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-steps",
        type=int_arg("--max-steps"),
        default=None,
        help="stop a run after this many control steps in all, even if its generations are "
        "not complete: a budget for populations that may never complete one (agents that "
        "learn from zero die before they mate); resume keeps it (default: no budget)",
    )


def add_tensorboard(p: argparse.ArgumentParser, where: str) -> None:
    p.add_argument(
        "--tensorboard",
        default=None,
        metavar="DIR",
        help=f"write each generation's statistics and the population's weights to TensorBoard "
        f"as it closes, {where}; watch with `tensorboard --logdir DIR` (needs "
        "pip install 'cyber-rodent[monitor]'; results are unchanged)",
    )


def add_run_options(p: argparse.ArgumentParser) -> None:
    add_setting_options(p)
    p.add_argument(
        "--policies",
        default="trained",
        metavar="{trained,reactive,DIR}",
        help="basic behaviours: the shipped trained values, the reactive baseline, or a "
        "directory of values trained by train-behaviours (e.g. for another robot body)",
    )
    p.add_argument("--resume", action="store_true", help="continue the run(s) in --out")
    p.add_argument("--force", action="store_true", help="replace the run(s) in --out")
    p.add_argument("--no-progress", action="store_true", help=NO_PROGRESS)


def load_plugin(spec: str) -> Plugin:
    """Load one ``--plugin``; a plugin that cannot be found or fails is one line naming
    ``--plugin``."""
    from cyber_rodent.plugins import PluginError
    from cyber_rodent.plugins import load_plugin as load

    try:
        return load(spec)
    except PluginError as err:
        raise CliError(f"--plugin {err}") from None


def load_plugins(args: argparse.Namespace) -> tuple[Plugin, ...]:
    """Load every ``--plugin`` of the command line, in order (before any setting is read)."""
    return tuple(load_plugin(spec) for spec in args.plugin)


def read_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The settings of ``--config FILE`` then ``--set KEY=VALUE`` (later ones win)."""
    from evolution.runner import settings

    from_file = settings.load_config_file(args.config) if args.config else {}
    return settings.merge(from_file, settings.parse_set(args.set))
