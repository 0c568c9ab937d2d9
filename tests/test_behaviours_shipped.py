"""The shipped trained behaviours: load by default, verified, beat random, export faithfully."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from behaviours import BEHAVIOUR_NAMES, SPECS, VALUES_VERSION, BehaviourPolicies
from behaviours.action_values import CorruptActionValuesError, IncompatibleActionValuesError
from behaviours.definitions import VALUES_DIR_ENV_VAR, default_values_dir, load_values
from behaviours.evaluation import evaluate
from behaviours.greedy_policy import GreedyPolicy
from cyber_rodent.commands import COMMAND_NAMES, COMMAND_SET_VERSION


@pytest.fixture(scope="module")
def learned() -> BehaviourPolicies:
    return BehaviourPolicies.load_default()


def test_shipped_files_are_package_data_with_version_and_checksum():
    directory = default_values_dir()
    assert directory.name == "data" and directory.parent.name == "behaviours"
    for s in SPECS:
        path = directory / f"{s.name}.npz"
        assert path.is_file()
        assert path.stat().st_size < 400_000  # small: compressed, mostly unvisited tiles
        values = load_values(s.name)
        assert values.coder_config == s.coder
        assert values.action_names == COMMAND_NAMES
        meta = values.metadata
        assert meta["behaviour"] == s.name
        assert meta["values_version"] == VALUES_VERSION
        assert meta["command_set_version"] == COMMAND_SET_VERSION
        assert meta["episodes"] >= 100 and "seed" in meta
        assert len(values.checksum) == 64
        assert np.count_nonzero(values.weights) > 1000  # trained, not a zero table


def test_load_default_is_the_learned_greedy_policies(learned):
    assert learned.kind == "learned"
    assert all(isinstance(p, GreedyPolicy) for p in learned.policies)


# Looser than the benchmark (200 episodes, targets 90 % / 70 %), on fewer episodes.
def test_learned_forage_docks_and_beats_random(learned):
    ours = evaluate("forage", learned.policies[1], 20, seed=11)
    rand = evaluate("forage", "random", 20, seed=11)
    assert ours.success_rate >= 0.75
    assert ours.success_rate >= rand.success_rate + 0.3


def test_learned_mate_meets_and_beats_random(learned):
    ours = evaluate("mate", learned.policies[0], 15, seed=11)
    rand = evaluate("mate", "random", 15, seed=11)
    assert ours.success_rate >= 0.6
    assert ours.success_rate >= rand.success_rate + 0.3


def test_learned_search_avoids_and_covers_better_than_random(learned):
    ours = evaluate("search", learned.policies[2], 8, seed=11)
    rand = evaluate("search", "random", 8, seed=11)
    assert ours.contacts_per_1000_steps < rand.contacts_per_1000_steps
    assert ours.area_covered > 1.5 * rand.area_covered


def test_corrupt_or_missing_or_mismatched_shipped_file_is_a_clear_error(tmp_path, monkeypatch):
    for name in BEHAVIOUR_NAMES:
        shutil.copy(default_values_dir() / f"{name}.npz", tmp_path / f"{name}.npz")
    monkeypatch.setenv(VALUES_DIR_ENV_VAR, str(tmp_path))
    BehaviourPolicies.load_default()  # the copies load

    raw = bytearray((tmp_path / "search.npz").read_bytes())
    raw[len(raw) // 2] ^= 0x55
    (tmp_path / "search.npz").write_bytes(bytes(raw))
    with pytest.raises(CorruptActionValuesError, match="search.npz"):
        BehaviourPolicies.load_default()

    (tmp_path / "search.npz").write_bytes(b"")
    with pytest.raises(CorruptActionValuesError):
        BehaviourPolicies.load_default()

    (tmp_path / "search.npz").unlink()
    with pytest.raises(FileNotFoundError, match="search.*train-behaviours"):
        BehaviourPolicies.load_default()

    # Forage's table saved under Mate's name: another coder (hash seed), refused.
    shutil.copy(tmp_path / "forage.npz", tmp_path / "mate.npz")
    with pytest.raises(IncompatibleActionValuesError):
        load_values("mate")


def test_commands_of_learned_policies_match_each_policy(learned):
    rng = np.random.default_rng(3)
    from behaviours.inputs import BehaviourInputs

    n = 64
    inputs = BehaviourInputs(
        mate=rng.random((n, 2)),
        forage=rng.random((n, 2)),
        search=np.sort(rng.random((n, 2)), axis=1)[:, ::-1].copy(),
        mate_available=np.ones(n, dtype=bool),
        forage_available=np.ones(n, dtype=bool),
    )
    behaviour = rng.integers(3, size=n)
    out = learned.commands(behaviour, inputs)
    for b in range(3):
        rows = behaviour == b
        np.testing.assert_array_equal(out[rows], learned.policies[b].act(inputs.of(b)[rows]))


def test_compiled_commands_equal_the_numpy_path(learned):
    """The compiled kernel (backend "numba", what the runner uses) chooses exactly what the
    numpy reference and each policy choose, on random inputs, on the edges 0 and 1, and on
    tile boundaries; bad input is refused the same way by both."""
    from behaviours.inputs import BehaviourInputs

    assert learned.backend == "numba" and learned.tables is not None
    reference = BehaviourPolicies(*learned.policies, kind="learned", backend="numpy")
    rng = np.random.default_rng(11)
    n = 500
    grid = np.linspace(0.0, 1.0, 41)  # many exact tile boundaries
    values = [rng.random((n, 2)), rng.choice(grid, size=(n, 2))]
    for mate, forage in zip(values, values[::-1], strict=True):
        inputs = BehaviourInputs(
            mate=mate,
            forage=forage,
            search=np.sort(mate, axis=1)[:, ::-1].copy(),
            mate_available=np.ones(n, dtype=bool),
            forage_available=np.ones(n, dtype=bool),
        )
        behaviour = rng.integers(3, size=n)
        compiled = learned.commands(behaviour, inputs, out=np.full(n, -1, dtype=np.int64))
        np.testing.assert_array_equal(compiled, reference.commands(behaviour, inputs))
        for b in range(3):
            rows = behaviour == b
            expected = learned.policies[b].act(inputs.of(b)[rows])
            np.testing.assert_array_equal(compiled[rows], expected)
    bad = BehaviourInputs(
        mate=np.array([[0.5, np.nan]]), forage=np.zeros((1, 2)), search=np.zeros((1, 2)),
        mate_available=np.ones(1, dtype=bool), forage_available=np.ones(1, dtype=bool),
    )  # fmt: skip
    for policies in (learned, reference):
        with pytest.raises(ValueError, match=r"must be in \[0, 1\] \(no NaN\)"):
            policies.commands(np.array([0]), bad, out=np.zeros(1, dtype=np.int64))
        with pytest.raises(ValueError, match=r"indices must be in \[0, 3\)"):
            policies.commands(np.array([3]), bad, out=np.zeros(1, dtype=np.int64))


def test_exported_shipped_policies_act_like_numpy(tmp_path):
    torch = pytest.importorskip("torch")
    from behaviours.export import export_behaviour_policies, load_exported_policy

    paths = export_behaviour_policies(tmp_path)
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.random((5000, 2)), np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]])])
    for name, path in paths.items():
        module, description = load_exported_policy(path)
        numpy_actions = GreedyPolicy(load_values(name)).act(x)
        assert np.array_equal(module(torch.from_numpy(x)).numpy(), numpy_actions)
        assert len(set(numpy_actions.tolist())) >= 3  # a real comparison, not one constant
        assert description["values_sha256"] == load_values(name).checksum


def test_learned_policies_work_in_the_dm_control_tasks(learned):
    """The same behaviours in the dm-control ``forage`` and ``mate`` tasks (same world, driven
    through dm_env): inputs built from the task observations, commands sent as wheel speeds."""
    from cyber_rodent import tasks
    from cyber_rodent.commands import COMMAND_SPEEDS
    from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE, normalise_bearing

    def inputs_from(target: np.ndarray) -> np.ndarray:
        x = np.empty((len(target), 2))
        x[:, 0] = np.where(target[:, 2] > 0, normalise_bearing(target[:, 0]), 0.5)
        x[:, 1] = np.where(target[:, 2] > 0, np.minimum(target[:, 1] / DEFAULT_MAX_DISTANCE, 1), 1)
        return x

    for name, index, key, k in (("forage", 1, "nearest_battery", 1), ("mate", 0, "nearest_led", 2)):
        env = tasks.load(name, seed=4)
        successes = 0
        for _ in range(5):
            ts = env.reset()
            while not ts.last():
                commands = learned.policies[index].act(inputs_from(ts.observation[key]))
                ts = env.step({"wheels": COMMAND_SPEEDS[commands], "led": np.ones(k)})
                if ts.reward.max() >= 1.0:
                    successes += 1
                    break
        assert successes >= 4, (name, successes)


def test_commands_reject_out_of_range_inputs(learned):
    from behaviours.inputs import BehaviourInputs

    good = np.full((2, 2), 0.5)
    bad = good.copy()
    bad[1, 0] = 1.5
    inputs = BehaviourInputs(good, bad, good, np.ones(2, bool), np.ones(2, bool))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        learned.commands(np.array([0, 1]), inputs)
