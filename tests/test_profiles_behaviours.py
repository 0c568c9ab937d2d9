"""Behaviour episodes in the hardware-like profile and domain randomisation."""

from __future__ import annotations

import numpy as np
import pytest

from behaviours.episodes import BehaviourEpisode, episode_rng
from behaviours.training import CheckpointError, train
from cyber_rodent.profiles import HardwareProfile


def test_profile_keeps_the_placements_and_changes_the_readings() -> None:
    plain = BehaviourEpisode("forage", profile=None)
    hw = BehaviourEpisode("forage", profile=HardwareProfile().without("field"))
    for e in range(3):
        a = plain.reset(episode_rng(0, e))
        b = hw.reset(episode_rng(0, e))
        np.testing.assert_array_equal(plain.world.poses(), hw.world.poses())  # same starts
        assert a.shape == b.shape
    assert not np.array_equal(plain.world.model.actuator_gainprm, hw.world.model.actuator_gainprm)
    ranges = hw._ranges()
    assert not np.array_equal(ranges, plain.world.range_readings())  # noisy IR


def test_hardware_field_in_episodes() -> None:
    assert BehaviourEpisode("forage", profile=HardwareProfile()).world.config.n_packs == 6
    search = BehaviourEpisode("search", profile=HardwareProfile())
    assert (search.world.config.n_robots, search.world.config.n_packs) == (3, 6)
    mate = BehaviourEpisode("mate", profile=HardwareProfile())
    assert (mate.world.config.n_robots, mate.world.config.n_packs) == (2, 0)


def test_randomised_episodes_are_seeded_and_do_not_compound() -> None:
    env = BehaviourEpisode("forage", profile=HardwareProfile(), randomise=True)
    built = env.world.model.actuator_gainprm.copy()
    env.reset(episode_rng(1, 4))
    first, gain = env.episode_profile, env.world.model.actuator_gainprm.copy()
    env.reset(episode_rng(1, 5))
    assert env.episode_profile != first  # each episode draws its own magnitudes
    env.reset(episode_rng(1, 4))
    assert env.episode_profile == first  # same episode seed, same draw
    np.testing.assert_array_equal(env.world.model.actuator_gainprm, gain)  # from the build
    motor = env.world._ctrl_slice.start
    factor = gain[motor, 0] / built[motor, 0]
    spread = HardwareProfile().actuators.wheel_gain_spread
    assert 0.7 * (1 - spread) <= factor <= 1 + spread


def test_randomise_needs_a_profile() -> None:
    with pytest.raises(ValueError, match=r"randomise must be True \(with a profile\) or False"):
        BehaviourEpisode("forage", randomise=True)
    with pytest.raises(ValueError, match=r"profile must be a HardwareProfile or None"):
        BehaviourEpisode("forage", profile="hardware")


def test_randomised_training_is_reproducible_and_resume_checks_it(tmp_path) -> None:
    a = train("forage", 4, seed=3, out_dir=tmp_path / "a", progress=False, randomise=True)
    b = train("forage", 4, seed=3, out_dir=tmp_path / "b", progress=False, randomise=True)
    np.testing.assert_array_equal(a.values.weights, b.values.weights)
    assert a.values.metadata["profile"]["randomise"] is True
    plain = train("forage", 4, seed=3, out_dir=tmp_path / "c", progress=False)
    assert not np.array_equal(a.values.weights, plain.values.weights)
    with pytest.raises(CheckpointError, match=r"profile differs from this run's"):
        train("forage", 6, seed=3, out_dir=tmp_path / "a", progress=False, resume=True)
