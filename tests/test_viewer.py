"""``cyber-rodent view`` (:mod:`evolution.lab.viewer`): the live viewer on a task and a checkpoint.

The window tests run the viewer in a subprocess (a GL crash cannot take pytest down) on a
virtual X display: an ``Xvfb`` started here on a free display number (``-displayfd``), with
``MUJOCO_GL=glfw``. They check the viewer's own ``--screenshot`` (read back from the X server,
:mod:`evolution.lab.window_capture`): the field is in it, every robot's body and the labels sit
where the viewer's camera puts them. The task test also reads Xvfb's framebuffer file
(``-fbdir``, XWD) while the viewer runs, an independent look at the screen, and compares it
with the screenshot. Without the ``Xvfb`` binary the window tests are skipped (CI installs it:
``.ci/system-deps.sh``); the other tests need no display.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import select
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

from evolution.lab import viewer
from evolution.lab.viewer import (
    MAX_PANEL_ROBOTS,
    OVERVIEW,
    Controls,
    Mirror,
    RobotStatus,
    Session,
    TaskSource,
    panel_texts,
)

#: The virtual screen; the viewer's window takes a part of it.
SCREEN = (1280, 800)
#: Wall seconds a viewer runs; at --speed 0.05 that is less than one control step, so the
#: robots are still where they started (within about one step's travel).
SECONDS = 4.0
SLOW = 0.05
ROBOT_TOP = 0.095  # m, top of the chassis


# --- the virtual display --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def x_display(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """An Xvfb display (``:N``) and its framebuffer file, for this module's tests."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("the Xvfb binary is missing (Debian package xvfb; .ci/system-deps.sh)")
    fbdir = tmp_path_factory.mktemp("xvfb")
    read_end, write_end = os.pipe()
    width, height = SCREEN
    server = subprocess.Popen(
        [xvfb, "-displayfd", str(write_end), "-screen", "0", f"{width}x{height}x24",
         "-fbdir", str(fbdir), "-nolisten", "tcp"],
        pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    os.close(write_end)
    try:
        ready, _, _ = select.select([read_end], [], [], 30.0)
        number = os.read(read_end, 64).decode().strip() if ready else ""
        if not number:
            pytest.fail("Xvfb did not report a display number within 30 s")
        yield f":{number}", fbdir / "Xvfb_screen0"
    finally:
        os.close(read_end)
        server.terminate()
        server.wait(timeout=10)


def viewer_env(display: str | None) -> dict[str, str]:
    """The viewer's environment: GLFW on ``display``; without one, MUJOCO_GL unset (a user's
    default; with MUJOCO_GL=glfw and no display, importing dm-control makes GLFW warn)."""
    env = dict(os.environ, LP_NUM_THREADS="1")
    for name in ("DISPLAY", "MUJOCO_GL"):
        env.pop(name, None)
    if display is not None:
        env.update(DISPLAY=display, MUJOCO_GL="glfw")
    return env


@contextmanager
def viewer_process(display: str, *args: str) -> Iterator[subprocess.Popen[str]]:
    process = subprocess.Popen(
        [sys.executable, "-m", "evolution.lab.viewer", *args],
        env=viewer_env(display), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        yield process
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def read_xwd(path: Path) -> np.ndarray:
    """Xvfb's screen file (XWD, 24-bit TrueColor in 32-bit pixels) as (h, w, 3) uint8 RGB."""
    raw = path.read_bytes()
    header = np.frombuffer(raw[:100], dtype=">u4")
    size, width, height = int(header[0]), int(header[4]), int(header[5])
    byte_order, bits, line = int(header[7]), int(header[11]), int(header[12])
    masks, colours = header[14:17], int(header[19])
    assert bits == 32, f"unexpected XWD pixel size {bits}"
    start = size + 12 * colours
    dtype = ">u4" if byte_order else "<u4"
    pixels = np.frombuffer(raw, dtype=dtype, count=height * line // 4, offset=start)
    pixels = pixels.reshape(height, line // 4)[:, :width]
    channels = []
    for mask in masks:
        shift = (int(mask) & -int(mask)).bit_length() - 1
        channels.append(((pixels >> shift) & 0xFF).astype(np.uint8))
    return np.stack(channels, axis=-1)


# --- what a screenshot must show ------------------------------------------------------------------
def robot_pixels(image: np.ndarray, xy: np.ndarray, half: int = 12) -> dict[str, int]:
    """Pixel counts around a robot's projected chassis top: its body (light, bluish grey,
    0.78 0.78 0.80 lit; the walls are warm, the floor darker) and its lit LED (green)."""
    x, y = (int(round(v)) for v in xy)
    patch = image[max(y - half, 0) : y + half + 1, max(x - half, 0) : x + half + 1]
    patch = patch.astype(np.int64)
    r, g, b = patch[..., 0], patch[..., 1], patch[..., 2]
    body = (patch.min(axis=-1) >= 200) & (b >= r) & (b - r <= 20) & (abs(r - g) <= 4)
    led = (g >= 200) & (r <= 50) & (b <= 50)
    return {"body": int(body.sum()), "led": int(led.sum()), "area": int(r.size)}


def label_pixels(image: np.ndarray, xy: np.ndarray) -> int:
    """White text pixels (labels are white with a black shadow) around a label's anchor."""
    x, y = (int(round(v)) for v in xy)
    patch = image[max(y - 25, 0) : y + 12, max(x - 70, 0) : x + 70]
    return int((patch == 255).all(axis=-1).sum())


def floor_share(image: np.ndarray) -> float:
    """Share of pixels of the field's floor: neutral mid grey (0.55 lit)."""
    flat = image.astype(np.int64)
    floor = (np.ptp(flat, axis=-1) <= 4) & (flat[..., 0] >= 140) & (flat[..., 0] <= 190)
    return float(floor.mean())


def check_screenshot(image: np.ndarray, poses: np.ndarray, leds: bool) -> None:
    height, width, _ = image.shape
    assert width >= 400 and height >= 300, image.shape
    assert width <= SCREEN[0] and height <= SCREEN[1]
    # Not blank: many colours, and the field's grey floor fills a good part of the window.
    assert image.std() > 20
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50
    floor = floor_share(image)
    assert floor > 0.15, f"the floor covers {floor:.0%} of the window"
    fovy = 45.0  # the arena's <visual> keeps MuJoCo's default
    n = len(poses)

    def at_height(z: float) -> np.ndarray:
        points = np.column_stack([poses[:, :2], np.full(n, z)])
        return OVERVIEW.project(points, width, height, fovy)

    tops, labels = at_height(ROBOT_TOP), at_height(viewer.LABEL_HEIGHT)
    for i in range(n):
        counts = robot_pixels(image, tops[i])
        assert counts["body"] >= 0.3 * counts["area"], f"robot {i}: {counts} at {tops[i]}"
        if leds:
            assert counts["led"] >= 3, f"robot {i}'s LED: {counts} at {tops[i]}"
        assert label_pixels(image, labels[i]) >= 15, f"robot {i}'s label near {labels[i]}"


# --- the window -----------------------------------------------------------------------------------
def test_view_task_shows_field_robots_and_labels(
    x_display: tuple[str, Path], tmp_path: Path
) -> None:
    from cyber_rodent import tasks

    display, framebuffer = x_display
    shot = tmp_path / "mate.png"
    env = tasks.load("mate", seed=3)
    env.reset()
    poses = env.task.world.poses()
    args = ["--task", "mate", "--seed", "3", "--speed", str(SLOW), "--seconds", str(SECONDS),
            "--screenshot", str(shot)]  # fmt: skip
    screen = None
    with viewer_process(display, *args) as process:
        # Meanwhile, Xvfb's own framebuffer: wait for the window to show the field.
        deadline = time.monotonic() + 90
        while process.poll() is None and time.monotonic() < deadline:
            frame = read_xwd(framebuffer)
            if floor_share(frame) > 0.05 and (frame[..., 1] >= 200).any():
                time.sleep(1.0)
                screen = read_xwd(framebuffer)
                break
            time.sleep(0.2)
        out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err
    assert f"wrote {shot}" in out
    image = iio.imread(shot)
    assert image.ndim == 3 and image.shape[2] == 3
    check_screenshot(image, poses, leds=True)  # both robots run Mate: LEDs on
    # The screenshot is what the screen showed (the window sits at the top left under Xvfb,
    # which has no window manager); robots barely move at this speed, the panel's time does.
    assert screen is not None, "the framebuffer never showed the window"
    h, w, _ = image.shape
    same = (np.abs(screen[:h, :w].astype(np.int64) - image).max(axis=-1) <= 8).mean()
    assert same > 0.9, f"screenshot and framebuffer agree on {same:.0%} of the window"


def test_view_checkpoint_shows_every_robot(x_display: tuple[str, Path], tmp_path: Path) -> None:
    from evolution.runner import EvolutionRunner, RunConfig

    display, _ = x_display
    with EvolutionRunner(RunConfig(), seed=0) as runner:
        for _ in range(3):
            runner.step()
        checkpoint = runner.save_checkpoint(tmp_path / "gen_00000.ckpt")
        poses = runner.world.poses()
    shot = tmp_path / "run.png"
    args = ["--checkpoint", str(checkpoint), "--speed", str(SLOW), "--seconds", str(SECONDS),
            "--screenshot", str(shot)]  # fmt: skip
    with viewer_process(display, *args) as process:
        out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err
    check_screenshot(iio.imread(shot), poses, leds=False)


# --- bad input: one line, status 2, nothing created -----------------------------------------------
def parse(*argv: str) -> argparse.Namespace:
    return viewer.build_parser().parse_args(list(argv))


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        ((), "RUN_DIR"),
        (("--task", "forage", "--checkpoint", "x.ckpt"), "RUN_DIR"),
        (("--task", "fly"), "--task"),
        (("--task", "forage", "--seconds", "-1"), "--seconds"),
        (("--task", "forage", "--seconds", "nan"), "--seconds"),
        (("--task", "forage", "--speed", "0"), "--speed"),
        (("--task", "forage", "--speed", "1000"), "--speed"),
        (("--task", "forage", "--seed", "-3"), "--seed"),
        (("--checkpoint", "x.ckpt", "--seed", "1"), "--seed"),
        (("--task", "forage", "--screenshot", "a.png"), "--screenshot"),
        (("--task", "forage", "--seconds", "1", "--screenshot", "a.jpg"), "--screenshot"),
        (("--task", "forage", "--seconds", "1", "--screenshot", "/no/such/dir/a.png"),
         "--screenshot"),
        (("/no/such/run",), "RUN_DIR"),
        (("--checkpoint", "/no/such.ckpt"), "--checkpoint"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_status_2(
    argv: tuple[str, ...], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert viewer.run(parse(*argv)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err, err
    assert "Traceback" not in err


def test_bad_run_directories_and_checkpoints(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "empty").mkdir()
    garbage = tmp_path / "garbage.ckpt"
    garbage.write_bytes(b"not a checkpoint")
    run_dir = tmp_path / "run"
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "run.json").write_text(json.dumps({"policies": "x"}))
    for argv, named in [
        ((str(tmp_path / "empty"),), "run directory"),  # no run.json
        ((str(run_dir),), "checkpoint"),  # a run without a checkpoint yet
        (("--checkpoint", str(garbage)), "--checkpoint"),
    ]:
        assert viewer.run(parse(*argv)) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and named in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "garbage.ckpt", "run"]


def test_no_display_fails_in_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    assert viewer.run(parse("--task", "forage")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "DISPLAY" in err and "xvfb-run" in err, err
    monkeypatch.setenv("DISPLAY", ":65000")  # nothing answers there
    assert viewer.run(parse("--task", "forage", "--seconds", "1")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot open the X display" in err, err


def test_no_display_from_the_command_line() -> None:
    """The whole program: no traceback, one line, status 2."""
    result = subprocess.run(
        [sys.executable, "-m", "evolution.lab.viewer", "--task", "survival", "--seconds", "2"],
        env=viewer_env(None), capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "DISPLAY" in result.stderr, result.stderr


def test_run_directory_resolves_to_its_newest_checkpoint(
    x_display: tuple[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from evolution.runner import EvolutionRunner, RunConfig, policy_identity

    display, _ = x_display
    monkeypatch.setenv("DISPLAY", display)
    run_dir = tmp_path / "run"
    (run_dir / "checkpoints").mkdir(parents=True)
    with EvolutionRunner(RunConfig(), seed=0) as runner:
        runner.save_checkpoint(run_dir / "checkpoints" / "gen_00001.ckpt")
        runner.step()
        runner.save_checkpoint(run_dir / "checkpoints" / "gen_00002.ckpt")
        identity = policy_identity(runner.policies)
    (run_dir / "run.json").write_text(json.dumps({"policies": identity}))
    chosen = viewer.plan(parse(str(run_dir)))
    assert chosen.checkpoint == run_dir / "checkpoints" / "gen_00002.ckpt"
    assert chosen.policies is not None and policy_identity(chosen.policies) == identity
    assert chosen.task is None


# --- the loop without a window --------------------------------------------------------------------
class FakeHandle:
    """Stands in for ``mujoco.viewer.Handle``: records what the viewer hands it."""

    def __init__(self, model: Any) -> None:
        self.user_scn = mujoco.MjvScene(model, maxgeom=200)
        self.texts: list[Any] = []
        self.syncs = 0
        self.running = True
        self.cam = mujoco.MjvCamera()  # a free camera, as the viewer opens it
        self.cam.lookat[:] = OVERVIEW.lookat
        self.cam.distance, self.cam.azimuth = OVERVIEW.distance, OVERVIEW.azimuth
        self.cam.elevation = OVERVIEW.elevation
        self.viewport = mujoco.MjrRect(0, 0, SCREEN[0], SCREEN[1])

    def is_running(self) -> bool:
        return self.running

    @contextmanager
    def lock(self) -> Iterator[None]:
        yield

    def set_texts(self, texts: list[Any]) -> None:
        self.texts = texts

    def sync(self) -> None:
        self.syncs += 1

    def close(self) -> None:
        self.running = False


class CountingTask(TaskSource):
    def __init__(self) -> None:
        from behaviours import BehaviourPolicies

        super().__init__("forage", 0, BehaviourPolicies.load_default())
        self.steps = 0

    def step(self) -> bool:
        self.steps += 1
        return super().step()


def test_loop_paces_steps_to_the_clock_and_obeys_the_keys() -> None:
    source = CountingTask()
    mirror = Mirror(source.world)
    handle = FakeHandle(mirror.model)
    controls = Controls(speed=1.0)
    session = Session(source, mirror, handle, controls, threads=[])
    dt = source.survival.config.control_dt
    assert session.watch(seconds=2.5 * dt) is True
    # One step at once, then one per control_dt of wall time: 3 in 2.5 dt (fewer if slow).
    assert 1 <= source.steps <= 3
    assert handle.syncs > source.steps
    # Labels and bars: three geoms per robot, the label naming robot, behaviour and energy.
    n = source.world.config.n_robots
    assert handle.user_scn.ngeom == 3 * n
    assert handle.user_scn.geoms[0].label.startswith("CR0 Forage ")
    about, robots = handle.texts[0][2:], handle.texts[1][2:]
    assert "task forage (seed 0)" in about[1] and "1x" in about[1]
    assert robots[0].startswith("CR0") and "Forage" in robots[1]
    # Paused: no steps; the right arrow makes exactly one.
    controls.on_key(viewer.KEY_SPACE)
    steps = source.steps
    session.watch(seconds=2 * dt)
    assert source.steps == steps
    controls.on_key(viewer.KEY_RIGHT)
    session.watch(seconds=2 * dt)
    assert source.steps == steps + 1 and controls.paused
    assert "PAUSED" in handle.texts[0][3]
    # A closed window ends the loop.
    handle.running = False
    assert session.watch(seconds=None) is False
    source.close()


class FakeClock:
    """Wall time that passes only when the loop sleeps or the test says so."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += max(0.0, seconds)


def run_with_fake_clock(
    speed: float, seconds: float, stall_at: float | None = None, stall: float = 0.0
) -> list[int]:
    """Watch a forage task for ``seconds`` of fake wall time, each frame costing 4 ms, with one
    ``stall`` (s) in the first frame after ``stall_at``. Returns the control steps taken in
    each frame."""
    source = CountingTask()
    assert source.survival.config.control_dt == 0.2
    mirror = Mirror(source.world)
    handle = FakeHandle(mirror.model)
    clock = FakeClock()
    loop = Session(
        source, mirror, handle, Controls(speed), threads=[], clock=clock, sleep=clock.sleep
    )
    per_frame: list[int] = []
    shown = [0]
    stalled = [stall_at is None]
    present = loop.present

    def timed_present(fraction: float) -> None:
        present(fraction)
        per_frame.append(source.steps - shown[0])
        shown[0] = source.steps
        clock.now += 0.004
        if not stalled[0] and clock.now >= stall_at:
            clock.now += stall
            stalled[0] = True

    loop.present = timed_present  # type: ignore[method-assign]
    assert loop.watch(seconds=seconds) is True
    source.close()
    return per_frame


def test_pacing_follows_the_clock_and_does_not_catch_up_after_a_stall() -> None:
    # Steady: one control step per 0.2 s of wall time (the first at once), one a frame at most.
    steps = run_with_fake_clock(speed=1.0, seconds=4.0)
    assert sum(steps) in (20, 21) and max(steps) == 1
    # A 3 s stall after 1 s: the 3 s are lost, not fast-forwarded (4 s of wall time hold only
    # 1 s of simulation), and no frame takes more than one step.
    steps = run_with_fake_clock(speed=1.0, seconds=4.0, stall_at=1.0, stall=3.0)
    assert sum(steps) in (6, 7) and max(steps) == 1, steps
    # Faster: 4x takes 4 steps per 0.2 s of wall time, still without a burst after a stall.
    steps = run_with_fake_clock(speed=4.0, seconds=2.0)
    assert 38 <= sum(steps) <= 41
    steps = run_with_fake_clock(speed=4.0, seconds=2.0, stall_at=1.0, stall=5.0)
    assert 19 <= sum(steps) <= 22 and max(steps) <= 2, steps


def test_pacer_re_anchors_after_a_stall() -> None:
    pacer = viewer.Pacer(dt=0.2)
    assert pacer.due(0.0, speed=1.0) == 1  # the first step at once
    assert pacer.taken(1) == 0.0
    assert pacer.due(0.1, speed=1.0) == 0 and pacer.progress == pytest.approx(0.5)
    # A 10 s gap counts as MAX_FRAME_GAP of wall time: at most what one slow frame is due.
    assert pacer.due(10.0, speed=1.0) == int(0.5 + viewer.MAX_FRAME_GAP / 0.2)
    # Steps not taken in time (the step budget ran out) are dropped, not owed.
    pacer.progress = 0.0
    assert pacer.due(viewer.MAX_FRAME_GAP, speed=100.0) == 50
    assert pacer.taken(3) == 1.0 and pacer.due(0.0, speed=100.0) == 1
    assert pacer.single_step() == 1.0


def test_bar_sits_under_its_label_at_any_camera() -> None:
    """The energy bar lies under the label's text, left-aligned, BAR_GAP_PX below its
    baseline and horizontal on the screen, whatever the zoom or the camera's angle."""
    source = CountingTask()
    mirror = Mirror(source.world)
    handle = FakeHandle(mirror.model)
    loop = Session(source, mirror, handle, Controls(1.0), threads=[])
    robots = source.robots()
    centres = mirror.data.xpos[source.world.chassis_body]
    for distance, azimuth, elevation in [(3.6, 90, -60), (8.0, 30, -20), (1.5, 200, -89)]:
        handle.cam.distance, handle.cam.azimuth = distance, azimuth
        handle.cam.elevation = elevation
        screen = loop.screen()
        viewer.decorate(handle.user_scn, centres, robots, 200.0, screen)
        geoms = handle.user_scn.geoms
        for i in range(len(robots)):
            label, frame, bar = geoms[3 * i], geoms[3 * i + 1], geoms[3 * i + 2]
            anchor = np.array(label.pos)
            px = screen.pixel(anchor)
            rel = (np.array(frame.pos) - anchor) / px
            mat = np.array(frame.mat).reshape(3, 3)
            half_x, half_y = frame.size[0] / px, frame.size[1] / px
            # The bar's axes are the screen's right and up.
            np.testing.assert_allclose(mat[:, 0], screen.right, atol=1e-6)
            np.testing.assert_allclose(mat[:, 1], screen.up, atol=1e-6)
            # Left end at the text's start (within the frame's pixel), top under the baseline.
            assert rel @ screen.right - half_x == pytest.approx(-1.0, abs=0.01)
            top = rel @ screen.up + half_y
            assert top == pytest.approx(-viewer.BAR_GAP_PX + 1.0, abs=0.01)
            # The energy fill lies within the frame, from its left end.
            fill = (np.array(bar.pos) - anchor) / px
            assert fill @ screen.right - bar.size[0] / px == pytest.approx(0.0, abs=0.01)
            assert bar.size[0] / px <= viewer.BAR_LENGTH_PX / 2 + 1e-6
    source.close()


def test_labels_of_robots_close_on_the_screen_are_lifted_apart() -> None:
    anchors = np.array([[0.0, 0.0], [12.0, 4.0], [-30.0, 9.0], [40.0, 2.0], [400.0, 1.0]])
    texts = ["CR0 Recharge 172", "CR1 Mate 90", "CR2 Forage 5", "CR3 Search 200", "CR4 Dead 0"]
    lifts = viewer.label_lifts(anchors, texts)
    assert lifts[0] == 0.0 and lifts[4] == 0.0  # the lowest one, and one far to the side
    assert (lifts >= 0).all() and lifts[1:4].min() > 0
    below = viewer.BAR_GAP_PX + viewer.BAR_THICKNESS_PX + 1.0
    boxes = [
        (x, y + lift - below, x + max(viewer.LABEL_CHAR_PX * len(t), viewer.BAR_LENGTH_PX),
         y + lift + viewer.LABEL_TOP_PX)
        for (x, y), lift, t in zip(anchors, lifts, texts, strict=True)
    ]  # fmt: skip
    for a, b in itertools.combinations(boxes, 2):
        apart = a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
        assert apart, (a, b)


def test_labels_of_a_large_colony_stay_on_their_robots() -> None:
    """Up to MAX_LIFTED_LABELS robots labels are lifted apart; beyond, they stay (lifting 100
    labels of robots a few pixels apart would stack towers taller than any window)."""
    n = viewer.MAX_LIFTED_LABELS
    rows = np.stack([np.zeros(n + 1), np.arange(n + 1) * 2.0], axis=1)  # a tight column
    texts = [f"CR{i} Search 100" for i in range(n + 1)]
    assert viewer.label_lifts(rows[:n], texts[:n])[1:].min() > 0
    np.testing.assert_array_equal(viewer.label_lifts(rows, texts), np.zeros(n + 1))


def test_mirror_glides_between_steps_and_leaves_the_world_alone() -> None:
    source = CountingTask()
    mirror = Mirror(source.world)
    live = source.world
    root = slice(int(live.root_qpos_adr[0]), int(live.root_qpos_adr[0]) + 2)  # robot 0's x, y
    before = live.data.qpos.copy()
    source.step()
    mirror.follow(jumped=False)
    after = live.data.qpos.copy()
    assert np.abs(after - before).max() > 1e-2  # it moved (wheels turned)
    mirror.show(0.0)
    np.testing.assert_allclose(mirror.data.qpos, before, atol=1e-12)
    mirror.show(1.0)
    np.testing.assert_allclose(mirror.data.qpos, after, atol=1e-9)
    mirror.show(0.5)
    np.testing.assert_allclose(mirror.data.qpos[root], (before[root] + after[root]) / 2)
    np.testing.assert_array_equal(live.data.qpos, after)  # the live world is untouched
    assert mirror.model is not live.model and mirror.data is not live.data
    # A new episode is shown at once, not glided to.
    source.env.reset()
    mirror.follow(jumped=True)
    mirror.show(0.0)
    np.testing.assert_array_equal(mirror.data.qpos, live.data.qpos)
    source.close()


def test_keys_change_speed_within_limits() -> None:
    controls = Controls(speed=1.0)
    controls.on_key(viewer.KEY_EQUAL)
    controls.on_key(viewer.KEY_KP_ADD)
    assert controls.speed == 4.0
    for _ in range(20):
        controls.on_key(viewer.KEY_MINUS)
    assert controls.speed == viewer.MIN_SPEED
    for _ in range(30):
        controls.on_key(viewer.KEY_EQUAL)
    assert controls.speed == viewer.MAX_SPEED
    controls.on_key(ord("A"))  # the viewer's own keys are left to it
    assert not controls.paused and not controls.take_step()


def test_help_names_every_task() -> None:
    from cyber_rodent.tasks import TASK_NAMES

    assert viewer.TASK_HELP_NAMES == ", ".join(TASK_NAMES)


def test_survival_choice_rule() -> None:
    from behaviours.inputs import FORAGE, MATE, SEARCH, BehaviourInputs

    n = 6
    inputs = BehaviourInputs(
        mate=np.full((n, 2), 0.5), forage=np.full((n, 2), 0.5), search=np.zeros((n, 2)),
        mate_available=np.array([True, True, False, False, True, False]),
        forage_available=np.array([True, True, True, False, False, False]),
    )  # fmt: skip
    energy = np.array([150.0, 50.0, 50.0, 150.0, 100.0, 10.0])
    docked = np.array([False, False, False, False, False, True])
    choice = viewer.survival_choice(inputs, energy, docked, max_energy=200.0)
    assert choice.tolist() == [MATE, FORAGE, FORAGE, SEARCH, MATE, viewer.RECHARGING]


def test_robot_panel_lists_a_large_colony_in_a_bounded_number_of_lines() -> None:
    def robots(n: int) -> list[RobotStatus]:
        return [RobotStatus(f"CR{i}", "Search", (255, 255, 255), 90.0) for i in range(n)]

    _, (names, _) = panel_texts([], robots(100), 0.0, Controls(1.0))
    assert len(names.splitlines()) == MAX_PANEL_ROBOTS + 1
    _, (names, values) = panel_texts([], robots(4), 0.0, Controls(1.0))
    assert names.splitlines() == ["CR0", "CR1", "CR2", "CR3"]  # the paper's colony: unchanged
    assert "more" not in values
    _, (_, values) = panel_texts([], robots(100), 0.0, Controls(1.0))
    assert values.splitlines()[-1] == f"and {100 - MAX_PANEL_ROBOTS} more"
