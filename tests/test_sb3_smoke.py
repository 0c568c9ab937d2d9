"""Stable-Baselines3 trains on the Gymnasium Forage environment and its policy acts in it.

A client no one here wrote (the ``rl`` extra); a base install without it skips this module.
The full learning curve is ``benchmarks/sb3_forage.py``.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from stable_baselines3 import PPO  # noqa: E402

import cyber_rodent  # noqa: E402, F401  (registers the ids)
from benchmarks.sb3_forage import (  # noqa: E402
    check_same_starts,
    evaluate_model,
    make_env,
)

STEPS = 256


@pytest.fixture(autouse=True)
def one_thread() -> None:
    torch.set_num_threads(1)


def trained_ppo(env: gym.Env[np.ndarray, int], seed: int = 0) -> PPO:
    model = PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=2, seed=seed,
                device="cpu")  # fmt: skip
    model.learn(total_timesteps=STEPS)
    return model


def test_ppo_trains_on_forage_and_acts_in_it() -> None:
    env = gym.make("CyberRodent/Forage-v0", action="discrete", reward="shaped")
    model = trained_ppo(env)
    assert model.num_timesteps == STEPS
    obs, _ = env.reset(seed=3)
    steps, terminated, truncated = 0, False, False
    info: dict[str, Any] = {}
    while not (terminated or truncated):
        action, _ = model.predict(obs, deterministic=True)
        assert env.action_space.contains(int(action))
        obs, reward, terminated, truncated, info = env.step(int(action))
        assert env.observation_space.contains(obs) and math.isfinite(float(reward))
        steps += 1
    assert steps == info["steps"] <= 100
    assert info["is_success"] == terminated
    env.close()


def test_same_seed_same_ppo() -> None:
    first, second = (trained_ppo(make_env(), seed=5) for _ in range(2))
    for a, b in zip(first.policy.parameters(), second.policy.parameters(), strict=True):
        assert torch.equal(a, b)


def test_benchmark_evaluates_on_the_behaviour_evaluation_episodes() -> None:
    env = make_env()
    check_same_starts(env, 3, eval_seed=0)  # raises if a start differs
    model = trained_ppo(make_env())
    result = evaluate_model(model, env, 3, eval_seed=0)
    again = evaluate_model(model, env, 3, eval_seed=0)
    assert result.episodes == 3 and ((1 <= result.steps) & (result.steps <= 100)).all()
    assert (result.success | (result.steps == 100)).all()  # a failure runs to the step limit
    assert np.array_equal(result.steps, again.steps)  # deterministic policy, same starts
    assert np.array_equal(result.success, again.success)
    env.close()
