"""Training under an evolution run's survival rules: episodes, checkpoints, values, the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from behaviours.definitions import load_values
from behaviours.episodes import BehaviourEpisode, EpisodeConfig, episode_rng, search_reward
from behaviours.training import (
    CheckpointError,
    TrainingConfig,
    TrainingResult,
    survival_changes,
    train,
)
from cyber_rodent.commands import command_index
from cyber_rodent.survival import SurvivalConfig
from evolution.cli import main

#: IR port: 11.1 cm ahead of the robot's centre, 2 cm to its right (cyber_rodent.xml).
PORT_FORWARD = 0.111


def _quick(
    out: Path,
    survival: SurvivalConfig | None = None,
    episodes: int = 2,
    resume: bool = False,
    seed: int = 7,
) -> TrainingResult:
    cfg = TrainingConfig(episode=EpisodeConfig(max_steps=25), checkpoint_every=2)
    return train(
        "forage", episodes, seed, out, resume=resume, progress=False, config=cfg,
        survival=survival,
    )  # fmt: skip


# --- episodes -----------------------------------------------------------------------------------
def test_a_longer_control_step_runs_more_substeps_and_scales_search_reward() -> None:
    env = BehaviourEpisode("search", survival=SurvivalConfig(control_dt=0.2))
    # 0.2 s of 1/120 s physics timesteps: 24 substeps (12 at the default 0.1 s).
    assert env.world.model.opt.timestep == pytest.approx(1 / 120)
    assert env.survival.n_substeps == 24 and env.dt == 0.2
    assert env.survival.config.control_dt == 0.2
    assert env.survival.config.initial_energy == env.survival.config.max_energy == 1e6
    env.reset(episode_rng(0, 0))
    slow = np.array([command_index("forward_slow")])  # 0.2 m/s: at most 0.04 m per 0.2 s step
    for _ in range(3):
        x0, y0, yaw0 = env.world.poses()[0]
        t0 = env.world.time
        result = env.step(slow)
        assert env.world.time - t0 == pytest.approx(0.2)
        x1, y1, _ = env.world.poses()[0]
        progress = (x1 - x0) * math.cos(yaw0) + (y1 - y0) * math.sin(yaw0)
        assert 0.02 < progress < 0.05  # so 0.1 m and 0.05 m give different, unclipped rewards
        # The reference step is 0.5 m/s x 0.2 s = 0.1 m, not the default 0.05 m.
        expected = search_reward(progress, bool(result.collided[0]), 0.1, 3.0)
        assert result.rewards[0] == pytest.approx(expected, abs=1e-12)


def _facing_mate_episode(survival: SurvivalConfig | None) -> BehaviourEpisode:
    """A Mate episode with the two robots' IR ports facing each other 0.3 m apart."""
    env = BehaviourEpisode("mate", survival=survival)
    env.reset(episode_rng(0, 0))
    along = math.sqrt(0.3**2 - 0.04**2) + 2 * PORT_FORWARD
    env.world.set_robot_pose(0, -along / 2, 0.0, 0.0)
    env.world.set_robot_pose(1, along / 2, 0.0, math.pi)
    mujoco.mj_forward(env.world.model, env.world.data)
    return env


@pytest.mark.parametrize("consecutive, succeeds_at", [(1, 1), (2, 2)])
def test_mate_success_needs_the_rules_consecutive_steps(consecutive: int, succeeds_at: int) -> None:
    env = _facing_mate_episode(SurvivalConfig(mate_consecutive_steps=consecutive))
    stop = np.full(2, command_index("stop"))
    terminal = [env.step(stop).terminal for _ in range(succeeds_at)]
    assert terminal == [False] * (succeeds_at - 1) + [True]


def test_episode_rules_keep_endless_energy_and_refuse_other_types() -> None:
    env = BehaviourEpisode("forage", survival=SurvivalConfig(initial_energy=5.0, max_energy=10.0))
    assert env.survival.config.initial_energy == env.survival.config.max_energy == 1e6
    assert env.survival.n_substeps == 24 and env.dt == 0.2  # the default control step
    with pytest.raises(ValueError, match="survival: must be a SurvivalConfig"):
        BehaviourEpisode("forage", survival={"control_dt": 0.2})  # type: ignore[arg-type]


def test_survival_changes_leave_out_energy() -> None:
    assert survival_changes(None) == {} == survival_changes(SurvivalConfig())
    changed = SurvivalConfig(control_dt=0.1, initial_energy=50.0, mate_consecutive_steps=3)
    assert survival_changes(changed) == {"control_dt": 0.1, "mate_consecutive_steps": 3}


# --- training -----------------------------------------------------------------------------------
def test_the_papers_rules_train_exactly_as_without_rules(tmp_path: Path) -> None:
    plain = _quick(tmp_path / "plain")
    paper = _quick(tmp_path / "paper", survival=SurvivalConfig())
    assert np.array_equal(plain.values.weights, paper.values.weights)
    assert np.array_equal(plain.curve, paper.curve)
    assert plain.values.checksum == paper.values.checksum  # metadata included
    assert "survival" not in plain.values.metadata
    for result in (plain, paper):
        with np.load(result.checkpoint_path) as data:
            assert "survival" not in json.loads(str(data["header"][()]))


def test_other_rules_are_recorded_and_change_the_values(tmp_path: Path) -> None:
    plain = _quick(tmp_path / "plain")
    shorter = _quick(tmp_path / "dt", survival=SurvivalConfig(control_dt=0.1))
    assert shorter.values.metadata["survival"] == {"control_dt": 0.1}
    assert load_values("forage", tmp_path / "dt").metadata["survival"] == {"control_dt": 0.1}
    assert not np.array_equal(plain.curve, shorter.curve)


def test_resume_under_other_rules_is_refused(tmp_path: Path) -> None:
    _quick(tmp_path / "plain", episodes=1)
    with pytest.raises(CheckpointError, match="survival"):
        _quick(tmp_path / "plain", SurvivalConfig(control_dt=0.1), episodes=2, resume=True)
    rules = SurvivalConfig(control_dt=0.1)
    _quick(tmp_path / "dt", rules, episodes=1)
    with pytest.raises(CheckpointError, match="survival"):
        _quick(tmp_path / "dt", episodes=2, resume=True)
    with pytest.raises(CheckpointError, match="survival"):
        _quick(tmp_path / "dt", SurvivalConfig(control_dt=0.3), episodes=2, resume=True)
    resumed = _quick(tmp_path / "dt", SurvivalConfig(control_dt=0.1), episodes=2, resume=True)
    assert resumed.episodes_run == 1


# --- the command line -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "setting, message",
    [
        ("world.n_packs=3", "train-behaviours takes survival.* settings, got world.n_packs"),
        ("n_packs=3", "train-behaviours takes survival.* settings, got world.n_packs"),
        ("evolution.initial_energy=50", "got evolution.initial_energy"),
        ("survival.bogus=1", "unknown config key 'survival.bogus'"),
        ("survival.control_dt=abc", "survival.control_dt must be a number in (0, 10], got 'abc'"),
        ("survival.control_dt=-1", "survival.control_dt must be a number in (0, 10]"),
        ("survival.control_dt=0.13", "control_dt must be a positive whole multiple"),
        ("survival.control_dt", "use KEY=VALUE"),
    ],
)
def test_cli_refuses_settings_outside_survival_or_bad_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], setting: str, message: str
) -> None:
    out = tmp_path / "run"
    code = main(
        ["train-behaviours", "--behaviour", "forage", "--set", setting, "--out", str(out)]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_config_file_takes_survival_settings_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    bad = tmp_path / "bad.toml"
    bad.write_text("[survival]\ncontrol_dt = 0.2\n[world]\nn_packs = 3\n")
    argv = ["train-behaviours", "--behaviour", "forage", "--no-progress", "--out", str(out)]
    assert main([*argv, "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "train-behaviours takes survival.* settings, got world.n_packs" in err
    assert not out.exists()
    good = tmp_path / "good.toml"
    good.write_text("[survival]\ncontrol_dt = 0.3\ninitial_energy = 50.0\n")
    # --set wins over the file.
    argv += ["--episodes", "1", "--config", str(good), "--set", "survival.control_dt=0.1"]
    assert main(argv) == 0, capsys.readouterr().err
    assert load_values("forage", out).metadata["survival"] == {"control_dt": 0.1}
