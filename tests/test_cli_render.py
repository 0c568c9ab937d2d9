"""`cyber-rodent render` options (--size, --camera, --start, --frames) and snapshot overlays:
bad values give exit status 2 and one line naming the option and its range, before any file is
created; good values give the video asked for."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import pytest


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "evolution.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
    )


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny 2-generation run of 4 robots that keeps every checkpoint."""
    out = tmp_path_factory.mktemp("render") / "run"
    result = run_cli(
        "evolve", "--generations", "2", "--out", str(out), "--keep-checkpoints", "0",
        "--policies", "reactive", "--no-progress",
        "--set", "evolution.population_size=8", "--set", "evolution.lifetime_steps=40",
        "--set", "evolution.time_sharing_steps=20",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return out


def tree(path: Path) -> list[str]:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


@pytest.mark.parametrize(
    "args, message",
    [
        (("--size", "100x100"), "--size must be WxH with even W and H, H in [480, 2160]"),
        (("--size", "1280x721"), "--size must be WxH"),
        (("--size", "700x600"), "W in [H + 256, 3840]"),
        (("--size", "big"), "--size must be WxH"),
        (("--camera", "chase:4"), "--camera chase:N needs a robot index N in [0, 3]"),
        (("--camera", "omni:9"), "--camera omni:N needs a robot index N in [0, 3]"),
        (("--camera", "side"), "--camera must be top, chase:N or omni:N"),
        (("--camera", "chase"), "--camera must be top, chase:N or omni:N"),
        (("--frames", "0"), "--frames must be an integer in [1, 100000]"),
        (("--frames", "many"), "--frames must be an integer in [1, 100000]"),
        (("--start", "9"), "--start must be a generation whose checkpoint"),
        (("--start", "-3"), "--start must be an integer in [0, ∞)"),
        (("--start", "x"), "--start must be an integer in [0, ∞)"),
    ],
)
def test_render_bad_option_one_line_before_any_file(
    run_dir: Path, tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    before = tree(run_dir)
    out = tmp_path / "video.mp4"
    result = run_cli("render", str(run_dir), "--out", str(out), "--no-progress", *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert message in lines[0] and "[" in lines[0], lines[0]
    assert "Traceback" not in result.stderr
    assert not out.exists() and not list(tmp_path.iterdir())  # nothing created
    assert tree(run_dir) == before


def test_render_start_range_is_the_kept_generations(run_dir: Path, tmp_path: Path) -> None:
    result = run_cli("render", str(run_dir), "--out", str(tmp_path / "v.mp4"), "--start", "9")
    assert result.returncode == 2
    assert "in [1, 2], got 9" in result.stderr
    checkpoint = run_dir / "checkpoints" / "gen_00001.ckpt"
    result = run_cli(
        "render", "--checkpoint", str(checkpoint), "--out", str(tmp_path / "v.mp4"), "--start", "1"
    )
    assert result.returncode == 2 and "--start" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_render_size_camera_start_frames(run_dir: Path, tmp_path: Path) -> None:
    before = tree(run_dir)
    out = tmp_path / "omni.mp4"
    result = run_cli(
        "render", str(run_dir), "--out", str(out), "--no-progress",
        "--size", "736x480", "--camera", "omni:1", "--start", "1", "--frames", "3",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    frames = iio.imread(out)
    assert frames.shape == (3, 480, 736, 3)
    dark = frames[0].max(axis=2) <= 16
    assert dark.all(axis=1).sum() <= 2 and dark.all(axis=0).sum() <= 2  # no black band
    assert tree(run_dir) == before  # the run directory is not modified


def test_snapshot_has_robot_ids_and_heading_arrows_unless_plain(tmp_path: Path) -> None:
    shown, plain = tmp_path / "shown.png", tmp_path / "plain.png"
    for path, extra in ((shown, ()), (plain, ("--plain",))):
        result = run_cli("snapshot", "--out", str(path), "--seed", "3", "--size", "320", *extra)
        assert result.returncode == 0, result.stderr
    a, b = iio.imread(shown), iio.imread(plain)
    assert a.shape == b.shape == (320, 320, 3)
    assert (~b.any(axis=2)).sum() > 100  # the bare render leaves empty space black
    assert not (~a.any(axis=2)).any()  # the annotated one paints it
    # Labels (light text in dark boxes) and arrows change a good share of the pixels.
    assert ((a != b).any(axis=2) & b.any(axis=2)).sum() > 400
