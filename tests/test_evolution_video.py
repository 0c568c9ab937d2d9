"""Videos of a run: an MP4 with the right number and size of frames, frames tiled with no dead
black areas in every layout, labels that never overlap, a legend, and clear errors."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent.render import boxes_intersect
from cyber_rodent.vision import CameraConfig
from evolution.lab.api import make_config
from evolution.lab.video import (
    MAX_HEIGHT,
    MAX_STRIPS,
    Camera,
    RunVideo,
    VideoConfig,
    check_camera_robot,
    frame_layout,
    legend_items,
    parse_camera,
    parse_integer_option,
    parse_size,
    render_video,
    start_checkpoint,
)
from evolution.runner import EvolutionRunner


@pytest.fixture(scope="module")
def runner() -> EvolutionRunner:
    config = make_config(
        "ee", n_robots=2, population_size=4, lifetime_steps=40, time_sharing_steps=20
    )
    r = EvolutionRunner(config, 0, BehaviourPolicies.reactive())
    for _ in range(30):
        r.step()
    return r


@pytest.fixture(scope="module")
def crowded() -> EvolutionRunner:
    """Four robots parked around one pack, a few cm from its ring, facing it."""
    config = make_config(
        "ee", n_robots=4, population_size=8, lifetime_steps=40, time_sharing_steps=20
    )
    r = EvolutionRunner(config, 1, BehaviourPolicies.reactive())
    world = r.world
    px, py = world.pack_positions()[0]
    for i in range(4):
        a = math.pi / 2 * i + 0.3
        world.set_robot_pose(i, px + 0.2 * math.cos(a), py + 0.2 * math.sin(a), a + math.pi)
    mujoco.mj_forward(world.model, world.data)
    return r


def longest_black_band(frame: np.ndarray, level: int = 16) -> int:
    """The most consecutive rows or columns whose every pixel is black (≤ ``level``)."""
    dark = frame.max(axis=2) <= level
    longest = 0
    for line in (dark.all(axis=1), dark.all(axis=0)):
        run = 0
        for black in line.tolist():
            run = run + 1 if black else 0
            longest = max(longest, run)
    return longest


def render_frame(runner: EvolutionRunner, config: VideoConfig) -> tuple[np.ndarray, RunVideo]:
    video = RunVideo(runner, config)
    try:
        return video.frame(), video
    finally:
        video.close()


def test_render_video_writes_an_mp4_with_frames(runner, tmp_path) -> None:
    out = tmp_path / "run.mp4"
    steps_before = runner.steps
    config = VideoConfig(width=736, height=480)
    render_video(runner, out, frames=6, config=config, progress=False)
    assert runner.steps == steps_before + 6  # one control step per frame
    frames = iio.imread(out)
    assert frames.shape == (6, 480, 736, 3)  # the size asked for
    assert frames.std() > 10  # not blank
    assert not list(tmp_path.glob(".*"))  # the temporary file was renamed away


def test_frame_layout_and_content(runner) -> None:
    video = RunVideo(runner, VideoConfig(width=736, height=480))
    try:
        video.advance()
        frame = video.frame()
    finally:
        video.close()
    assert frame.shape == (480, 736, 3) and frame.dtype == np.uint8
    field = video.layout.field
    left, right = frame[field.slices], frame[:, field.w :]
    assert field.x == 0 and field.w >= field.h == 480  # the whole field, never cropped
    assert left.std() > 10 and right.std() > 10


@pytest.mark.parametrize("camera", ["top", "chase:1", "omni:2"])
@pytest.mark.parametrize("size", [(736, 480), (1280, 720)])
def test_crowded_frame_labels_apart_legend_and_no_black_band(crowded, camera, size) -> None:
    width, height = size
    frame, video = render_frame(crowded, VideoConfig(width=width, height=height, camera=camera))
    assert frame.shape == (height, width, 3)
    # No dead black area anywhere (the field's surroundings, the sky, the column's end).
    assert longest_black_band(frame) <= 2
    # The four labels on the crowded pack: all drawn, none intersecting, inside the field.
    boxes = video.label_boxes
    assert boxes is not None and len(boxes) == 4
    field = video.layout.field
    assert (boxes[:, :2] >= 0).all() and (boxes[:, 2] <= field.w).all()
    assert (boxes[:, 3] <= field.h).all()
    for a, b in itertools.combinations(boxes.tolist(), 2):
        assert not boxes_intersect(a, b), (a, b)
    # The legend is drawn: light text on its dark panel.
    legend = frame[video.layout.legend.slices]
    assert (legend.min(axis=2) > 180).sum() > 200
    texts = [item.text for item in video.items]
    assert any("Mate" in t for t in texts) and any("mating" in t for t in texts)
    assert any("heading" in t for t in texts) and any("docked" in t for t in texts)
    assert any("followed" in t for t in texts) == (camera != "top")


@pytest.mark.parametrize("n_robots", [1, 2, 4, 12, 26])
@pytest.mark.parametrize("camera", ["top", "chase:0", "omni:0"])
@pytest.mark.parametrize("size", [(736, 480), (1280, 720), (1920, 1080), (3840, 720)])
def test_panels_tile_the_frame_exactly(n_robots, camera, size) -> None:
    width, height = size
    try:
        layout = frame_layout(width, height, parse_camera(camera), n_robots, CameraConfig())
    except ValueError as err:  # many robots' strips need a taller frame; the error says so
        assert camera == "top" and n_robots >= 12 and "at least" in str(err)
        return
    cover = np.zeros((height, width), dtype=np.int64)
    for rect in layout.panels:
        assert rect.w > 0 and rect.h > 0
        cover[rect.slices] += 1
    assert (cover == 1).all()  # every pixel in exactly one panel
    assert layout.field.w >= layout.field.h  # the top-down field is never cropped
    if camera == "top":
        assert layout.cell_robots == tuple(range(n_robots))


def test_a_large_colony_shows_the_first_strips_and_says_which() -> None:
    # No frame holds 100 robots' strips: the top layout shows the first MAX_STRIPS.
    for size in ((1280, 720), (1920, 1080)):
        layout = frame_layout(*size, Camera("top"), 100, CameraConfig())
        assert 1 <= len(layout.cells) <= MAX_STRIPS
        assert layout.cell_robots == tuple(range(len(layout.cells)))
        shown = layout.cell_robots
        note = f"strips: CR0-CR{shown[-1]} of 100"
        assert note in [item.text for item in legend_items(Camera("top"), shown, 100)]
    assert "of 4" not in str(legend_items(Camera("top"), (0, 1, 2, 3), 4))  # all shown


def test_too_many_robots_for_the_frame_says_the_size_needed() -> None:
    with pytest.raises(ValueError, match=r"--size 736x480 .* H must be at least \d+") as caught:
        frame_layout(736, 480, Camera("top"), 26, CameraConfig())
    suggested = str(caught.value).split("e.g. --size ")[1].rstrip(")")
    width, height = parse_size(suggested)
    assert height <= MAX_HEIGHT
    frame_layout(width, height, Camera("top"), 26, CameraConfig())  # fits
    with pytest.raises(ValueError, match="at least"):
        frame_layout(width, height - 2, Camera("top"), 26, CameraConfig())


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"fps": 0}, "fps"),
        ({"steps_per_frame": 0}, "steps_per_frame"),
        ({"width": 100}, "width"),
        ({"width": 800, "height": 600}, "--size"),
        ({"width": 1281}, "--size"),
        ({"camera": "side"}, "--camera"),
        ({"camera": "chase"}, "--camera"),
    ],
)
def test_bad_video_config(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        VideoConfig(**kwargs)


def test_camera_following_a_missing_robot(runner) -> None:
    with pytest.raises(ValueError, match=r"--camera chase:N needs a robot index N in \[0, 1\]"):
        RunVideo(runner, VideoConfig(camera="chase:2"))
    check_camera_robot(parse_camera("omni:1"), 2)
    assert parse_camera(" chase : 3 ") == Camera("chase", 3) and str(Camera("omni", 1)) == "omni:1"


@pytest.mark.parametrize("text", ["", "1280", "1280x", "x720", "1280x720x3", "-1280x720", "wide"])
def test_parse_size_rejects(text: str) -> None:
    with pytest.raises(ValueError, match=r"--size must be WxH .* H in \[480, 2160\]"):
        parse_size(text)


def test_parse_options() -> None:
    assert parse_size("1920x1080") == (1920, 1080) and parse_size(" 1024X768 ") == (1024, 768)
    assert parse_integer_option("--frames", "12", 1, 100) == 12
    with pytest.raises(ValueError, match=r"--frames must be an integer in \[1, 100\], got 'x'"):
        parse_integer_option("--frames", "x", 1, 100)
    with pytest.raises(ValueError, match=r"--start must be an integer in \[0, ∞\), got -1"):
        parse_integer_option("--start", "-1", 0, math.inf)


def test_start_checkpoint(tmp_path: Path) -> None:
    (tmp_path / "checkpoints").mkdir()
    for g in (3, 4, 5):
        (tmp_path / "checkpoints" / f"gen_{g:05d}.ckpt").write_bytes(b"")
    assert start_checkpoint(tmp_path, 4).name == "gen_00004.ckpt"
    with pytest.raises(ValueError, match=r"--start must be a generation .* in \[3, 5\], got 1"):
        start_checkpoint(tmp_path, 1)
    (tmp_path / "checkpoints" / "gen_00004.ckpt").unlink()
    with pytest.raises(ValueError, match=r"one of \[3, 5\]"):
        start_checkpoint(tmp_path, 4)
    with pytest.raises(ValueError, match="no checkpoint"):
        start_checkpoint(tmp_path / "checkpoints", 1)


def test_bad_output_and_frames(runner, tmp_path) -> None:
    with pytest.raises(ValueError, match="mp4"):
        render_video(runner, tmp_path / "x.avi", frames=1, progress=False)
    with pytest.raises(ValueError, match="does not exist"):
        render_video(runner, tmp_path / "no" / "x.mp4", frames=1, progress=False)
    with pytest.raises(ValueError, match="frames"):
        render_video(runner, tmp_path / "x.mp4", frames=0, progress=False)
    with pytest.raises(ValueError, match="--camera"):
        render_video(
            runner, tmp_path / "x.mp4", 1, VideoConfig(camera="omni:5"), progress=False
        )
    assert not list(tmp_path.iterdir())  # nothing created
