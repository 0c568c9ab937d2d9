"""dm_env conformance of the four tasks: spec checks, long random runs, determinism."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import tree
from absl.testing import absltest
from dm_env import StepType, test_utils

from cyber_rodent import tasks
from cyber_rodent.survival import SurvivalWorld
from cyber_rodent.world import WorldConfig


def random_action(env, rng: np.random.Generator) -> dict:
    return {
        key: rng.uniform(spec.minimum, spec.maximum, size=spec.shape)
        for key, spec in env.action_spec().items()
    }


class _Conformance(test_utils.EnvironmentTestMixin):
    task_name = ""

    def make_object_under_test(self):
        # Short episodes, so the action sequence below runs through episode ends and resets.
        return tasks.load(self.task_name, seed=1, episode_steps=8)

    def make_action_sequence(self):
        rng = np.random.default_rng(0)
        for _ in range(30):
            yield random_action(self.environment, rng)


class SurvivalConformance(_Conformance, absltest.TestCase):
    task_name = "survival"


class ForageConformance(_Conformance, absltest.TestCase):
    task_name = "forage"


class MateConformance(_Conformance, absltest.TestCase):
    task_name = "mate"


class SearchConformance(_Conformance, absltest.TestCase):
    task_name = "search"


@pytest.mark.parametrize("name", tasks.TASK_NAMES)
def test_observations_finite_and_within_specs_over_1000_random_steps(name):
    env = tasks.load(name, seed=2)
    obs_spec, reward_spec = env.observation_spec(), env.reward_spec()
    rng = np.random.default_rng(3)
    ts = env.reset()
    episodes = steps = 0
    for _ in range(1000):
        for key, spec in obs_spec.items():
            value = ts.observation[key]
            assert np.all(np.isfinite(value)), key
            spec.validate(value)  # shape, dtype and bounds
        if ts.step_type is not StepType.FIRST:
            reward_spec.validate(ts.reward)
            assert np.all(np.isfinite(ts.reward))
            assert ts.discount in (0.0, 1.0)
        if ts.step_type is StepType.LAST:
            episodes += 1
        ts = env.step(random_action(env, rng))
        steps += 1
    assert episodes >= 2  # resets were exercised too


def _trajectory(name: str, seed: int, steps: int = 40) -> list:
    env = tasks.load(name, seed=seed)
    rng = np.random.default_rng(11)
    out = [env.reset()]
    for _ in range(steps):
        out.append(env.step(random_action(env, rng)))
    return out


def _flatten(trajectory: list) -> np.ndarray:
    parts = []
    for ts in trajectory:
        parts += [np.ravel(x) for x in tree.flatten(ts.observation)]
        if ts.reward is not None:
            parts += [np.ravel(ts.reward), np.ravel(ts.discount)]
    return np.concatenate(parts)


@pytest.mark.parametrize("name", tasks.TASK_NAMES)
def test_same_seed_same_trajectory_different_seed_different_start(name):
    a = _trajectory(name, seed=7)
    b = _trajectory(name, seed=7)
    assert np.array_equal(_flatten(a), _flatten(b))  # bit-identical
    c = _trajectory(name, seed=8, steps=0)
    assert not np.array_equal(_flatten(a[:1]), _flatten(c))


def test_successive_resets_draw_new_initial_states():
    env = tasks.load("survival", seed=0)
    first = env.reset()
    env.step(random_action(env, np.random.default_rng(0)))
    second = env.reset()
    assert not np.array_equal(first.observation["range"], second.observation["range"])
    assert env.survival.step_count == 0


def test_dm_control_path_equals_lean_path():
    """The task steps the same physics as SurvivalWorld.step: bit-identical trajectories."""
    env = tasks.load("survival", seed=4)
    env.reset()
    lean = SurvivalWorld(WorldConfig())
    lean.world.data.qpos[:] = env.physics.data.qpos
    lean.world.model.body_pos[:] = env.physics.model.body_pos
    lean.refresh_pack_positions()
    lean.rng.bit_generator.state = env.survival.rng.bit_generator.state  # same reflex draws
    mujoco.mj_forward(lean.world.model, lean.world.data)
    rng = np.random.default_rng(5)
    for _ in range(95):  # all robots die at step 100 (no docking): stay inside the episode
        action = random_action(env, rng)
        action["wheels"] = np.clip(action["wheels"], -0.6, 0.6)
        assert env.step(action).mid()
        lean.step(
            action["wheels"], action["led"] > 0.5, action["mate"] > 0.5, action["recharge"] > 0.5
        )
    assert np.array_equal(env.physics.data.qpos, lean.world.data.qpos)
    assert np.array_equal(env.survival.energy, lean.energy)
