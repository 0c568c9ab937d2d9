"""One episode loop for every task interface: a registered task runs in all of them, and they
agree on what a task's spec says (here: a docking released at once)."""

from __future__ import annotations

from collections.abc import Iterator

import mujoco
import numpy as np
import pytest

from cyber_rodent import tasks
from cyber_rodent.colony_env import ColonyConfig, ColonyEnv
from cyber_rodent.gym_env import CyberRodentEnv, GymConfig
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.tasks import rewards as R
from cyber_rodent.tasks.spec import A_PACK_IN_VIEW, Field, TaskSpec, register, unregister
from cyber_rodent.world import World
from evolution.lab import viewer

WANDER = TaskSpec(
    name="wander",
    summary="one robot moves about beside a parked one, starting with a pack in view",
    field=Field(robots=2, packs=3),
    learners=1,
    start=A_PACK_IN_VIEW,
    sparse=(R.NEW_CELL_TERM,),
    shaped=R.SEARCH_TERMS,
    measure="coverage_cells",
    release_docking=True,
    episode_steps=20,
)


@pytest.fixture
def wander() -> Iterator[TaskSpec]:
    spec = register(WANDER)
    try:
        yield spec
    finally:
        unregister("wander")


def test_a_registered_task_runs_in_every_interface(wander: TaskSpec) -> None:
    assert "wander" in tasks.task_names()

    # dm-control
    dm = tasks.load("wander", seed=0)
    ts = dm.reset()
    assert ts.observation["nearest_battery"][0, 2] == 1.0  # the start condition holds
    assert list(dm.action_spec()) == ["wheels", "led"] and dm.reward_spec().shape == (1,)
    rng = np.random.default_rng(0)
    for step in range(1, 21):
        ts = dm.step({"wheels": rng.uniform(-0.5, 0.5, (1, 2)), "led": np.zeros(1)})
        assert ts.last() == (step == 20)
    dm.close()

    # Gymnasium
    env = CyberRodentEnv("wander", reward="shaped")
    assert env.task_spec is wander and env.world.config.n_robots == 2
    obs, _ = env.reset(seed=0)
    assert obs[env.observation_names.index("battery_visible")] == 1.0
    env.action_space.seed(0)
    truncated = terminated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert list(info["reward_terms"]) == ["progress", "collision"]
        assert reward == info["reward_terms"]["progress"] + info["reward_terms"]["collision"]
    assert truncated and info["steps"] == 20 and info["coverage_cells"] >= 1
    assert not env.world.led_on[1] and not env.survival.docked[1]  # parked
    env.close()

    # PettingZoo: the learner is the one agent, the parked robot none
    colony = ColonyEnv(task="wander")
    assert colony.possible_agents == ["robot_0"] and colony.max_cycles == 20
    observations, _ = colony.reset(seed=0)
    assert observations["robot_0"][colony.observation_names.index("battery_visible")] == 1.0
    colony.action_space("robot_0").seed(0)
    steps = 0
    while colony.agents:
        *_, truncations, _ = colony.step({"robot_0": colony.action_space("robot_0").sample()})
        steps += 1
    assert steps == 20 and truncations == {"robot_0": True}
    colony.close()

    # the viewer's task check, and its task source (no window)
    from behaviours import BehaviourPolicies

    assert viewer.check_task("WANDER") == "wander"
    assert "wander" in viewer.TASK_HELP_NAMES.split(", ")
    source = viewer.TaskSource("wander", 0, BehaviourPolicies.load_default())
    assert [source.step() for _ in range(20)] == [False] * 19 + [True]  # one whole episode
    assert source.episode == 2
    source.close()


def test_the_viewer_refuses_an_unknown_task_naming_the_registered_ones() -> None:
    with pytest.raises(viewer.ViewerError, match="--task must be one of survival, forage"):
        viewer.check_task("wander")


def test_configs_and_keywords_build_the_same_environments() -> None:
    by_config = CyberRodentEnv(config=GymConfig(task="search", action="continuous"))
    by_keywords = CyberRodentEnv("search", action="continuous")
    assert by_config.config == by_keywords.config
    assert by_config.action_space == by_keywords.action_space
    colony = ColonyEnv(ColonyConfig(n_robots=2), max_cycles=3)
    assert colony.config == ColonyConfig(n_robots=2, max_cycles=3)
    assert colony.possible_agents == ["robot_0", "robot_1"] and colony.max_cycles == 3
    with pytest.raises(ValueError, match="max_wheel_speed must be a number in"):
        GymConfig(max_wheel_speed=2.0)
    with pytest.raises(ValueError, match="task must be one of survival, forage, mate, search"):
        ColonyConfig(task="dance")


def _face_a_pack(world: World, survival: SurvivalWorld) -> None:
    """Robot 0 half a metre behind a pack, facing it; the others out of the way."""
    for i, (x, y) in enumerate([(-0.5, 0.0), (0.6, 0.6), (-0.6, 0.7), (0.6, -0.7)]):
        world.set_robot_pose(i, x, y, 0.0)
    for j, xy in enumerate([(0.0, 0.0), (0.9, -0.2), (-0.9, -0.9), (0.2, 0.9), (-0.2, -0.5)]):
        world.set_pack_position(j, *xy)
    survival.refresh_pack_positions()
    mujoco.mj_forward(world.model, world.data)


def test_every_interface_releases_a_search_docking_at_once() -> None:
    """Search's spec says ``release_docking``: the step that docks reports the docking, and the
    robot is free at its end (no recharge, no reflex), in dm-control as in Gymnasium."""
    dm = tasks.load("search", seed=0)
    dm.reset()
    _face_a_pack(dm.task.world, dm.survival)
    action = {"wheels": np.full((1, 2), 0.4), "led": np.zeros(1)}
    gym_env = CyberRodentEnv("search", action="continuous")
    gym_env.reset(seed=0)
    _face_a_pack(gym_env.world, gym_env.survival)
    for survival, step in (
        (dm.survival, lambda: dm.step(action).observation["docked"][0]),
        (gym_env.survival, lambda: gym_env.step(np.full(2, 0.4, dtype=np.float32))[0][19]),
    ):
        for _ in range(15):
            docked_observed = step()
            if survival.events.docked[0]:
                break
        assert survival.events.docked[0], "the robot docked"
        assert docked_observed == 0.0 and not survival.docked[0]  # released at once
        assert survival.reflex_steps_left[0] == 0  # without the reflex
