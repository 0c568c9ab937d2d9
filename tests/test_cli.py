"""The command line: snapshot writes a PNG; bad input gives one clear line, no traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import pytest

from cyber_rodent.assets import ASSETS_ENV_VAR


def run_cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "evolution.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, **(env or {})},
    )


def test_snapshot_writes_a_png(tmp_path: Path) -> None:
    out = tmp_path / "field.png"
    result = run_cli("snapshot", "--out", str(out), "--seed", "3", "--size", "200")
    assert result.returncode == 0, result.stderr
    image = iio.imread(out)
    assert image.shape == (200, 200, 3)
    assert not list(tmp_path.glob(".*"))  # no temp file left behind


@pytest.mark.parametrize(
    "args, message",
    [
        (("--robots", "0"), "n_robots"),
        (("--robots", "-1"), "n_robots"),
        (("--robots", "1000"), "n_robots"),
        (("--packs", "-2"), "n_packs"),
        (("--robots", "many"), "--robots must be an integer"),
    ],
)
def test_snapshot_bad_counts(tmp_path: Path, args: tuple, message: str) -> None:
    out = tmp_path / "x.png"
    result = run_cli("snapshot", "--out", str(out), *args)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_snapshot_unwritable_out(tmp_path: Path) -> None:
    result = run_cli("snapshot", "--out", str(tmp_path / "missing" / "x.png"))
    assert result.returncode == 2 and "does not exist" in result.stderr
    assert "Traceback" not in result.stderr
    result = run_cli("snapshot", "--out", str(tmp_path))
    assert result.returncode == 2 and "is a directory" in result.stderr


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_snapshot_read_only_directory(tmp_path: Path) -> None:
    tmp_path.chmod(0o500)
    try:
        result = run_cli("snapshot", "--out", str(tmp_path / "x.png"))
    finally:
        tmp_path.chmod(0o700)
    assert result.returncode == 2 and "not writable" in result.stderr


def test_snapshot_missing_asset(tmp_path: Path) -> None:
    result = run_cli(
        "snapshot", "--out", str(tmp_path / "x.png"), env={ASSETS_ENV_VAR: str(tmp_path)}
    )
    assert result.returncode == 2
    assert "missing asset" in result.stderr and "Traceback" not in result.stderr


def test_help_shows_every_default() -> None:
    from evolution.cli import build_parser

    parser = build_parser()
    expected = {
        # the schemes are a registry plugins add to: named in the help, checked after loading
        "evolve": ["--method METHOD", "medea", "(default: ee)", "(default: 0)", "(default: 1)"],
        "sweep": ["(default: ee,ce)", "(default: 0-19)", "(default: 120)", "(default: CPU"],
        "transfer": ["(default: 40)", "(default: 5)", "(default: 3)", "(default: hardware)"],
        "resume": ["(default: the run's own)"],
        "config": ["(default: ee)"],
    }
    for command, fragments in expected.items():
        text = " ".join(parser.commands[command].format_help().split())
        for fragment in fragments:
            assert fragment in text, (command, fragment)
    assert "projected run time" in " ".join(parser.commands["sweep"].format_help().split())


def test_render_help_describes_every_option() -> None:
    """Every option of ``render`` has a help text; --fps says what plays in real time."""
    from evolution.cli import build_parser

    render = build_parser().commands["render"]
    bare = [a.option_strings[0] for a in render._actions if a.option_strings and not a.help]
    assert bare == []
    text = " ".join(render.format_help().split())
    assert "5 fps plays in real time" in text and "control steps simulated between" in text


def test_counts_read_in_the_singular_for_one() -> None:
    from evolution.cli.evolve import _count

    assert _count(1, "generation") == "1 generation"
    assert _count(0, "generation") == "0 generations"
    assert _count(12, "generation") == "12 generations"


def test_parser_errors_are_one_line_without_usage() -> None:
    result = run_cli("evolve", "--method", "xyz")
    assert result.returncode == 2
    # the schemes are a registry that plugins add to: checked after they are loaded
    from evolution.schemes import scheme_names

    assert result.stderr.splitlines() == [
        f"cyber-rodent evolve: error: method must be one of {', '.join(scheme_names())}, "
        "got 'xyz'"
    ]
    result = run_cli("evolve", "--seed", "abc", "--no-such-option")
    assert result.returncode == 2 and len(result.stderr.splitlines()) == 1
    assert "usage:" not in result.stderr


def test_a_rendered_task_closes_its_gl_context_at_exit() -> None:
    code = (
        "from cyber_rodent import tasks\n"
        "e = tasks.load('forage', seed=0, vision='rendered'); e.reset()\n"  # never closed
        "f = tasks.load('mate', seed=1, vision='rendered'); f.reset(); f.close(); f.close()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
        env={**os.environ, "MUJOCO_GL": "egl"},
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""


@pytest.mark.parametrize(
    "args, message",
    [
        (("--field-size", "0.2"), "field_size must be a number in [0.5, 50], got 0.2"),
        (("--field-size", "wide"), "--field-size must be a number"),
        # 100 robots and 125 packs need 7.58 m; the paper's 2.3 m field holds 16 packs.
        (("--robots", "100", "--packs", "125"), "need field_size >= 7.58 m"),
        (("--robots", "100", "--packs", "125", "--field-size", "7"), "field_size >= 7.58 m"),
    ],
)
def test_snapshot_bad_field(tmp_path: Path, args: tuple, message: str) -> None:
    out = tmp_path / "x.png"
    result = run_cli("snapshot", "--out", str(out), *args)
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr
    assert not out.exists()
