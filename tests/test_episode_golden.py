"""Golden traces of every task interface: a fixed seed and fixed actions, hashed step by step.

Each trace runs one interface for 300 control steps (resetting when an episode ends) with actions
drawn from a fixed generator, and hashes everything the interface returns: observations,
rewards, terminations, truncations, discounts and infos (arrays by dtype, shape and bytes,
other values by ``repr``). The expected hashes were recorded at commit ``f8649f5``, before the
four episode loops (the dm-control task, the Gymnasium environment, the PettingZoo colony and
the behaviours' training episodes) became adapters over one ``TaskEpisode``; they pin that the
refactoring changed no number. Floats are hashed bit for bit, so a hash holds on one platform
and build of MuJoCo and numpy (x86_64 Linux, the versions of ``pyproject.toml``).

Where a hash was changed on purpose, :data:`CHANGED` says which and why.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

STEPS = 300


class Trace:
    """A running SHA-256 of what an interface returned."""

    def __init__(self) -> None:
        self._hash = hashlib.sha256()

    def add(self, *values: Any) -> None:
        for value in values:
            self._add(value)

    def _add(self, value: Any) -> None:
        if isinstance(value, np.ndarray):
            self._hash.update(f"{value.dtype.str}{value.shape}".encode())
            self._hash.update(np.ascontiguousarray(value).tobytes())
        elif isinstance(value, dict):
            for key in sorted(value):
                self._hash.update(repr(key).encode())
                self._add(value[key])
        elif isinstance(value, list | tuple):
            self._hash.update(f"{type(value).__name__}{len(value)}".encode())
            for item in value:
                self._add(item)
        elif isinstance(value, np.generic):
            self._add(np.asarray(value))
        else:
            self._hash.update(f"{type(value).__name__}:{value!r}".encode())

    def hexdigest(self) -> str:
        return self._hash.hexdigest()[:16]


# --- the interfaces -------------------------------------------------------------------------------
def dm_control_trace(name: str, seed: int = 0) -> str:
    from cyber_rodent import tasks

    env = tasks.load(name, seed=seed)
    rng = np.random.default_rng(1000 + seed)
    spec = env.action_spec()
    trace = Trace()
    ts = env.reset()
    trace.add(ts.step_type.value, ts.observation)
    for _ in range(STEPS):
        action = {key: rng.uniform(s.minimum, s.maximum, size=s.shape) for key, s in spec.items()}
        ts = env.step(action)  # a step after the last one resets
        trace.add(ts.step_type.value, ts.reward, ts.discount, ts.observation)
    env.close()
    return trace.hexdigest()


def gym_trace(task: str, seed: int = 0, **options: Any) -> str:
    from cyber_rodent.gym_env import CyberRodentEnv

    env = CyberRodentEnv(task, **options)
    env.action_space.seed(2000 + seed)
    trace = Trace()
    obs, info = env.reset(seed=seed)
    trace.add(obs, info)
    for _ in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace.add(obs, reward, terminated, truncated, info)
        if terminated or truncated:
            obs, info = env.reset()
            trace.add(obs, info)
    env.close()
    return trace.hexdigest()


def colony_trace(policy: str, seed: int = 0, **options: Any) -> str:
    from cyber_rodent.colony_env import baseline_policy, parallel_env

    env = parallel_env(**options)
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(3000 + seed + i)
    trace = Trace()
    observations, infos = env.reset(seed=seed)
    trace.add(observations, infos)
    act: Callable[[dict[str, Any]], dict[str, Any]]
    if policy == "baseline":
        act = baseline_policy(env)
    else:

        def act(observations: dict[str, Any]) -> dict[str, Any]:
            return {agent: env.action_space(agent).sample() for agent in env.agents}

    for _ in range(STEPS):
        if not env.agents:
            observations, infos = env.reset()
            trace.add(observations, infos)
        result = env.step(act(observations))
        observations = result[0]
        trace.add(*result)
    env.close()
    return trace.hexdigest()


def behaviour_trace(name: str, seed: int = 0, hardware: bool = False) -> str:
    from behaviours.episodes import BehaviourEpisode, episode_rng, random_commands
    from cyber_rodent.profiles import HardwareProfile

    profile = HardwareProfile() if hardware else None
    env = BehaviourEpisode(name, profile=profile, randomise=hardware)
    rng = np.random.default_rng(4000 + seed)
    trace = Trace()
    episode = 0
    states = env.reset(episode_rng(seed, episode))
    trace.add(states)
    for _ in range(STEPS):
        result = env.step(random_commands(rng, env.n_learners))
        trace.add(result.states, result.rewards, result.terminal, result.collided)
        if result.terminal or env.steps >= env.config.max_steps:
            episode += 1
            states = env.reset(episode_rng(seed, episode))
            trace.add(states)
    return trace.hexdigest()


# --- the expected hashes (recorded at f8649f5) --------------------------------------------------
TRACES: dict[str, Callable[[], str]] = {
    "dm_control/survival": lambda: dm_control_trace("survival"),
    "dm_control/forage": lambda: dm_control_trace("forage"),
    "dm_control/mate": lambda: dm_control_trace("mate"),
    "dm_control/search": lambda: dm_control_trace("search"),
    "gym/survival": lambda: gym_trace("survival"),
    "gym/survival/continuous-raw": lambda: gym_trace(
        "survival", action="continuous", observation="raw"
    ),
    "gym/forage": lambda: gym_trace("forage"),
    "gym/forage/continuous-shaped": lambda: gym_trace(
        "forage", action="continuous", reward="shaped"
    ),
    "gym/mate": lambda: gym_trace("mate"),
    "gym/mate/shaped-partner": lambda: gym_trace(
        "mate", reward="shaped", partner_policy=lambda obs: int(obs[9] * 7.0)
    ),
    "gym/search": lambda: gym_trace("search"),
    "gym/search/shaped": lambda: gym_trace("search", reward="shaped"),
    "pettingzoo/random": lambda: colony_trace("random"),
    "pettingzoo/random-continuous-raw": lambda: colony_trace(
        "random", action="continuous", observation="raw"
    ),
    "pettingzoo/baseline": lambda: colony_trace("baseline"),
    "behaviours/forage": lambda: behaviour_trace("forage"),
    "behaviours/mate": lambda: behaviour_trace("mate"),
    "behaviours/search": lambda: behaviour_trace("search"),
    "behaviours/forage/hardware": lambda: behaviour_trace("forage", hardware=True),
}

GOLDEN: dict[str, str] = {
    "dm_control/survival": "bd3fed93e1789d90",
    "dm_control/forage": "ea86c541f31146a9",
    "dm_control/mate": "ca55072799d2b070",
    "dm_control/search": "1929c407536e67f5",  # f8649f5: 2ae79a8a093e3ee3 (see CHANGED)
    "gym/survival": "c01c5dcfa4d17451",
    "gym/survival/continuous-raw": "e756b46938ff0937",
    "gym/forage": "d1512687434410d5",
    "gym/forage/continuous-shaped": "62cb7bc87061c0fb",
    "gym/mate": "0aae1676fabb97d8",
    "gym/mate/shaped-partner": "bf270f3abea33b65",
    "gym/search": "1e33664a405b1955",
    "gym/search/shaped": "3654cdf818c3eb57",
    "pettingzoo/random": "2c33ad4f3fb8e0df",
    "pettingzoo/random-continuous-raw": "c4638e8b8fe5ed5a",
    "pettingzoo/baseline": "57d45ea9ef59c216",
    "behaviours/forage": "7f59fa0df4398078",
    "behaviours/mate": "fd5354b7ecaa0f76",
    "behaviours/search": "e53a11f7d14fb76b",
    "behaviours/forage/hardware": "53e04d2ad7b0de96",
}

#: Hashes changed on purpose since f8649f5, and why.
CHANGED: dict[str, str] = {
    "dm_control/search": (
        "Search's spec says release_docking; the dm-control task now honours it, as the "
        "Gymnasium environment and the behaviour episodes always did (the episode loop is "
        "shared). In this trace the learner docks at step 229: steps 1-228 and that step's "
        "reward are as before; its observation now reads docked 0 (released at once, no "
        "reflex) where it read 1, and the learner keeps its wheels where the rotation reflex "
        "took them for 2 steps, so every later step differs."
    ),
}


@pytest.mark.parametrize("name", sorted(TRACES))
def test_trace_matches_the_recorded_hash(name: str) -> None:
    assert TRACES[name]() == GOLDEN[name], CHANGED.get(name, "")


if __name__ == "__main__":  # print the hashes of this checkout
    for key in TRACES:
        print(f'    "{key}": "{TRACES[key]()}",')
