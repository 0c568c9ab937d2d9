"""``cyber-rodent config``: every setting, resolved, as commented TOML, and what each
``--plugin`` registered."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

from evolution.cli import options

if TYPE_CHECKING:
    from cyber_rodent.plugins import Plugin

HELP = "print every setting, resolved, as commented TOML (a valid --config file)"

#: What plugins may register, by the word ``config`` lists them with.
_REGISTRY_KINDS = ("controller", "input", "task", "scheme")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Print the resolved configuration (the paper's defaults, then --config, "
        "then --set) as TOML: each setting with its meaning, allowed range, unit and source."
    )
    parser.add_argument(
        "--method", default="ee", help="the scheme the config is for (ee, ce, medea, ...)"
    )
    options.add_plugin_option(parser, "lists what each one registered")
    options.add_setting_options(parser)


def run(args: argparse.Namespace) -> int:
    from evolution.lab.api import make_config
    from evolution.runner.settings import to_toml

    added: list[tuple[Plugin, dict[str, tuple[str, ...]]]] = []
    if args.plugin:
        before = _registered()
        for spec in args.plugin:
            plugin = options.load_plugin(spec)
            after = _registered()
            new = {kind: tuple(n for n in after[kind] if n not in before[kind]) for kind in after}
            added.append((plugin, new))
            before = after
    config = make_config(args.method, **options.read_settings(args))
    text = to_toml(config, method=args.method)
    if added:  # after the header: the file stays a valid --config file
        header, _, rest = text.partition("\n\n")
        text = f"{header}\n\n{_plugins_section(added)}\n{rest}"
    sys.stdout.write(text)
    return 0


def _registered() -> dict[str, tuple[str, ...]]:
    """The names in each registry plugins may add to, by :data:`_REGISTRY_KINDS`."""
    from cyber_rodent.tasks.spec import task_names
    from evolution.controllers import controller_names
    from evolution.input_kernels import available_inputs
    from evolution.schemes import scheme_names

    return {
        "controller": controller_names(),
        "input": tuple(row.name for row in available_inputs()),
        "task": task_names(),
        "scheme": scheme_names(),
    }


def _plugins_section(added: Sequence[tuple[Plugin, dict[str, tuple[str, ...]]]]) -> str:
    """The ``config`` listing of what each plugin registered, as TOML comments."""
    lines = [
        "# registered by plugins (a --config file names them, but does not load them: give the",
        "# same --plugin again wherever you use this file):",
    ]
    for plugin, names in added:
        found = [(kind, name) for kind in _REGISTRY_KINDS for name in names[kind]]
        if not found:
            lines.append(f"#   nothing registered by {plugin.name}")
        for kind, name in found:
            lines.append(f"#   {kind} {name}  (plugin {plugin.name})")
    return "\n".join(lines) + "\n"
