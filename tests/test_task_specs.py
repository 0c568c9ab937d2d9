"""The task registry: every task defined once, read by every consumer; a new task is one entry."""

from __future__ import annotations

import math
from collections.abc import Iterator

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import cyber_rodent  # noqa: F401  (registers the ids)
from behaviours.episodes import BehaviourEpisode, episode_rng
from cyber_rodent import tasks
from cyber_rodent.colony_env import ColonyEnv
from cyber_rodent.commands import command_index
from cyber_rodent.gym_env import CyberRodentEnv
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.tasks import rewards as R
from cyber_rodent.tasks.spec import (
    A_PACK_IN_VIEW,
    FORAGE,
    MATE,
    SEARCH,
    SURVIVAL,
    Field,
    TaskSpec,
    docked,
    pack_distance,
    register,
    task_names,
    task_spec,
    unregister,
)


# --- the registry -------------------------------------------------------------------------------
def test_built_in_tasks_in_registry_order_and_by_name() -> None:
    assert task_names()[:4] == ("survival", "forage", "mate", "search") == tasks.TASK_NAMES
    assert task_spec("MATE") is MATE and task_spec("search") is SEARCH
    with pytest.raises(ValueError, match="unknown task 'dance'; allowed names: survival, forage"):
        task_spec("dance")
    with pytest.raises(ValueError, match="registered already"):
        register(FORAGE)
    with pytest.raises(ValueError, match="can be removed"):
        unregister("forage")


def test_every_consumer_reads_the_spec() -> None:
    """The dm-control tasks, the Gymnasium and PettingZoo environments and the behaviour
    episodes take their field, learners and episode length from the spec."""
    for spec in (FORAGE, MATE, SEARCH, SURVIVAL):
        task = tasks.load(spec.name, seed=0).task
        assert task.task_spec is spec and type(task) is tasks.TASKS[spec.name]
        assert (task.world.config.n_robots, task.world.config.n_packs) == (
            spec.field.robots, spec.field.packs)  # fmt: skip
        assert task.k == spec.n_learners(spec.field.robots)
        assert task.episode_steps == spec.episode_steps
        env = CyberRodentEnv(spec.name)
        assert env.task_spec is spec.gym and env.episode.max_steps == spec.episode_steps
        assert env.world.config.n_robots == spec.gym.field.robots
        assert env.action_names[1:] == spec.gym.switches
    for spec in (FORAGE, MATE, SEARCH):
        episode = BehaviourEpisode(spec.name)
        assert episode.task is spec and episode.n_learners == spec.learners
        assert episode.world.config.n_robots == spec.field.robots
    colony = ColonyEnv()
    assert colony.world.config.n_robots == SURVIVAL.field.robots
    assert colony.max_cycles == SURVIVAL.episode_steps
    assert colony.action_names[1:] == SURVIVAL.switches == ("led", "mate", "recharge")


def test_the_gymnasium_ids_are_the_built_in_tasks() -> None:
    for name in tasks.TASK_NAMES:
        spec = task_spec(name)
        env_spec = gym.spec(f"CyberRodent/{spec.title}-v0")
        assert env_spec.kwargs == {"task": name}


def test_gymnasium_survival_is_one_robot_alone() -> None:
    solo = SURVIVAL.gym
    assert solo.field == Field(robots=1, packs=5) and solo.switches == ("recharge",)
    assert (solo.led, solo.mate, solo.sparse) == (False, False, SURVIVAL.sparse)


def test_hardware_field_replaces_packs_and_parked_robots() -> None:
    assert (FORAGE.parked, MATE.parked, SEARCH.parked, SURVIVAL.parked) == (0, 0, 3, 0)
    assert FORAGE.hardware_field(3, 6) == Field(robots=1, packs=6)
    assert MATE.hardware_field(3, 6) == Field(robots=2, packs=0)
    assert SEARCH.hardware_field(3, 6) == Field(robots=3, packs=6)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"name": "Big"}, "lower-case"),
        ({"learners": 3}, r"learners: must be in \[1, 2\]"),
        ({"success": None}, "'is_success' needs a success"),
        ({"target": None}, "needs the target's distance"),
        ({"death": "some"}, "death: must be one of any, all"),
        ({"control_reward": "shaped", "shaped": ()}, "has no shaped reward"),
    ],
)
def test_a_spec_refuses_what_no_consumer_could_run(changes: dict, match: str) -> None:
    base = dict(name="tiny", summary="", field=Field(robots=2, packs=1), success=docked,
                shaped=R.APPROACH, target=pack_distance)  # fmt: skip
    with pytest.raises(ValueError, match=match):
        TaskSpec(**{**base, **changes})


# --- a new task is one entry ----------------------------------------------------------------
def _alive(outcome: R.StepOutcome, scales: R.RewardScales) -> np.ndarray:
    """A test term: 0.5 per step."""
    return np.full(len(outcome.captured), 0.5)


TINY = TaskSpec(
    name="tiny",
    summary="one robot docks onto the one pack in view while a second robot stands parked",
    field=Field(robots=2, packs=1),
    start=A_PACK_IN_VIEW,
    success=docked,
    shaped=(*R.APPROACH, R.RewardTerm("alive", _alive)),
    target=pack_distance,
    recharge=True,
    episode_steps=12,
)


@pytest.fixture
def tiny() -> Iterator[TaskSpec]:
    spec = register(TINY)
    gym.register(id="CyberRodent/Tiny-v0", entry_point="cyber_rodent.gym_env:CyberRodentEnv",
                 kwargs={"task": "tiny"})  # fmt: skip
    yield spec
    del gym.registry["CyberRodent/Tiny-v0"]
    unregister("tiny")


def test_a_registered_task_is_a_gym_env_and_a_dm_control_task(tiny: TaskSpec) -> None:
    env = gym.make("CyberRodent/Tiny-v0", reward="shaped")
    assert env.unwrapped.task_spec is tiny
    assert env.unwrapped.world.config.n_robots == 2 and env.unwrapped.world.config.n_packs == 1
    obs, info = env.reset(seed=0)
    assert obs[16] == 1.0  # battery_visible: the start condition holds
    steps = 0
    truncated = terminated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(command_index("spin_left"))
        steps += 1
        terms = info["reward_terms"]
        assert list(terms) == ["shaping", "step_cost", "goal", "alive"]
        assert terms["alive"] == 0.5 and terms["step_cost"] == -0.02
        assert reward == ((terms["shaping"] + terms["step_cost"]) + terms["goal"]) + 0.5
    assert truncated and steps == 12 and "is_success" in info
    parked = env.unwrapped
    assert not parked.world.led_on[1] and not parked._wheels[1].any()  # parked: dark, still
    env.close()
    dm = tasks.load("tiny", seed=0)
    assert dm.task.k == 1 and list(dm.action_spec()) == ["wheels", "led"]
    assert "start_in_view" in type(dm.task).option_names()
    assert dm.reset().observation["nearest_battery"][0, 2] == 1.0
    with pytest.raises(ValueError, match="n_packs must be >= 1 for Tiny"):
        tasks.load("tiny", seed=0, n_packs=0)
    with pytest.raises(ValueError, match="one of survival, forage, mate, search, tiny"):
        CyberRodentEnv("tinier")


# --- rewards --------------------------------------------------------------------------------
def test_heading_progress_by_hand() -> None:
    before = np.array([0.1, -0.2, math.pi / 2])
    after = np.array([0.3, 0.1, 0.0])
    # Facing +y: 0.3 m along the heading; the 0.2 m sideways do not count.
    assert R.heading_progress(before, after) == pytest.approx(0.3)
    both = R.heading_progress(np.stack([before, before]), np.stack([after, before]))
    assert both.shape == (2,) and both[1] == 0.0


def test_terms_sum_to_the_documented_formulas() -> None:
    scales = R.RewardScales()
    outcome = R.StepOutcome.zeros(1, 0.2)
    outcome.progress[:] = 0.07
    outcome.collided[:] = True
    search = R.total_reward({t.name: t.value(outcome, scales) for t in R.SEARCH_TERMS})
    assert search[0] == R.search_reward(0.07, True, 0.5 * 0.2, 3.0) == 0.7 - 3.0
    outcome.distance_before[:], outcome.distance_after[:] = 0.30, 0.28
    approach = R.total_reward({t.name: t.value(outcome, scales) for t in R.APPROACH})
    assert approach[0] == R.approach_reward(R.EpisodeConfig(), 0.30, 0.28, False)
    assert approach[0] == pytest.approx(0.98 * -0.28 + 0.30 - 0.02)


@pytest.mark.parametrize("name", ["forage", "search", "survival"])
def test_info_names_the_terms_that_make_the_reward(name: str) -> None:
    reward = "sparse" if name == "survival" else "shaped"
    env = CyberRodentEnv(name, reward=reward)
    env.reset(seed=1)
    env.action_space.seed(1)
    expected = [t.name for t in task_spec(name).rewards(reward)]
    for _ in range(20):
        _, r, terminated, truncated, info = env.step(env.action_space.sample())
        assert list(info["reward_terms"]) == expected
        total = R.total_reward({k: np.array([v]) for k, v in info["reward_terms"].items()})
        assert r == total[0]
        if terminated or truncated:
            break


def test_episode_rewards_are_the_task_terms() -> None:
    """The behaviour episode's reward is its task's shaped terms on the same step."""
    episode = BehaviourEpisode("search")
    episode.reset(episode_rng(0, 0))
    forward = np.array([command_index("forward")])
    for _ in range(10):
        x0, y0, yaw0 = episode.world.poses()[0]
        result = episode.step(forward)
        x1, y1, _ = episode.world.poses()[0]
        progress = (x1 - x0) * math.cos(yaw0) + (y1 - y0) * math.sin(yaw0)
        expected = R.search_reward(progress, bool(result.collided[0]), 0.5 * episode.dt, 3.0)
        assert result.rewards[0] == expected


def test_dm_control_survival_rewards_captures_by_the_capture_rule() -> None:
    """With ``capture_rule="recharge"`` a battery counts on the docking's first recharge step
    (``StepEvents.captured``), as in the Gymnasium and PettingZoo environments."""
    env = tasks.load("survival", seed=0, survival=SurvivalConfig(capture_rule="recharge"))
    env.reset()
    world = env.task.world
    for i, (x, y) in enumerate([(-0.5, 0.0), (0.6, 0.6), (-0.6, 0.7), (0.6, -0.7)]):
        world.set_robot_pose(i, x, y, 0.0)
    for j, xy in enumerate([(0.0, 0.0), (0.9, -0.2), (-0.9, -0.9), (0.2, 0.9), (-0.2, -0.5)]):
        world.set_pack_position(j, *xy)
    env.survival.refresh_pack_positions()
    mujoco.mj_forward(world.model, world.data)
    wheels = np.zeros((4, 2))
    wheels[0] = 0.4
    action = {"wheels": wheels, "led": np.zeros(4), "mate": np.zeros(4),
              "recharge": np.ones(4)}  # fmt: skip
    for _ in range(15):
        ts = env.step(action)
        if ts.observation["docked"][0]:
            break
    assert ts.observation["docked"][0] == 1.0 and ts.reward.sum() == 0.0  # docked, no capture
    ts = env.step(action)
    assert ts.reward.tolist() == [1.0, 0.0, 0.0, 0.0]  # the first recharge step
