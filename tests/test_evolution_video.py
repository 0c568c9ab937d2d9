"""Videos of a run: an MP4 with the right number of frames, and clear errors."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from behaviours import BehaviourPolicies
from evolution.api import make_config
from evolution.runner import EvolutionRunner
from evolution.video import RunVideo, VideoConfig, render_video


@pytest.fixture(scope="module")
def runner() -> EvolutionRunner:
    config = make_config(
        "ee", n_robots=2, population_size=4, lifetime_steps=40, time_sharing_steps=20
    )
    r = EvolutionRunner(config, 0, BehaviourPolicies.reactive())
    for _ in range(30):
        r.step()
    return r


def test_render_video_writes_an_mp4_with_frames(runner, tmp_path) -> None:
    out = tmp_path / "run.mp4"
    steps_before = runner.steps
    render_video(runner, out, frames=6, config=VideoConfig(field_px=256), progress=False)
    assert runner.steps == steps_before + 6  # one control step per frame
    frames = iio.imread(out)
    assert frames.shape[0] == 6 and frames.shape[2] == 2 * 256 and frames.shape[3] == 3
    assert frames.std() > 10  # not blank
    assert not list(tmp_path.glob(".*"))  # the temporary file was renamed away


def test_frame_layout_and_content(runner) -> None:
    video = RunVideo(runner, VideoConfig(field_px=256))
    try:
        video.advance()
        frame = video.frame()
    finally:
        video.close()
    assert frame.shape == (video.height, 512, 3) and frame.dtype == np.uint8
    left, right = frame[:256, :256], frame[:, 256:]
    assert left.std() > 10 and right.std() > 10


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"fps": 0}, "fps"),
        ({"steps_per_frame": 0}, "steps_per_frame"),
        ({"field_px": 100}, "field_px"),
    ],
)
def test_bad_video_config(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        VideoConfig(**kwargs)


def test_bad_output_and_frames(runner, tmp_path) -> None:
    with pytest.raises(ValueError, match="mp4"):
        render_video(runner, tmp_path / "x.avi", frames=1, progress=False)
    with pytest.raises(ValueError, match="does not exist"):
        render_video(runner, tmp_path / "no" / "x.mp4", frames=1, progress=False)
    with pytest.raises(ValueError, match="frames"):
        render_video(runner, tmp_path / "x.mp4", frames=0, progress=False)
