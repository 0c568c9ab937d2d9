"""Sarsa(λ) with replacing traces: hand-computed updates, exploration, learning, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from behaviours.sarsa import SarsaConfig, SarsaLambda, epsilon_greedy
from behaviours.tile_coding import TileCoder, TileCoderConfig

# -- a two-state coder for hand computation ---------------------------------------------------
# One tiling, resolution 1, no wrap: x < 1 is tile 0, x = 1 is tile 1. With one tiling the
# per-weight step is alpha itself.
S0, S1 = np.array([0.0]), np.array([1.0])


def _two_state_learner(config: SarsaConfig, n_actions: int = 2) -> tuple[SarsaLambda, int, int]:
    coder = TileCoder(TileCoderConfig(resolution=(1,), n_tilings=1, table_size=64, seed=5))
    i0, i1 = int(coder.indices(S0)[0]), int(coder.indices(S1)[0])
    assert i0 != i1, "the two tiles must not collide for the hand computation"
    learner = SarsaLambda(coder, n_actions, config, np.random.default_rng(0))
    return learner, i0, i1


HAND = SarsaConfig(alpha=0.5, gamma=0.5, lam=0.5, epsilon=0.0, trace_cutoff=1e-9)


def test_replacing_trace_is_set_to_one_and_updates_match_hand_computation():
    learner, i0, i1 = _two_state_learner(HAND)
    w = learner.weights
    w[0, i0], w[0, i1] = 1.0, 0.5  # greedy action is 0 everywhere

    assert learner.begin_episode(S0) == 0
    assert learner.traces()[0, i0] == 1.0

    # r = 1, back to s0: δ = 1 - 1 + 0.5 * 1 = 0.5; w[0,i0] += 0.5 * 0.5 * 1 -> 1.25.
    # The trace decays to 0.25 and the revisit *replaces* it with 1 (accumulating: 1.25).
    assert learner.step(1.0, S0) == 0
    assert w[0, i0] == 1.25
    assert learner.traces()[0, i0] == 1.0

    # r = 0, to s1: δ = 0 - 1.25 + 0.5 * 0.5 = -1.0; w[0,i0] += 0.5 * -1 * 1 -> 0.75;
    # trace of (s0, 0) decays to 0.25, (s1, 0) is set to 1.
    assert learner.step(0.0, S1) == 0
    assert w[0, i0] == 0.75
    assert learner.traces()[0, i0] == 0.25 and learner.traces()[0, i1] == 1.0

    # r = 2, terminal: δ = 2 - 0.5 = 1.5; w[0,i0] += 0.5*1.5*0.25 -> 0.9375, w[0,i1] -> 1.25.
    assert learner.step(2.0, None, terminal=True) is None
    assert w[0, i0] == 0.9375 and w[0, i1] == 1.25
    assert not w[1].any()
    assert not learner.traces().any() and learner.n_active_traces == 0


@pytest.mark.parametrize("clear", [True, False])
def test_other_actions_traces_are_cleared_on_a_visit(clear):
    config = SarsaConfig(
        alpha=0.5,
        gamma=0.5,
        lam=0.5,
        epsilon=0.0,
        trace_cutoff=1e-9,
        clear_other_action_traces=clear,
    )
    learner, i0, i1 = _two_state_learner(config)
    w = learner.weights
    w[1, i0], w[0, i1] = 0.1, 1.0

    assert learner.begin_episode(S0) == 1
    # r = -4 to s1 (greedy 0): δ = -4 - 0.1 + 0.5 * 1 = -3.6; w[1,i0] -> 0.1 - 1.8 = -1.7.
    assert learner.step(-4.0, S1) == 0
    assert w[1, i0] == pytest.approx(-1.7, abs=1e-15)
    # r = 0 to s0, now greedy 0: δ = 0 - 1 + 0 = -1; w[1,i0] += 0.5*-1*0.25, w[0,i1] -> 0.5.
    assert learner.step(0.0, S0) == 0
    assert w[0, i1] == 0.5
    assert w[1, i0] == pytest.approx(-1.825, abs=1e-15)
    traces = learner.traces()
    assert traces[0, i0] == 1.0 and traces[0, i1] == 0.25
    # (s0, 1) had trace 0.25 -> decayed 0.0625; visiting (s0, 0) clears it (or keeps it).
    assert traces[1, i0] == (0.0 if clear else 0.0625)


# -- sparse bookkeeping equals a dense textbook implementation -----------------------------


def _dense_reference(coder, n_actions, config, rng, transitions):
    """Sutton & Barto (1998) Fig. 8.8 with dense traces, no cut-off; returns the weights."""
    w = np.zeros((n_actions, coder.table_size))
    e = np.zeros_like(w)
    step = config.alpha / coder.n_tilings
    f = coder.indices(transitions[0][0])
    a = epsilon_greedy(w[:, f].sum(axis=1), config.epsilon, rng)
    for _, reward, s_next, terminal in transitions:
        e[:, f] = np.where(np.arange(n_actions)[:, None] == a, 1.0, 0.0)
        delta = reward - w[a, f].sum()
        if terminal:
            w += step * delta * e
            break
        f = coder.indices(s_next)
        q = w[:, f].sum(axis=1)
        a = epsilon_greedy(q, config.epsilon, rng)
        delta += config.gamma * q[a]
        w += step * delta * e
        e *= config.gamma * config.lam
    return w


def test_sparse_traces_match_dense_reference():
    rng = np.random.default_rng(11)
    coder = TileCoder(TileCoderConfig(resolution=(5, 3), n_tilings=4, table_size=50, seed=2))
    states = rng.random((400, 2))
    rewards = rng.normal(size=400)
    transitions = [(states[k], rewards[k], states[k + 1], k == 398) for k in range(399)]
    config = SarsaConfig(alpha=0.3, gamma=0.9, lam=0.8, epsilon=0.2, trace_cutoff=1e-12)
    reference = _dense_reference(coder, 3, config, np.random.default_rng(5), transitions)

    learner = SarsaLambda(coder, 3, config, np.random.default_rng(5))
    learner.begin_episode(transitions[0][0])
    max_active = 0
    for _, reward, s_next, terminal in transitions:
        learner.step(reward, s_next, terminal)
        max_active = max(max_active, learner.n_active_traces)
        if terminal:
            break
    assert np.allclose(learner.weights, reference, rtol=0, atol=1e-9)
    # The table has 150 weights; traces older than log(1e-12)/log(0.72) ≈ 84 steps are dropped.
    assert max_active <= 3 * 50


def test_traces_stay_sparse_with_the_default_cutoff():
    rng = np.random.default_rng(0)
    coder = TileCoder(TileCoderConfig(resolution=(50, 50), n_tilings=8, table_size=1 << 16))
    config = SarsaConfig()  # γλ = 0.855, cutoff 1e-3 -> a trace lives at most 44 steps
    learner = SarsaLambda(coder, 4, config, rng)
    learner.begin_episode(rng.random(2))
    lifetime = math.ceil(math.log(config.trace_cutoff) / math.log(config.gamma * config.lam))
    bound = 8 * (lifetime + 1) + 8 * 3  # live traces + other actions' zeroed this step
    for _ in range(500):
        learner.step(float(rng.normal()), rng.random(2))
        assert learner.n_active_traces <= bound
    dense = learner.traces()
    assert np.count_nonzero(dense) <= 8 * (lifetime + 1)
    assert dense[dense > 0].min() >= config.trace_cutoff


# -- ε-greedy -----------------------------------------------------------------------------------


def test_epsilon_greedy_frequencies():
    rng = np.random.default_rng(42)
    q = np.array([0.0, 0.0, 1.0, 0.0])
    n = 40_000
    counts = np.bincount([epsilon_greedy(q, 0.3, rng) for _ in range(n)], minlength=4) / n
    # greedy: 1 - ε + ε/4 = 0.775, others ε/4 = 0.075; 5 standard errors ≈ 0.0105 / 0.0066
    assert abs(counts[2] - 0.775) < 0.0105
    assert np.all(np.abs(counts[[0, 1, 3]] - 0.075) < 0.0066)


def test_epsilon_zero_is_greedy_with_random_tie_breaking():
    rng = np.random.default_rng(1)
    assert {epsilon_greedy(np.array([0.0, 2.0, 1.0]), 0.0, rng) for _ in range(200)} == {1}
    picks = np.array([epsilon_greedy(np.array([1.0, 1.0, 0.0]), 0.0, rng) for _ in range(4000)])
    assert set(picks.tolist()) == {0, 1}
    assert abs(picks.mean() - 0.5) < 5 * math.sqrt(0.25 / 4000)


def test_epsilon_one_is_uniform():
    rng = np.random.default_rng(2)
    q = np.array([5.0, 0.0, 0.0])
    counts = np.bincount([epsilon_greedy(q, 1.0, rng) for _ in range(30_000)]) / 30_000
    assert np.all(np.abs(counts - 1 / 3) < 5 * math.sqrt((1 / 3) * (2 / 3) / 30_000))


# -- learning a known problem: mountain car (Sutton & Barto, Example 8.2) ---------------------


def _mountain_car(seed: int, episodes: int, alpha: float = 0.5) -> tuple[list[int], np.ndarray]:
    """Classic mountain car: reward -1 per step, γ = 1, ε = 0, zero (optimistic) initial Q,
    8 tilings of 8 × 8 tiles over (position, velocity), λ = 0.9."""
    rng = np.random.default_rng(seed)
    coder = TileCoder(TileCoderConfig(resolution=(8, 8), n_tilings=8, table_size=4096, seed=seed))
    config = SarsaConfig(alpha=alpha, gamma=1.0, lam=0.9, epsilon=0.0)
    learner = SarsaLambda(coder, 3, config, rng)

    def observe(p: float, v: float) -> np.ndarray:
        return np.array([(p + 1.2) / 1.7, (v + 0.07) / 0.14])

    lengths = []
    for _ in range(episodes):
        p, v = rng.uniform(-0.6, -0.4), 0.0
        action = learner.begin_episode(observe(p, v))
        steps = 0
        while steps < 5000:  # cut-off: the next begin_episode clears the traces
            steps += 1
            v = min(max(v + 0.001 * (action - 1) - 0.0025 * math.cos(3 * p), -0.07), 0.07)
            p += v
            if p < -1.2:
                p, v = -1.2, 0.0
            if p >= 0.5:
                learner.step(-1.0, None, terminal=True)
                break
            action = learner.step(-1.0, observe(p, v))
        lengths.append(steps)
    return lengths, learner.weights


def test_learns_mountain_car():
    lengths, _ = _mountain_car(seed=0, episodes=60)
    # A policy that ignores the state needs far more than 300 steps (it must swing); the
    # optimum from these starts is ~100-120 steps. Measured: first ≈ 2000, last 10 ≈ 130.
    assert lengths[0] > 400
    assert np.mean(lengths[-10:]) < 180
    assert max(lengths[-10:]) < 300


def test_same_seed_gives_bit_identical_weights():
    lengths_a, w_a = _mountain_car(seed=3, episodes=8)
    lengths_b, w_b = _mountain_car(seed=3, episodes=8)
    assert lengths_a == lengths_b
    assert w_a.tobytes() == w_b.tobytes()
    _, w_c = _mountain_car(seed=4, episodes=8)
    assert w_a.tobytes() != w_c.tobytes()


# -- sharing, snapshots, misuse ---------------------------------------------------------------


def test_two_learners_share_one_weight_table_in_place():
    coder = TileCoder(TileCoderConfig(resolution=(4,), n_tilings=2, table_size=32))
    shared = np.zeros((2, 32))
    a = SarsaLambda(coder, 2, SarsaConfig(), np.random.default_rng(0), weights=shared)
    b = SarsaLambda(coder, 2, SarsaConfig(), np.random.default_rng(1), weights=shared)
    a.begin_episode(np.array([0.1]))
    b.begin_episode(np.array([0.9]))
    a.step(1.0, None, terminal=True)
    after_a = shared.copy()
    assert after_a.any()
    b.step(-1.0, None, terminal=True)
    assert not np.array_equal(shared, after_a)
    assert a.weights is shared and b.weights is shared


def test_snapshot_is_an_immutable_copy():
    learner, i0, _ = _two_state_learner(HAND)
    learner.weights[0, i0] = 3.0
    values = learner.action_values(("left", "right"), {"behaviour": "test"})
    learner.weights[0, i0] = -1.0
    assert values.weights[0, i0] == 3.0
    assert not values.weights.flags.writeable
    assert values.action_names == ("left", "right")


def test_step_before_begin_episode_is_an_error():
    learner, _, _ = _two_state_learner(HAND)
    with pytest.raises(RuntimeError, match="begin_episode"):
        learner.step(0.0, S0)
    learner.begin_episode(S0)
    learner.step(0.0, None, terminal=True)
    with pytest.raises(RuntimeError, match="begin_episode"):
        learner.step(0.0, S0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"alpha": 0.0}, "alpha"),
        ({"alpha": 1.5}, "alpha"),
        ({"gamma": -0.1}, "gamma"),
        ({"gamma": float("nan")}, "gamma"),
        ({"lam": 1.1}, "lam"),
        ({"epsilon": -0.01}, "epsilon"),
        ({"trace_cutoff": 0.0}, "trace_cutoff"),
    ],
)
def test_bad_config_names_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        SarsaConfig(**kwargs)


def test_bad_learner_arguments_name_the_field():
    coder = TileCoder(TileCoderConfig(resolution=(2,), table_size=16))
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="n_actions"):
        SarsaLambda(coder, 0, SarsaConfig(), rng)
    with pytest.raises(ValueError, match="weights"):
        SarsaLambda(coder, 2, SarsaConfig(), rng, weights=np.zeros((2, 15)))
    with pytest.raises(ValueError, match="rng"):
        SarsaLambda(coder, 2, SarsaConfig(), 0)
    learner = SarsaLambda(coder, 2, SarsaConfig(), rng)
    learner.begin_episode(np.array([0.5]))
    with pytest.raises(ValueError, match="reward"):
        learner.step(float("nan"), np.array([0.5]))
