"""Training: rewards by hand, reproducibility, resume, checkpoints, bad input, the CLI."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from behaviours.action_values import CorruptActionValuesError
from behaviours.definitions import load_values
from behaviours.episodes import (
    BehaviourEpisode,
    EpisodeConfig,
    coverage_cells,
    episode_rng,
    search_reward,
    shaping_reward,
)
from behaviours.inputs import FORAGE, MATE
from behaviours.sarsa import SarsaConfig
from behaviours.training import CheckpointError, TrainingConfig, train
from cyber_rodent.commands import command_index
from cyber_rodent.vision.types import BATTERY, FACE, LED


# --- rewards, by hand ---------------------------------------------------------------------------
def test_shaping_reward_hand_computed():
    # γ Φ(s') − Φ(s), Φ = −scale·d: 0.98·(−0.28) − (−0.30) = 0.0256.
    assert shaping_reward(0.98, 1.0, 0.30, 0.28) == pytest.approx(0.0256)
    # Losing sight of the pack (d → 1) from d = 0.2 with scale 2: 0.98·(−2) + 0.4 = −1.56.
    assert shaping_reward(0.98, 2.0, 0.2, 1.0) == pytest.approx(-1.56)


def test_search_reward_hand_computed():
    # 0.05 m forward at 0.5 m/s reference over 0.1 s: exactly 1; colliding costs the penalty.
    assert search_reward(0.05, False, 0.05, 1.0) == pytest.approx(1.0)
    assert search_reward(0.02, True, 0.05, 1.0) == pytest.approx(0.4 - 1.0)
    assert search_reward(0.2, False, 0.05, 1.0) == 1.0  # clipped
    assert search_reward(-0.2, True, 0.05, 0.5) == -1.5


def test_coverage_counts_distinct_cells():
    # Cells of 0.1 m from the field's corner (-1.15, -1.15): x = 0.0 and 0.04 share a cell.
    pos = np.array([[0.0, 0.0], [0.04, 0.0], [0.0, 0.06], [-1.15, -1.15]])
    assert coverage_cells(pos) == 3


def test_forage_episode_rewards_follow_the_formula():
    """In the physics world: every step's reward is the documented formula of the inputs."""
    cfg = EpisodeConfig()
    env = BehaviourEpisode("forage", cfg)
    states = env.reset(episode_rng(3, 0))
    assert env._frame.visible[0, BATTERY]  # start condition: a pack in view
    forward = np.array([command_index("forward")])
    d_before = states[0, 1]
    for _ in range(30):
        result = env.step(forward)
        d_after = 0.0 if result.terminal else result.states[0, 1]
        expected = cfg.gamma * -d_after + d_before - cfg.step_cost + (1.0 if result.terminal else 0)
        assert result.rewards[0] == pytest.approx(expected, abs=1e-12)
        if result.terminal:
            break
        d_before = result.states[0, 1]


def test_mate_episode_starts_in_view_and_rewards_both():
    env = BehaviourEpisode("mate")
    env.reset(episode_rng(0, 1))
    seen = env._frame.visible[:2, LED] | env._frame.visible[:2, FACE]
    assert seen.all() and env.world.led_on.all()
    result = env.step(np.array([command_index("stop"), command_index("stop")]))
    assert result.rewards.shape == (2,) and result.states.shape == (2, 2)


def test_episode_config_rejects_bad_values():
    with pytest.raises(ValueError, match="max_steps"):
        EpisodeConfig(max_steps=0)
    with pytest.raises(ValueError, match="step_cost"):
        EpisodeConfig(step_cost=-1.0)
    with pytest.raises(ValueError, match="episode.gamma"):
        TrainingConfig(sarsa=SarsaConfig(gamma=0.9), episode=EpisodeConfig(gamma=0.98))


# --- training -----------------------------------------------------------------------------------
def _quick(behaviour: str, episodes: int, out: Path, resume: bool = False, seed: int = 7):
    cfg = TrainingConfig(episode=EpisodeConfig(max_steps=25), checkpoint_every=2)
    return train(behaviour, episodes, seed, out, resume=resume, progress=False, config=cfg)


def test_same_seed_gives_bit_identical_values(tmp_path):
    a = _quick("forage", 6, tmp_path / "a")
    b = _quick("forage", 6, tmp_path / "b")
    assert np.abs(a.values.weights).sum() > 0  # it learned something
    assert np.array_equal(a.values.weights, b.values.weights)
    assert a.values.checksum == b.values.checksum
    c = _quick("forage", 6, tmp_path / "c", seed=8)
    assert not np.array_equal(a.values.weights, c.values.weights)


def test_resume_gives_the_uninterrupted_values(tmp_path):
    """Mate: two self-play learners on one table, each with its own exploration stream."""
    full = _quick("mate", 5, tmp_path / "full")
    _quick("mate", 3, tmp_path / "part")
    resumed = _quick("mate", 5, tmp_path / "part", resume=True)
    assert resumed.episodes_run == 2
    assert np.array_equal(full.values.weights, resumed.values.weights)
    assert np.array_equal(full.curve, resumed.curve)


def test_outputs_curve_and_loadable_values(tmp_path):
    result = _quick("search", 3, tmp_path)
    lines = result.curve_csv.read_text().splitlines()
    assert lines[0] == "episode,return,steps,success,contacts" and len(lines) == 4
    assert result.curve_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    values = load_values("search", tmp_path)
    assert values.metadata["episodes"] == 3 and values.metadata["seed"] == 7
    assert np.array_equal(values.weights, result.values.weights)
    assert not list(tmp_path.glob("*.tmp*"))


def test_resume_refuses_another_run_or_a_damaged_checkpoint(tmp_path):
    _quick("forage", 2, tmp_path)
    with pytest.raises(CheckpointError, match="seed"):
        _quick("forage", 3, tmp_path, resume=True, seed=99)
    ckpt = tmp_path / "forage_checkpoint.npz"
    data = bytearray(ckpt.read_bytes())
    data[len(data) // 2] ^= 0xFF
    ckpt.write_bytes(bytes(data))
    with pytest.raises(CheckpointError):
        _quick("forage", 3, tmp_path, resume=True)
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        _quick("forage", 3, tmp_path / "empty", resume=True)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(behaviour="dance", episodes=1), "behaviour: unknown behaviour 'dance'"),
        (dict(behaviour="forage", episodes=-5), "episodes"),
        (dict(behaviour="forage", episodes=0), "episodes"),
        (dict(behaviour="forage", episodes=2.5), "episodes"),
        (dict(behaviour="forage", episodes=1, seed=-1), "seed"),
    ],
)
def test_bad_training_input_is_a_clear_error(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        train(out_dir=tmp_path, progress=False, **kwargs)


def test_corrupt_values_file_is_a_clear_error(tmp_path):
    _quick("forage", 1, tmp_path)
    path = tmp_path / "forage.npz"
    raw = bytearray(path.read_bytes())
    raw[-200] ^= 0x01
    path.write_bytes(bytes(raw))
    with pytest.raises(CorruptActionValuesError):
        load_values("forage", tmp_path)
    with pytest.raises(FileNotFoundError, match="train-behaviours --behaviour mate"):
        load_values("mate", tmp_path)


# --- the command line -----------------------------------------------------------------------------
def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "evolution.cli", "train-behaviours", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ},
    )


def test_cli_trains_and_resumes(tmp_path):
    out = tmp_path / "run"
    args = ("--behaviour", "forage", "--seed", "3", "--out", str(out), "--no-progress")
    first = _cli(*args, "--episodes", "2")
    assert first.returncode == 0, first.stderr
    assert "forage: 2 episodes" in first.stdout
    for name in ("forage.npz", "forage_curve.csv", "forage_curve.png", "forage_checkpoint.npz"):
        assert (out / name).is_file()
    again = _cli(*args, "--episodes", "3", "--resume")
    assert again.returncode == 0, again.stderr
    assert "forage: 3 episodes (1 this run" in again.stdout
    assert load_values("forage", out).metadata["episodes"] == 3


@pytest.mark.parametrize(
    "args, message",
    [
        (("--behaviour", "dance"), "unknown behaviour 'dance'; allowed: mate, forage, search"),
        (("--behaviour", "forage", "--episodes", "-3"), "episodes: must be in [1,"),
        (("--episodes", "many"), "--episodes must be an integer"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(tmp_path, args, message):
    result = _cli(*args, "--out", str(tmp_path), "--no-progress")
    assert result.returncode == 2
    assert message in result.stderr and "Traceback" not in result.stderr
    assert not list(tmp_path.iterdir())  # failed before any work


def test_behaviour_indices_match_the_episode_worlds():
    assert BehaviourEpisode("mate").n_learners == 2 and MATE == 0
    assert BehaviourEpisode("forage").n_learners == 1 and FORAGE == 1
    assert math.isclose(BehaviourEpisode("forage").dt, 0.2)
