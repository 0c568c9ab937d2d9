"""The PettingZoo colony's baseline policy: shipped behaviours with evolved controllers, run by
the robot step on the baseline bundle shipped in cyber_rodent/baseline."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cyber_rodent.colony_baseline import baseline_dir
from cyber_rodent.colony_env import BaselinePolicy, baseline_policy, parallel_env
from cyber_rodent.commands import COMMAND_SPEEDS
from cyber_rodent.robot_step import MATE, check_vectors
from cyber_rodent.survival import SurvivalConfig


def test_baseline_docks_and_mates_within_500_steps() -> None:
    env = parallel_env(max_cycles=500)
    observations, _ = env.reset(seed=0)
    policy = baseline_policy(env)
    captures = matings = 0
    while env.agents:
        observations, _, _, _, infos = env.step(policy(observations))
        captures += sum(info["captured"] for info in infos.values())
        matings += sum(info["mate_partner"] is not None for info in infos.values())
    assert env.steps == 500
    assert captures >= 1 and matings >= 1, (captures, matings)


def test_actions_of_both_kinds_are_the_steps_decisions() -> None:
    for kind in ("discrete", "continuous"):
        env = parallel_env(action=kind)
        env.reset(seed=3)
        policy = baseline_policy(env)
        for _ in range(40):
            actions = policy()
            raw = env.raw_observations()
            assert actions.keys() == set(env.agents)
            for agent, action in actions.items():
                assert env.action_space(agent).contains(action)
                d = policy.decide(agent, raw[agent])
                switches = [d.led, d.behaviour == MATE, d.continue_recharge]
                if kind == "discrete":
                    assert action.tolist() == [d.command, *map(int, switches)]
                else:
                    np.testing.assert_allclose(action[:2], COMMAND_SPEEDS[d.command], rtol=1e-6)
                    assert [bool(v > 0) for v in action[2:]] == switches
            env.step(actions)


def test_raw_observations_are_the_physical_observations() -> None:
    env = parallel_env(observation="raw")
    with pytest.raises(RuntimeError, match=r"call reset\(\)"):
        env.raw_observations()
    observations, _ = env.reset(seed=1)
    raw = env.raw_observations()
    assert raw.keys() == observations.keys()
    for agent, obs in observations.items():
        np.testing.assert_array_equal(raw[agent], obs)
        assert raw[agent].dtype == np.float32 and raw[agent].shape == (21,)
    policy = baseline_policy(env)
    for _ in range(5):
        observations, *_ = env.step(policy(observations))
    for agent in env.agents:
        np.testing.assert_array_equal(env.raw_observations()[agent], observations[agent])
    # With the default normalised observations, raw_observations still gives physical units.
    normalised = parallel_env()
    observations, _ = normalised.reset(seed=1)
    raw_env = parallel_env(observation="raw")
    expected, _ = raw_env.reset(seed=1)
    for agent in observations:
        np.testing.assert_array_equal(normalised.raw_observations()[agent], expected[agent])
        assert not np.array_equal(observations[agent], expected[agent])


def test_baseline_reads_each_entry_by_name_and_unit(monkeypatch) -> None:
    env = parallel_env()
    env.reset(seed=0)
    units = list(env.observation_units)
    units[env.observation_names.index("energy")] = "fraction of max_energy"
    monkeypatch.setattr(env, "observation_units", tuple(units))
    with pytest.raises(ValueError, match=r"observation 'energy': the baseline reads it in "
                                         r"'energy' .* the env has 'fraction of max_energy'"):
        baseline_policy(env)
    monkeypatch.setattr(env, "observation_names", tuple(
        "distance_to_led" if n == "led_distance" else n for n in env.observation_names
    ))  # fmt: skip
    with pytest.raises(ValueError, match=r"observation 'led_distance': .* has 'missing'"):
        BaselinePolicy(env)


def test_baseline_options_are_checked() -> None:
    env = parallel_env(n_robots=2, n_packs=2)
    env.reset(seed=0)
    policy = baseline_policy(env, agents=[4, 4])
    assert policy.rows == {"robot_0": 4, "robot_1": 4}
    with pytest.raises(ValueError, match=r"agents: every row must be an integer in \[0, 4\]"):
        baseline_policy(env, agents=[0, 5])
    with pytest.raises(ValueError, match=r"agents must give one row per robot \(2\)"):
        baseline_policy(env, agents=[0])
    other = parallel_env(survival=SurvivalConfig(max_recharge_steps=20))
    with pytest.raises(ValueError, match=r"max_recharge_steps 40; the env has 200 and 20"):
        baseline_policy(other)


def test_baseline_bundle_is_small_checked_and_documented() -> None:
    from behaviours.definitions import load_values
    from behaviours.portable import greedy_table

    root = baseline_dir()
    files = sorted(p.name for p in root.iterdir())
    assert files == ["baseline.json", "behaviours.json", "behaviours.npz", "bundle.json",
                     "controller_weights.npy", "test_vectors.npz"]  # fmt: skip
    assert sum(p.stat().st_size for p in root.iterdir()) < 300_000
    result = check_vectors(root)
    assert result.passed and result.backend == "table" and result.rows >= 300, result.line()
    # the shipped behaviours, as the package ships them today
    spec = json.loads((root / "bundle.json").read_text())
    with np.load(root / "behaviours.npz") as arrays:
        for name in ("mate", "forage", "search"):
            values = load_values(name)
            assert spec["behaviours"]["values_sha256"][name] == values.checksum
            np.testing.assert_array_equal(arrays[f"{name}_greedy"], greedy_table(values))
    # where the agents came from
    origin = json.loads((root / "baseline.json").read_text())
    assert origin["run"]["command"].startswith("cyber-rodent evolve --method ee --seed 100 ")
    assert len(origin["run"]["commit"]) == 40 and origin["generation"] == 40
    assert "among the lives that mated" in origin["ranking"]
    assert all(agent["mated"] for agent in origin["agents"])
    assert spec["provenance"]["agents"] == origin["agents"]
