"""The parser every command shares: one-line errors with exit status 2, and each option's
default in ``--help``; the option types that name the option in their error."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from typing import Any, NoReturn, TypeVar

EXIT_USAGE = 2

T = TypeVar("T")


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class UsageError(CliError):
    """A malformed command line, found by the parser of ``prog`` (``cyber-rodent evolve``)."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(message)
        self.prog = prog


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Each option's default after its help, unless the help states it or there is none (a
    flag, an option unset by default)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if "default" in text or default is None or default is False or default == []:
            return text
        if default is argparse.SUPPRESS:
            return text
        return super()._get_help_string(action)


class CliParser(argparse.ArgumentParser):
    """The parser of the command and of each sub-command (``add_subparsers`` makes its
    sub-parsers of the parent's class): an error is one line, ``PROG: error: MESSAGE``, with
    exit status 2 and no usage block, and ``--help`` shows every default."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)
        #: The sub-commands' parsers by name (set by :func:`evolution.cli.app.build_parser`).
        self.commands: Mapping[str, argparse.ArgumentParser] = {}

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        """An option without help still shows its default in ``--help``."""
        if kwargs.get("help") is None and args and str(args[0]).startswith("-"):
            default = kwargs.get("default")
            if default is not None and default is not False and default != []:
                kwargs["help"] = "(default: %(default)s)"
        return super().add_argument(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


def one_line(text: object) -> str:
    """``text`` on one line (a message from a library may span several)."""
    return " ".join(str(text).split())


def int_arg(name: str) -> Callable[[str], int]:
    """The type of an integer option: its error names the option (``name``)."""
    return _option_type(name, int, "an integer")


def float_arg(name: str) -> Callable[[str], float]:
    """The type of a number option: its error names the option (``name``)."""
    return _option_type(name, float, "a number")


def _option_type(name: str, convert: Callable[[str], T], what: str) -> Callable[[str], T]:
    def parse(text: str) -> T:
        try:
            return convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be {what}, got {text!r}") from None

    return parse
