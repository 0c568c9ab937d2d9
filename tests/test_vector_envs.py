"""Vectorised Gymnasium environments: ``gymnasium.make_vec`` (sync and async) and SB3's
``SubprocVecEnv`` step and reset deterministically with seeds, as the single environments do."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import cyber_rodent  # noqa: F401  (registers the ids)

ENV_ID = "CyberRodent/Forage-v0"
STEPS = 12
#: Fixed commands for the two environments, so every run takes the same actions.
ACTIONS = np.array([[k % 8, (3 * k + 1) % 8] for k in range(STEPS)])


def rollout(envs: Any, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observations, rewards and episode ends of ``STEPS`` steps from ``reset(seed=seed)``."""
    obs, _ = envs.reset(seed=seed)
    trace, rewards, ends = [obs], [], []
    for action in ACTIONS:
        obs, reward, terminated, truncated, _ = envs.step(action)
        trace.append(obs)
        rewards.append(reward)
        ends.append(terminated | truncated)
    envs.close()
    return np.stack(trace), np.stack(rewards), np.stack(ends)


def single_rollouts(seed: int, **kwargs: Any) -> np.ndarray:
    """The observations of two single environments reset with ``seed`` and ``seed + 1``
    (the seeds ``make_vec``'s ``reset(seed=seed)`` gives its environments), (steps, 2, 21)."""
    traces = []
    for i in range(2):
        env = gym.make(ENV_ID, **kwargs)
        obs, _ = env.reset(seed=seed + i)
        trace = [obs]
        for action in ACTIONS[:, i]:
            obs, _, terminated, truncated, _ = env.step(int(action))
            trace.append(obs)
            assert not (terminated or truncated)  # no autoreset to mirror in these steps
        traces.append(np.stack(trace))
        env.close()
    return np.stack(traces, axis=1)


@pytest.fixture(scope="module")
def sync_rollout() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync", reward="shaped")
    assert envs.num_envs == 2
    assert envs.single_observation_space == gym.make(ENV_ID).observation_space
    return rollout(envs, seed=5)


def test_sync_vector_env_steps_the_single_environments(sync_rollout) -> None:
    obs, rewards, ends = sync_rollout
    assert obs.shape == (STEPS + 1, 2, 21) and obs.dtype == np.float32
    assert ((obs >= -1) & (obs <= 1)).all()
    assert rewards.shape == (STEPS, 2) and not ends.any()
    assert np.array_equal(obs, single_rollouts(5, reward="shaped"))
    again = rollout(gym.make_vec(ENV_ID, num_envs=2, reward="shaped"), seed=5)
    assert all(np.array_equal(a, b) for a, b in zip(sync_rollout, again, strict=True))
    other = rollout(gym.make_vec(ENV_ID, num_envs=2, reward="shaped"), seed=6)
    assert not np.array_equal(obs, other[0])


@pytest.mark.parametrize("context", ["fork", "forkserver"])
def test_async_vector_env_matches_the_sync_one(sync_rollout, context: str) -> None:
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="async", reward="shaped",
                        vector_kwargs={"context": context})  # fmt: skip
    result = rollout(envs, seed=5)
    assert all(np.array_equal(a, b) for a, b in zip(sync_rollout, result, strict=True))


def test_sb3_subproc_vec_env_matches_the_dummy_one() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    def run(vec_env_cls: type) -> np.ndarray:
        # "cyber_rodent:" makes gymnasium import the package, so the ids are registered in the
        # worker processes too (forkserver, SB3's default, does not inherit the registry).
        envs = make_vec_env("cyber_rodent:" + ENV_ID, n_envs=2, seed=5,
                            vec_env_cls=vec_env_cls)  # fmt: skip
        trace = [envs.reset()]
        for action in ACTIONS:
            obs, _, dones, _ = envs.step(action)
            trace.append(obs)
            assert not dones.any()
        envs.close()
        return np.stack(trace)

    subproc = run(SubprocVecEnv)
    assert np.array_equal(subproc, run(DummyVecEnv))
    assert np.array_equal(subproc, single_rollouts(5))  # make_vec_env seeds env i with 5 + i
