"""The tasks' rewards, terminations, options and input validation, in scripted physical scenes."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from dm_env import StepType

from cyber_rodent import commands, tasks
from cyber_rodent.robot import cyber_rodent
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.vision import BATTERY

#: The paper's robot, read from its MJCF file and sensor table.
CR = cyber_rodent()


def place(env, poses: dict[int, tuple[float, float, float]], packs=None) -> None:
    """Put robots (and packs) where a scripted test needs them, after ``env.reset()``."""
    world = env.task.world
    for i, (x, y, yaw) in poses.items():
        world.set_robot_pose(i, x, y, yaw)
    for j, (x, y) in (packs or {}).items():
        world.set_pack_position(j, x, y)
    env.survival.refresh_pack_positions()
    mujoco.mj_forward(world.model, world.data)


def wheels_action(env, wheels, **extra) -> dict:
    k = env.task.k
    action = {"wheels": np.asarray(wheels, dtype=float).reshape(k, 2), "led": np.zeros(k)}
    for key in env.action_spec():
        if key not in action:
            action[key] = extra.get(key, np.zeros(k))
    return action


# --- loading and options ------------------------------------------------------------------------
def test_load_by_name_gives_the_documented_settings():
    env = tasks.load("survival", seed=0)
    assert isinstance(env.task, tasks.Survival)
    assert env.task.world.config.n_robots == 4 and env.task.world.config.n_packs == 5
    assert env.task.episode_steps == 400
    assert env.control_timestep() == pytest.approx(0.2)
    assert set(env.observation_spec()) == set(tasks.OBSERVATION_NAMES)
    assert list(env.action_spec()) == ["wheels", "led", "mate", "recharge"]
    assert env.action_spec()["wheels"].maximum == CR.top_speed
    assert env.reward_spec().shape == (4,)
    assert tasks.load("MATE", seed=0).reward_spec().shape == (2,)
    assert tasks.load("forage", seed=0).observation_spec()["energy"].shape == (1,)


def test_episode_lasts_episode_steps():
    env = tasks.load("search", seed=0, episode_steps=7)
    env.reset()
    steps = [env.step(wheels_action(env, [[0.0, 0.0]])).step_type for _ in range(7)]
    assert steps[:6] == [StepType.MID] * 6 and steps[6] is StepType.LAST


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"name": "surival"}, "unknown task 'surival'; allowed names: survival, forage"),
        ({"name": "survival", "episode_steps": 0}, "episode_steps"),
        ({"name": "survival", "episode_steps": -5}, "episode_steps"),
        ({"name": "forage", "colour": "red"}, r"unknown option\(s\) \['colour'\]"),
        ({"name": "survival", "vision": "sonar"}, "allowed names: geometric, rendered"),
        ({"name": "survival", "n_robots": 0}, "n_robots"),
        ({"name": "mate", "n_robots": 1}, "n_robots must be >= 2"),
        ({"name": "survival", "seed": -1}, "seed"),
        ({"name": "survival", "seed": "zero"}, "seed"),
        ({"name": "search", "collision_penalty": -1.0}, "collision_penalty"),
    ],
)
def test_bad_load_arguments_raise_value_error(kwargs, match):
    kwargs = dict(kwargs)
    name = kwargs.pop("name")
    kwargs.setdefault("seed", 0)
    with pytest.raises(ValueError, match=match):
        tasks.load(name, **kwargs)


@pytest.mark.parametrize(
    ("field", "value"),
    [("initial_energy", -10.0), ("max_energy", 50.0), ("max_recharge_steps", 0)],
)
def test_invalid_survival_config_raises_before_loading(field, value):
    with pytest.raises(ValueError, match=field):
        tasks.load("survival", seed=0, survival=SurvivalConfig(**{field: value}))


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda a: a.__setitem__("wheels", np.full((4, 2), np.nan)), "'wheels' must be finite"),
        (lambda a: a.__setitem__("wheels", np.full((4, 2), 2.0)), r"'wheels' must be in \[-1.3"),
        (lambda a: a.__setitem__("led", np.full(4, -0.5)), r"'led' must be in \[0.0, 1.0\]"),
        (lambda a: a.__setitem__("mate", np.zeros(3)), r"'mate' must have shape \(4,\)"),
        (lambda a: a.pop("recharge"), r"missing \['recharge'\]"),
        (lambda a: a.__setitem__("jump", np.zeros(4)), r"unknown \['jump'\]"),
    ],
)
def test_bad_actions_raise_value_error(mutate, match):
    env = tasks.load("survival", seed=0)
    env.reset()
    action = wheels_action(env, np.zeros((4, 2)))
    mutate(action)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_bad_action_type_raises():
    env = tasks.load("forage", seed=0)
    env.reset()
    with pytest.raises(ValueError, match="action must be a dict"):
        env.step(np.zeros(3))


# --- Survival ----------------------------------------------------------------------------------
def test_survival_docking_rewards_the_right_robot_and_recharges():
    env = tasks.load("survival", seed=0)
    env.reset()
    place(
        env,
        {0: (-0.5, 0.0, 0.0), 1: (0.6, 0.6, 0.0), 2: (-0.6, 0.7, 0.0), 3: (0.6, -0.7, 0.0)},
        packs={0: (0.0, 0.0), 1: (0.9, -0.2), 2: (-0.9, -0.9), 3: (0.2, 0.9), 4: (-0.2, -0.5)},
    )
    wheels = np.zeros((4, 2))
    wheels[0] = 0.4
    rewards = []
    for _ in range(15):
        ts = env.step(wheels_action(env, wheels, recharge=np.ones(4)))
        rewards.append(ts.reward)
        if ts.observation["docked"][0]:
            break
    assert ts.observation["docked"].tolist() == [1.0, 0.0, 0.0, 0.0]
    assert np.array_equal(rewards[-1], [1.0, 0.0, 0.0, 0.0])
    assert sum(r.sum() for r in rewards) == 1.0
    energy = ts.observation["energy"][0]
    ts = env.step(wheels_action(env, wheels, recharge=np.ones(4)))
    assert ts.observation["energy"][0] == energy + 5
    assert ts.observation["recharge_steps"][0] == 1
    assert np.array_equal(ts.reward, np.zeros(4))
    ts = env.step(wheels_action(env, wheels, recharge=np.zeros(4)))  # stop
    assert ts.observation["docked"][0] == 0.0 and ts.observation["recharge_steps"][0] == 0


def test_survival_mating_rewards_both_partners_and_led_is_observed():
    env = tasks.load("survival", seed=0, n_packs=0)
    env.reset()
    gap = math.sqrt(0.3**2 - 0.04**2) + 2 * 0.111  # IR ports 0.3 m apart
    place(
        env,
        {
            0: (-gap / 2, 0.0, 0.0),
            1: (gap / 2, 0.0, math.pi),
            2: (-0.8, 0.8, 0.0),
            3: (0.8, -0.8, 0.0),
        },
    )
    mate = np.array([1.0, 1.0, 1.0, 0.0])
    action = wheels_action(env, np.zeros((4, 2)), mate=mate)
    action["led"] = np.array([1.0, 0.0, 0.0, 0.0])
    # The IR exchange takes 2 steps (mate_consecutive_steps); observed at the end of its second
    # step, before the partners turn away (mate_reflex).
    ts = env.step(action)
    assert np.array_equal(ts.reward, np.zeros(4))
    ts = env.step(action)
    assert np.array_equal(ts.reward, [1.0, 1.0, 0.0, 0.0])
    assert ts.observation["led_on"].tolist() == [1.0, 0.0, 0.0, 0.0]
    assert ts.observation["nearest_led"][1, 2] == 1.0  # robot 1 sees robot 0's green LED
    assert abs(ts.observation["nearest_led"][1, 0]) < math.radians(10)  # straight ahead


def test_survival_ends_with_discount_zero_when_all_robots_are_dead():
    env = tasks.load("survival", seed=0, survival=SurvivalConfig(initial_energy=3.0))
    env.reset()
    types = []
    for _ in range(3):
        ts = env.step(wheels_action(env, np.zeros((4, 2))))
        types.append(ts.step_type)
    assert types == [StepType.MID, StepType.MID, StepType.LAST]
    assert ts.discount == 0.0
    assert ts.observation["energy"].tolist() == [0.0] * 4


# --- Forage -------------------------------------------------------------------------------------
def steer_to_battery(obs) -> np.ndarray:
    """A hand-written reactive Forage controller: turn towards the pack, then drive on."""
    bearing, _, visible = obs["nearest_battery"][0]
    if not visible:
        return commands.wheel_speeds(commands.command_index("spin_left"))[None]
    turn = float(np.clip(1.2 * bearing, -0.25, 0.25))
    return np.array([[0.3 - turn, 0.3 + turn]])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_forage_starts_with_a_pack_in_view_and_rewards_the_capture(seed):
    env = tasks.load("forage", seed=seed)
    ts = env.reset()
    assert ts.observation["nearest_battery"][0, 2] == 1.0
    assert env.task.frame.visible[0, BATTERY]
    total = 0.0
    while not ts.last():
        ts = env.step(wheels_action(env, steer_to_battery(ts.observation)))
        total += ts.reward[0]
    assert ts.discount == 0.0, "the scripted approach did not capture the pack"
    assert ts.reward.tolist() == [1.0] and total == 1.0
    assert ts.observation["docked"][0] == 1.0


def test_forage_without_a_capture_is_cut_with_discount_one():
    env = tasks.load("forage", seed=0, episode_steps=5)
    env.reset()
    for _ in range(5):
        ts = env.step(wheels_action(env, [[-0.2, 0.2]]))  # spin in place
        assert ts.reward.tolist() == [0.0]
    assert ts.last() and ts.discount == 1.0


# --- Mate ---------------------------------------------------------------------------------------
def test_mate_starts_in_view_with_leds_on_and_rewards_both_at_the_exchange():
    env = tasks.load("mate", seed=3)
    ts = env.reset()
    seen = np.maximum(ts.observation["nearest_led"][:, 2], ts.observation["nearest_face"][:, 2])
    assert seen.tolist() == [1.0, 1.0]
    assert ts.observation["led_on"].tolist() == [1.0, 1.0]
    gap = math.sqrt(0.3**2 - 0.04**2) + 2 * 0.111
    place(env, {0: (-gap / 2, 0.2, 0.0), 1: (gap / 2, 0.2, math.pi)})
    ts = env.step(wheels_action(env, np.zeros((2, 2))))  # the 2-step exchange's first step
    assert ts.reward.tolist() == [0.0, 0.0] and not ts.last()
    ts = env.step(wheels_action(env, np.zeros((2, 2))))
    assert ts.reward.tolist() == [1.0, 1.0]
    assert ts.last() and ts.discount == 0.0


def test_mate_partner_acts_through_its_own_action_row():
    env = tasks.load("mate", seed=3)
    env.reset()
    place(env, {0: (-0.6, 0.0, 0.0), 1: (0.6, 0.0, math.pi)})
    # Only robot 1 drives; robot 0 waits. They meet because the partner's row moves it.
    found = None
    for k in range(40):
        ts = env.step(wheels_action(env, [[0.0, 0.0], [0.3, 0.3]]))
        if ts.reward[0] > 0:
            found = k
            break
    assert found is not None
    x1 = env.task.world.poses()[1, 0]
    assert x1 < 0.5 and env.task.world.poses()[0, 0] == pytest.approx(-0.6, abs=0.01)


# --- Search -------------------------------------------------------------------------------------
def test_search_rewards_progress_and_penalises_collisions():
    env = tasks.load("search", seed=0, n_robots=1, n_packs=0)
    env.reset()
    place(env, {0: (0.0, 0.0, 0.0)})
    free = [env.step(wheels_action(env, [[0.5, 0.5]])).reward[0] for _ in range(6)]
    assert 0.7 < free[-1] <= 1.0  # ~5 cm per step at 0.5 m/s
    place(env, {0: (0.9, 0.0, 0.0)})  # facing the east wall, 0.15 m of free space
    rewards = [env.step(wheels_action(env, [[0.5, 0.5]])).reward[0] for _ in range(8)]
    assert rewards[-1] <= -0.9  # pressed against the wall, no progress
    spin = env.step(wheels_action(env, [[-0.3, -0.3]])).reward[0]
    assert spin > -1.0  # backing off frees it (negative progress, but less than the penalty)


# --- vision provider option ------------------------------------------------------------
def test_rendered_vision_is_a_task_option():
    env = tasks.load("forage", seed=0, vision="rendered")
    from cyber_rodent.vision.rendered import RenderedVision

    assert isinstance(env.task.vision, RenderedVision)
    ts = env.reset()
    for key, spec in env.observation_spec().items():
        spec.validate(ts.observation[key])
    assert ts.observation["nearest_battery"][0, 2] == 1.0
    for _ in range(3):
        ts = env.step(wheels_action(env, steer_to_battery(ts.observation)))
        for key, spec in env.observation_spec().items():
            spec.validate(ts.observation[key])
