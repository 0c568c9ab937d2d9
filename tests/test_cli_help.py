"""Every command's ``--help`` is the text its users know, word for word.

``tests/cli_help/`` holds the help of the command (``cyber-rodent.txt``) and of each
sub-command (``evolve.txt``, ...) as printed 100 columns wide. Changing an option's text is
changing that file, on purpose and in the same commit; moving the code that prints it is not.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from evolution.cli import build_parser, main

HELP = Path(__file__).with_name("cli_help")
TOP = "cyber-rodent"
COMMANDS = sorted(p.stem for p in HELP.glob("*.txt") if p.stem != TOP)


def test_every_command_has_its_help_on_file() -> None:
    assert sorted(build_parser().commands) == COMMANDS


@pytest.mark.parametrize("command", [TOP, *COMMANDS])
def test_help_is_unchanged(
    command: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("COLUMNS", "100")
    argv = ["--help"] if command == TOP else [command, "--help"]
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 0
    assert capsys.readouterr().out == (HELP / f"{command}.txt").read_text()


def test_help_of_the_module_run_as_a_program() -> None:
    """``python -m`` prints the same text, under the program name ``cyber-rodent``."""
    result = subprocess.run(
        [sys.executable, "-m", "evolution.cli", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "COLUMNS": "100"},
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout == (HELP / f"{TOP}.txt").read_text()
