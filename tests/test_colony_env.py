"""The colony as a PettingZoo ParallelEnv: API, seeding, and the survival rules per agent."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo.test import parallel_api_test, parallel_seed_test

from cyber_rodent.colony_env import ColonyEnv, parallel_env
from cyber_rodent.commands import N_COMMANDS, command_index
from cyber_rodent.gym_env import OBSERVATION_NAMES
from cyber_rodent.survival import SurvivalConfig

AGENTS = ["robot_0", "robot_1", "robot_2", "robot_3"]
STOP = command_index("stop")


def index(name: str) -> int:
    return OBSERVATION_NAMES.index(name)


def act(command: int = STOP, led: int = 0, mate: int = 0, recharge: int = 1) -> np.ndarray:
    return np.array([command, led, mate, recharge])


def place(env: ColonyEnv, poses: dict[int, tuple[float, float, float]], packs=None) -> None:
    """Put robots (and packs) where a scripted test needs them, after ``env.reset()``."""
    for i, pose in poses.items():
        env.world.set_robot_pose(i, *pose)
    for j, xy in (packs or {}).items():
        env.world.set_pack_position(j, *xy)
    env.survival.refresh_pack_positions()
    mujoco.mj_forward(env.world.model, env.world.data)


@pytest.mark.parametrize("action", ["discrete", "continuous"])
def test_parallel_api_and_seed_tests_pass(action: str, capsys: pytest.CaptureFixture) -> None:
    env = parallel_env(action=action, render_mode="rgb_array")
    parallel_api_test(env, num_cycles=120)  # long enough for deaths (energy 100, -1 per step)
    assert "Passed Parallel API test" in capsys.readouterr().out
    assert env.max_cycles == 120  # the test's cycle limit is the truncation
    parallel_seed_test(lambda: parallel_env(action=action))
    env.close()


def test_spaces_agents_and_observation_layout() -> None:
    env = ColonyEnv(action="continuous", observation="raw")
    assert env.possible_agents == AGENTS and env.agents == []
    obs, infos = env.reset(seed=0)
    assert env.agents == AGENTS and set(obs) == set(infos) == set(AGENTS)
    space = env.observation_space("robot_2")
    assert space is env.observation_space("robot_2") and isinstance(space, spaces.Box)
    assert space.shape == (len(OBSERVATION_NAMES),) and space.dtype == np.float32
    assert space.high[index("energy")] == 200.0
    assert all(o in space and o[index("energy")] == 100.0 for o in obs.values())
    assert env.action_names == ("left_wheel", "right_wheel", "led", "mate", "recharge")
    box = env.action_space("robot_0")
    assert box.low.tolist() == [-1] * 5 and box.high.tolist() == [1] * 5
    discrete = ColonyEnv()
    assert discrete.action_space("robot_0") == spaces.MultiDiscrete([N_COMMANDS, 2, 2, 2])
    assert discrete.observation_names == OBSERVATION_NAMES


def test_the_default_observation_is_normalised() -> None:
    raw_env, env = ColonyEnv(observation="raw"), ColonyEnv()
    assert env.observation_kind == "normalised"
    space = env.observation_space("robot_1")
    assert isinstance(space, spaces.Box) and space.shape == (len(OBSERVATION_NAMES),)
    bearings = [index(f"{target}_bearing") for target in ("led", "face", "battery")]
    assert (space.high == 1).all() and space.dtype == np.float32
    assert (space.low[bearings] == -1).all() and np.delete(space.low, bearings).max() == 0
    for i, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(i)
        raw_env.action_space(agent).seed(i)
    obs, _ = env.reset(seed=2)
    raw, _ = raw_env.reset(seed=2)
    assert all(o[index("energy")] == 0.5 for o in obs.values())  # 100 of 200 at birth
    for _ in range(150):  # past the deaths at step 100
        for agent, o in obs.items():
            assert o in space and np.array_equal(o, env.observation_scale.normalise(raw[agent]))
            assert raw[agent] in raw_env.observation_space(agent)
        if not env.agents:
            break
        actions = {a: env.action_space(a).sample() for a in env.agents}
        raw_actions = {a: raw_env.action_space(a).sample() for a in raw_env.agents}
        obs, *_ = env.step(actions)
        raw, *_ = raw_env.step(raw_actions)
    with pytest.raises(ValueError, match="observation must be one of normalised, raw"):
        ColonyEnv(observation="metres")


def test_observations_change_and_same_seed_gives_same_trajectory() -> None:
    def rollout(seed: int) -> list[dict[str, np.ndarray]]:
        env = ColonyEnv()
        for i, agent in enumerate(env.possible_agents):
            env.action_space(agent).seed(i)
        obs, _ = env.reset(seed=seed)
        trace = [obs]
        for _ in range(20):
            obs, *_ = env.step({a: env.action_space(a).sample() for a in env.agents})
            trace.append(obs)
        return trace

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert all(np.array_equal(x[k], y[k]) for x, y in zip(a, b, strict=True) for k in x)
    assert not np.array_equal(a[0]["robot_0"], c[0]["robot_0"])
    robot_0 = np.stack([obs["robot_0"] for obs in a])
    assert (robot_0.std(axis=0) > 0).sum() >= 3


def test_capture_rewards_the_robot_and_the_dead_leave_the_agents() -> None:
    env = ColonyEnv()
    env.reset(seed=0)
    place(
        env,
        {0: (-0.5, 0.0, 0.0), 1: (0.6, 0.6, 0.0), 2: (-0.6, 0.7, 0.0), 3: (0.6, -0.7, 0.0)},
        packs={0: (0.0, 0.0), 1: (0.9, -0.2), 2: (-0.9, -0.9), 3: (0.2, 0.9), 4: (-0.2, -0.5)},
    )
    forward = command_index("forward_slow")
    captured_at = None
    for step in range(1, 400):
        actions = {a: act() for a in env.agents}
        if captured_at is None:  # drive onto the pack, then stand (and recharge while docked)
            actions["robot_0"] = act(forward)
        obs, rewards, terminations, truncations, infos = env.step(actions)
        if captured_at is None and rewards.get("robot_0"):
            captured_at = step
            assert rewards == {"robot_0": 1.0, "robot_1": 0.0, "robot_2": 0.0, "robot_3": 0.0}
            assert infos["robot_0"]["captured"] and obs["robot_0"][index("docked")] == 1.0
        if step == 100:  # energy 100, -1 per step: the robots that never recharged die now
            assert terminations == {"robot_0": False, "robot_1": True, "robot_2": True,
                                    "robot_3": True}  # fmt: skip
            assert env.agents == ["robot_0"]
            assert obs["robot_1"][index("energy")] == 0.0
        if not env.agents:
            break
    assert captured_at is not None and captured_at < 20
    # Robot 0 recharged to full (200) and then drained 1 per step: it outlived the others.
    assert 200 < step < 400
    assert terminations == {"robot_0": True} and truncations == {"robot_0": False}
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})


def test_mating_rewards_both_partners() -> None:
    env = ColonyEnv(n_packs=0)
    env.reset(seed=0)
    gap = math.sqrt(0.3**2 - 0.04**2) + 2 * 0.111  # IR ports 0.3 m apart, facing
    place(env, {0: (-gap / 2, 0.0, 0.0), 1: (gap / 2, 0.0, math.pi), 2: (-0.8, 0.8, 0.0),
                3: (0.8, -0.8, 0.0)})  # fmt: skip
    actions = {"robot_0": act(led=1, mate=1), "robot_1": act(mate=1), "robot_2": act(mate=1),
               "robot_3": act()}  # fmt: skip
    _, first, *_ = env.step(actions)  # the exchange takes 2 steps (mate_consecutive_steps)
    obs, second, _, _, infos = env.step(actions)
    assert set(first.values()) == {0.0}
    assert second == {"robot_0": 1.0, "robot_1": 1.0, "robot_2": 0.0, "robot_3": 0.0}
    assert infos["robot_0"]["mate_partner"] == "robot_1"
    assert infos["robot_1"]["mate_partner"] == "robot_0"
    assert infos["robot_2"]["mate_partner"] is None
    assert obs["robot_1"][index("led_visible")] == 1.0  # robot 1 sees robot 0's green LED
    assert obs["robot_0"][index("led_on")] == 1.0


def test_truncation_after_max_cycles_and_bad_actions() -> None:
    env = ColonyEnv(n_robots=2, n_packs=1, max_cycles=3, survival=SurvivalConfig())
    env.reset(seed=1)
    with pytest.raises(ValueError, match="missing"):
        env.step({"robot_0": act()})
    with pytest.raises(ValueError, match="must lie in"):
        env.step({"robot_0": act(command=N_COMMANDS), "robot_1": act()})
    for _ in range(3):
        _, _, terminations, truncations, _ = env.step({a: act() for a in env.agents})
    assert truncations == {"robot_0": True, "robot_1": True}
    assert terminations == {"robot_0": False, "robot_1": False} and env.agents == []
    with pytest.raises(ValueError, match="max_cycles"):
        ColonyEnv(max_cycles=0)


def test_render_rgb_array() -> None:
    env = ColonyEnv(render_mode="rgb_array", render_width=200, render_height=100)
    env.reset(seed=0)
    image = env.render()
    assert image is not None and image.shape == (100, 200, 3) and image.std() > 0
    env.close()
    env.close()
    assert ColonyEnv().render() is None
