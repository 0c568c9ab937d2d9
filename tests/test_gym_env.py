"""The Gymnasium environments: API conformance, spaces, seeding, and the behaviours' rewards."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cyber_rodent  # noqa: F401  (registers the ids)
from behaviours import FORAGE, MATE, SEARCH, BehaviourPolicies
from behaviours.episodes import BehaviourEpisode
from cyber_rodent.commands import N_COMMANDS, command_index
from cyber_rodent.gym_env import (
    OBSERVATION_NAMES,
    OBSERVATION_UNITS,
    CyberRodentEnv,
    decode_action,
)
from cyber_rodent.robot import cyber_rodent as paper_robot
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.tasks.rewards import coverage_cells
from cyber_rodent.vision import CameraConfig

IDS = ["CyberRodent/Forage-v0", "CyberRodent/Mate-v0", "CyberRodent/Search-v0",
       "CyberRodent/Survival-v0"]  # fmt: skip
#: A small camera for the pixel tests (64 x 256 strips): the pixels' shape follows it.
SMALL_CAMERA = CameraConfig(view_width=64, height=64)

#: The paper's robot, read from its MJCF file and sensor table.
CR = paper_robot()
#: Its range sensors as (name, bearing in degrees, range in metres).
RANGE_ROWS = [(row.name, row.bearing_deg, row.limit) for row in CR.range_sensors]


def index(name: str) -> int:
    return OBSERVATION_NAMES.index(name)


def run_checker(env: gym.Env) -> list[str]:
    """``check_env``'s warnings (it raises on a failure)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    return [str(w.message) for w in caught]


# --- registration and conformance --------------------------------------------------------------
def test_import_registers_the_ids_without_importing_mujoco() -> None:
    code = (
        "import sys, cyber_rodent, gymnasium; "
        "print(sorted(k for k in gymnasium.registry if k.startswith('CyberRodent/'))); "
        "print('mujoco' in sys.modules, 'cyber_rodent.gym_env' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    ids, loaded = out.stdout.strip().splitlines()
    assert ids == str(sorted(IDS))
    assert loaded == "False False"


@pytest.mark.parametrize("action", ["discrete", "continuous"])
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_passes_without_warnings(env_id: str, action: str) -> None:
    env = gym.make(env_id, action=action, render_mode="rgb_array")
    assert run_checker(env.unwrapped) == []
    env.close()


@pytest.mark.parametrize(
    "env_id, action", [(IDS[0], "continuous"), (IDS[1], "discrete"), (IDS[2], "continuous"),
                       (IDS[3], "discrete")],  # fmt: skip
)
def test_check_env_passes_with_pixels_and_make_s_wrappers(env_id: str, action: str) -> None:
    env = gym.make(env_id, action=action, pixels=True, masks=True, camera=SMALL_CAMERA)
    warned = run_checker(env)  # OrderEnforcing and PassiveEnvChecker around the env
    # The one warning: the checker recommends checking env.unwrapped.
    assert len(warned) == 1 and "different from the unwrapped version" in warned[0]
    assert run_checker(env.unwrapped) == []
    env.close()


@pytest.mark.slow
@pytest.mark.parametrize("pixels", [False, True])
@pytest.mark.parametrize("action", ["discrete", "continuous"])
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_every_combination(env_id: str, action: str, pixels: bool) -> None:
    env = gym.make(env_id, action=action, pixels=pixels, masks=pixels, render_mode="rgb_array")
    assert run_checker(env.unwrapped) == []
    assert len(run_checker(env)) == 1
    env.close()


# --- spaces -------------------------------------------------------------------------------------
def test_observation_names_units_and_bounds_are_documented() -> None:
    env = CyberRodentEnv("survival", observation="raw")
    space = env.observation_space
    assert isinstance(space, gym.spaces.Box) and space.dtype == np.float32
    assert space.shape == (len(OBSERVATION_NAMES),) == (21,) == (len(OBSERVATION_UNITS),)
    assert env.observation_names[:8] == tuple(name for name, _, _ in RANGE_ROWS)
    low, high = space.low, space.high
    assert high[index("range_front")] == np.float32(1.0)
    assert high[index("range_back")] == np.float32(0.3)
    for target in ("led", "face", "battery"):
        assert low[index(f"{target}_bearing")] == np.float32(-math.pi)
        assert high[index(f"{target}_bearing")] == np.float32(math.pi)
        assert high[index(f"{target}_distance")] == np.float32(CameraConfig().max_range)
        assert high[index(f"{target}_visible")] == 1.0
    assert high[index("energy")] == 200.0 and high[index("recharge_steps")] == 40.0
    assert (low[[index("energy"), index("docked"), index("range_front")]] == 0).all()
    forage = CyberRodentEnv("forage", observation="raw")
    assert forage.observation_space.high[index("energy")] == 1e6
    assert np.array_equal(env.observation_bounds.low, low)
    assert np.array_equal(env.observation_bounds.high, high)


def test_the_default_observation_is_normalised_by_the_bounds() -> None:
    env = CyberRodentEnv("survival")
    assert env.observation_kind == "normalised"
    space = env.observation_space
    assert isinstance(space, gym.spaces.Box) and space.dtype == np.float32
    bearings = [index(f"{target}_bearing") for target in ("led", "face", "battery")]
    others = [i for i in range(21) if i not in bearings]
    assert space.shape == (21,) and (space.high == 1).all()
    assert (space.low[bearings] == -1).all() and (space.low[others] == 0).all()
    scale = env.observation_scale
    # The ranges read as proximities (0 = nothing in range, 1 = touching), the rest by bounds.
    assert scale.zero[index("range_front")] == 1.0 and scale.one[0] == 0.0
    assert scale.zero[index("range_back")] == 0.3
    for target in ("led", "face", "battery"):  # bearings: 0 ahead, -1 and 1 behind
        assert scale.zero[index(f"{target}_bearing")] == 0.0
        assert scale.one[index(f"{target}_bearing")] == math.pi
        assert scale.one[index(f"{target}_distance")] == CameraConfig().max_range
    assert scale.one[index("energy")] == 200.0 and scale.one[index("recharge_steps")] == 40.0
    raw = np.zeros(21, dtype=np.float32)
    raw[index("range_front")] = 0.25  # 0.25 of 1.0 m: proximity 0.75
    raw[index("range_back")] = 0.3  # nothing in range
    raw[index("battery_bearing")] = math.pi / 2  # on the left: 0.5
    raw[index("face_bearing")] = -3 * math.pi / 4  # behind on the right: -0.75
    raw[index("battery_distance")] = CameraConfig().max_range / 4
    raw[index("energy")] = 150.0
    raw[index("recharge_steps")] = 10.0
    normalised = scale.normalise(raw)
    assert normalised.dtype == np.float32
    expected = {"range_front": 0.75, "range_back": 0.0, "range_left": 1.0, "led_bearing": 0.0,
                "battery_bearing": 0.5, "face_bearing": -0.75, "battery_distance": 0.25,
                "energy": 0.75, "recharge_steps": 0.25, "docked": 0.0}  # fmt: skip
    for name, value in expected.items():
        assert normalised[index(name)] == pytest.approx(value, abs=1e-7), name
    assert np.allclose(scale.raw(normalised), raw, rtol=1e-6, atol=1e-7)
    # Beyond the bounds is clipped; a reversed entry reads +0.0, not -0.0.
    beyond = scale.normalise(np.full(21, 1e9))
    assert ((beyond == 0) | (beyond == 1)).all() and not np.signbit(beyond).any()
    assert (beyond[:8] == 0).all() and (beyond[8:] == 1).all()  # ranges: nothing in range
    below = scale.normalise(np.full(21, -1e9))
    assert (below[:8] == 1).all() and np.array_equal(below[8:], space.low[8:])  # bearings -1
    assert np.array_equal(scale.low, space.low) and np.array_equal(scale.high, space.high)
    # The endless energy of Forage, Mate and Search reads full.
    forage = CyberRodentEnv("forage")
    obs, _ = forage.reset(seed=0)
    assert obs[index("energy")] == 1.0
    obs, *_ = forage.step(command_index("stop"))
    assert 1.0 - 1e-5 < obs[index("energy")] <= 1.0


def test_raw_observations_keep_their_values() -> None:
    """The raw layout and values, recorded before the observation was normalised by default
    (reset with seed 0, then 5 steps of arc_left)."""
    r3 = 0.30000001192092896
    far = 3.2526912689208984
    recorded = {
        "forage": (
            [1.0, *[r3] * 7, 0.0, far, 0.0, 0.0, far, 0.0, -2.4478631019592285,
             0.6227758526802063, 1.0, 1e6, 0.0, 0.0, 0.0],
            [0.09028934687376022, 0.1307847797870636, 0.08267983049154282, r3,
             0.22677887976169586, r3, r3, r3, 0.0, far, 0.0, 0.0, far, 0.0, -2.85066294670105,
             0.7883510589599609, 1.0, 999995.0, 0.0, 0.0, 0.0],
        ),
        "mate": (
            [1.0, *[r3] * 7, 1.5750772953033447, 1.2821811437606812, 1.0, 0.0, far, 0.0, 0.0,
             far, 0.0, 1e6, 1.0, 0.0, 0.0],
            [1.0, *[r3] * 7, 0.32672497630119324, 1.1253541707992554, 1.0, 0.0, far, 0.0, 0.0,
             far, 0.0, 999995.0, 1.0, 0.0, 0.0],
        ),
        "search": (
            [0.3254320025444031, *[r3] * 7, 0.0, far, 0.0, -2.9959053993225098,
             1.1266417503356934, 1.0, 2.4175689220428467, 0.6227758526802063, 1.0, 1e6, 0.0,
             0.0, 0.0],
            [0.48982423543930054, r3, r3, r3, 0.21583543717861176, r3, r3,
             0.18345630168914795, 0.0, far, 0.0, 0.0, far, 0.0, 0.6013655662536621,
             0.5633728504180908, 1.0, 999995.0, 0.0, 0.0, 0.0],
        ),
        "survival": (
            [1.0, *[r3] * 7, 0.0, far, 0.0, 0.0, far, 0.0, -2.4478631019592285,
             0.6227758526802063, 1.0, 100.0, 0.0, 0.0, 0.0],
            [0.09028934687376022, 0.1307847797870636, 0.08267983049154282, r3,
             0.22677887976169586, r3, r3, r3, 0.0, far, 0.0, 0.0, far, 0.0, -2.85066294670105,
             0.7883510589599609, 1.0, 95.0, 0.0, 0.0, 0.0],
        ),
    }  # fmt: skip
    arc = command_index("arc_left")
    for task, (first, fifth) in recorded.items():
        raw = CyberRodentEnv(task, observation="raw")
        normalised = CyberRodentEnv(task)
        obs, _ = raw.reset(seed=0)
        scaled, _ = normalised.reset(seed=0)
        assert np.array_equal(obs, np.array(first, dtype=np.float32)), task
        assert np.array_equal(scaled, raw.observation_scale.normalise(obs)), task
        for _ in range(5):
            action = [arc, 1] if task == "survival" else arc
            obs, *_ = raw.step(action)
            scaled, *_ = normalised.step(action)
        assert np.array_equal(obs, np.array(fifth, dtype=np.float32)), task
        assert np.array_equal(scaled, raw.observation_scale.normalise(obs)), task


def test_action_spaces() -> None:
    assert CyberRodentEnv("mate").action_space == gym.spaces.Discrete(N_COMMANDS)
    survival = CyberRodentEnv("survival")
    assert survival.action_space == gym.spaces.MultiDiscrete([N_COMMANDS, 2])
    assert survival.action_names == ("command", "recharge")
    box = CyberRodentEnv("search", action="continuous").action_space
    assert isinstance(box, gym.spaces.Box) and box.shape == (2,)
    assert box.low.tolist() == [-1.0, -1.0] and box.high.tolist() == [1.0, 1.0]
    fast = CyberRodentEnv("survival", action="continuous", max_wheel_speed=CR.top_speed)
    assert fast.action_names == ("left_wheel", "right_wheel", "recharge")
    assert fast.action_space.high.tolist() == pytest.approx([1.3, 1.3, 1.0])
    assert fast.action_space.low.tolist() == pytest.approx([-1.3, -1.3, -1.0])
    wheels, switch = np.zeros(2), np.zeros(1, dtype=bool)
    for recharge, on in ((0.4, True), (0.0, False), (-0.4, False)):
        decode_action(np.array([0.25, -1.25, recharge]), fast.action_space, wheels, switch)
        assert wheels.tolist() == [0.25, -1.25] and switch[0] == on  # on above 0
    decode_action([command_index("arc_left"), 1], survival.action_space, wheels, switch)
    assert wheels.tolist() == [0.2, 0.45] and switch[0]  # arc_left, keep recharging


def test_bad_options_and_actions_raise() -> None:
    with pytest.raises(ValueError, match="task must be one of"):
        CyberRodentEnv("dance")
    with pytest.raises(ValueError, match="observation must be one of normalised, raw, got 'bogus'"):
        CyberRodentEnv("forage", observation="bogus")
    with pytest.raises(ValueError, match="observation must be one of"):
        gym.make("CyberRodent/Search-v0", observation=None)
    with pytest.raises(ValueError, match="Survival has none"):
        CyberRodentEnv("survival", reward="shaped")
    with pytest.raises(ValueError, match="masks=True needs pixels=True"):
        CyberRodentEnv("forage", masks=True)
    with pytest.raises(ValueError, match="only Mate has a partner"):
        CyberRodentEnv("forage", partner_policy=lambda obs: 0)
    with pytest.raises(ValueError, match="max_wheel_speed"):
        CyberRodentEnv("forage", action="continuous", max_wheel_speed=2.0)
    env = CyberRodentEnv("forage", action="continuous")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(2, dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must lie in"):
        env.step(np.array([1.1, 0.0], dtype=np.float32))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    discrete = CyberRodentEnv("forage")
    discrete.reset(seed=0)
    with pytest.raises(ValueError, match="must lie in"):
        discrete.step(N_COMMANDS)
    with pytest.raises(ValueError, match="integer"):
        discrete.step(0.5)


# --- episodes -----------------------------------------------------------------------------------
@pytest.mark.parametrize("observation", ["normalised", "raw"])
@pytest.mark.parametrize("env_id", IDS)
def test_observations_stay_in_bounds_and_change(env_id: str, observation: str) -> None:
    env = gym.make(env_id, action="continuous", observation=observation)
    env.action_space.seed(1)
    obs, _ = env.reset(seed=1)
    seen = [obs]
    for _ in range(30):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert obs in env.observation_space and isinstance(reward, float)
        seen.append(obs)
        if terminated or truncated:
            break
    trace = np.stack(seen)
    assert (trace.std(axis=0) > 0).sum() >= 3  # ranges, bearings, energy... move
    env.close()


@pytest.mark.parametrize("observation", ["normalised", "raw"])
@pytest.mark.parametrize("action", ["discrete", "continuous"])
@pytest.mark.parametrize("env_id", IDS)
def test_every_observation_of_many_random_steps_lies_in_the_space(
    env_id: str, action: str, observation: str
) -> None:
    env = gym.make(env_id, action=action, observation=observation)
    env.action_space.seed(2)
    obs, _ = env.reset(seed=2)
    space = env.observation_space
    assert obs in space
    for _ in range(300):  # random episodes: starts, dockings, deaths, truncations
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert obs in space and np.isfinite(obs).all()
        if terminated or truncated:
            obs, _ = env.reset()
            assert obs in space
    env.close()


def test_same_seed_same_trajectory_and_another_seed_another() -> None:
    def rollout(seed: int) -> tuple[np.ndarray, list[float]]:
        env = gym.make("CyberRodent/Survival-v0")
        env.action_space.seed(3)
        obs, _ = env.reset(seed=seed)
        trace, rewards = [obs], []
        for _ in range(25):
            obs, reward, *_ = env.step(env.action_space.sample())
            trace.append(obs)
            rewards.append(float(reward))
        return np.stack(trace), rewards

    a, b, c = rollout(11), rollout(11), rollout(12)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]
    assert not np.array_equal(a[0], c[0])


def test_a_reset_without_seed_continues_the_seeded_stream() -> None:
    env = CyberRodentEnv("search")
    env.reset(seed=4)
    first = env.reset()[0]
    env.reset(seed=4)
    assert np.array_equal(env.reset()[0], first)


def shipped_episode(name: str, behaviour: int, seed: int, steps: int = 100):
    """The shipped greedy behaviour's episode in ``BehaviourEpisode``: (commands, rewards)."""
    policies = BehaviourPolicies.load_default()
    episode = BehaviourEpisode(name)
    states = episode.reset(np.random.default_rng(seed))
    commands, rewards, terminal = [], [], False
    for _ in range(steps):
        action = policies.act(behaviour, states)
        result = episode.step(action)
        commands.append(action.copy())
        rewards.append(result.rewards[0])
        states, terminal = result.states, result.terminal
        if terminal:
            break
    return np.array(commands), rewards, terminal


@pytest.mark.parametrize("name, behaviour, seed", [("forage", FORAGE, 0), ("mate", MATE, 1),
                                                   ("search", SEARCH, 2)])  # fmt: skip
def test_shaped_reward_is_the_training_reward_step_by_step(
    name: str, behaviour: int, seed: int
) -> None:
    commands, expected, terminal = shipped_episode(name, behaviour, seed)
    assert terminal == (name != "search")  # the goal is reached, so its reward is compared too
    partner = iter(commands[:, -1])  # Mate: robot 1's commands of the episode

    def replay(obs: np.ndarray) -> int:
        return int(next(partner))

    env = CyberRodentEnv(name, reward="shaped", partner_policy=replay if name == "mate" else None)
    env.reset(seed=seed)  # env.np_random is np.random.default_rng(seed), the episode's generator
    rewards = []
    for command in commands[:, 0]:
        _, reward, terminated, truncated, _ = env.step(command)
        rewards.append(reward)
    assert rewards == expected  # the same floats, bit for bit
    assert terminated == terminal and truncated == (not terminal)


def test_sparse_reward_is_one_at_the_capture() -> None:
    commands, _, terminal = shipped_episode("forage", FORAGE, 0)
    assert terminal
    env = CyberRodentEnv("forage")
    obs, _ = env.reset(seed=0)
    assert obs[index("battery_visible")] == 1.0  # the start condition
    rewards = [env.step(c) for c in commands[:, 0]]
    assert [r[1] for r in rewards] == [0.0] * (len(commands) - 1) + [1.0]
    obs, _, terminated, truncated, info = rewards[-1]
    assert terminated and not truncated and info["is_success"]
    assert obs[index("docked")] == 1.0 and env.survival.docked[0]


def test_mate_sparse_reward_at_the_ir_exchange_with_a_partner_policy() -> None:
    seen = []

    def partner(obs: np.ndarray) -> int:
        seen.append(obs)
        return command_index("stop")

    env = CyberRodentEnv("mate", partner_policy=partner)
    env.reset(seed=0)
    along = math.sqrt(0.3**2 - 0.04**2) + 2 * 0.111  # IR ports 0.3 m apart, facing
    env.world.set_robot_pose(0, -along / 2, 0.0, 0.0)
    env.world.set_robot_pose(1, along / 2, 0.0, math.pi)
    mujoco.mj_forward(env.world.model, env.world.data)
    stop = command_index("stop")
    first = env.step(stop)
    second = env.step(stop)  # the exchange takes 2 steps (mate_consecutive_steps)
    assert first[1] == 0.0 and not first[2]
    assert second[1] == 1.0 and second[2] and second[4]["is_success"]
    assert len(seen) == 2 and seen[0].shape == (21,)
    assert seen[1][index("led_visible")] == 1.0  # the partner sees robot 0's LED


def test_search_sparse_rewards_sum_to_the_cells_covered() -> None:
    env = CyberRodentEnv("search", observation="raw")  # ranges in metres
    obs, _ = env.reset(seed=0)
    positions = [env.world.poses()[0, :2].copy()]
    total = 0.0
    truncated = False
    forward, spin = command_index("forward"), command_index("spin_left")
    while not truncated:  # a wall follower: forward, spin away from what is close ahead
        blocked = obs[index("range_front")] < 0.4 or (obs[1:5] < 0.25).any()
        obs, reward, terminated, truncated, info = env.step(spin if blocked else forward)
        assert not terminated
        total += reward
        positions.append(env.world.poses()[0, :2].copy())
    assert env.steps == 100
    assert total == coverage_cells(np.array(positions)) - 1 == info["coverage_cells"] - 1
    assert total > 5


def test_survival_capture_recharge_and_death() -> None:
    env = CyberRodentEnv(
        "survival", survival=SurvivalConfig(initial_energy=30.0), observation="raw"
    )  # energy in its own units
    env.reset(seed=0)
    env.world.set_robot_pose(0, -0.5, 0.0, 0.0)
    for j, xy in enumerate([(0.0, 0.0), (0.9, -0.2), (-0.9, -0.9), (0.2, 0.9), (-0.2, -0.5)]):
        env.world.set_pack_position(j, *xy)
    env.survival.refresh_pack_positions()
    mujoco.mj_forward(env.world.model, env.world.data)
    forward, stop = command_index("forward_slow"), command_index("stop")
    rewards = []
    while not env.survival.docked[0]:
        obs, reward, terminated, _, info = env.step([forward, 1])
        rewards.append(reward)
        assert len(rewards) < 20, "the robot did not dock"
    assert rewards[-1] == 1.0 and sum(rewards) == 1.0 and info["captures"] == 1
    energy = obs[index("energy")]
    obs, reward, *_ = env.step([forward, 1])
    assert obs[index("energy")] == energy + 5 and obs[index("recharge_steps")] == 1
    assert reward == 0.0
    obs, *_ = env.step([stop, 0])  # stop recharging: released with the reflex
    assert obs[index("docked")] == 0.0
    terminated = False
    while not terminated:
        obs, reward, terminated, truncated, _ = env.step([stop, 1])
        assert not truncated
    assert obs[index("energy")] == 0.0 and not env.survival.alive[0]


def test_pixels_and_masks() -> None:
    env = CyberRodentEnv("forage", pixels=True, masks=True, camera=SMALL_CAMERA)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state", "pixels", "masks"}
    assert obs["pixels"].shape == obs["masks"].shape == (64, 256, 3)
    assert obs["pixels"].dtype == obs["masks"].dtype == np.uint8
    assert set(np.unique(obs["masks"])) <= {0, 255}
    assert obs["state"][index("battery_visible")] == 1.0
    assert obs["masks"][..., 2].any()  # the pack in view is segmented as battery
    assert not obs["masks"][..., 0].any()  # no LED: the only robot's own is not in view
    after, *_ = env.step(command_index("spin_left"))
    assert not np.array_equal(after["pixels"], obs["pixels"])
    env.close()
    env.close()  # idempotent


def test_render_rgb_array() -> None:
    env = gym.make("CyberRodent/Mate-v0", render_mode="rgb_array", render_width=160,
                   render_height=120)  # fmt: skip
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8 and image.std() > 0
    env.close()
    assert CyberRodentEnv("mate").render() is None
