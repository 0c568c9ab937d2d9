"""Learning mode: the in-life learner, its genes, its inheritance and its run state.

The learner's update is the algorithm of ``behaviours/sarsa.py``: fed the same transitions,
:func:`behaviours.kernels.learn_commands` (compiled and numpy) and :class:`SarsaLambda` end with
the same weights, bit for bit. The other tests are hand-computed cases of each rule
(docs/design.md §11).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from behaviours.definitions import spec
from behaviours.inputs import FORAGE, MATE, SEARCH
from behaviours.kernels import (
    OK,
    BehaviourInputs,
    GreedyTables,
    LearnedValues,
    LearningEpisodes,
    LearningOutcome,
    LearningStep,
    learn_commands,
    learn_commands_reference,
    learn_outcome,
    learn_outcome_reference,
)
from behaviours.sarsa import SarsaConfig, SarsaLambda
from behaviours.tile_coding import TileCoder
from evolution.config import (
    GENOME_LENGTH,
    LEARNING_GENOME_LENGTH,
    EvolutionConfig,
    GeneticConfig,
    LearningConfig,
)
from evolution.genome import CONTROLLER, META, SHAPING, Genome, reflect_unit
from evolution.learning import decode_meta
from evolution.runner import EvolutionRunner, RunConfig

Kernel = Callable[..., int]
Outcome = Callable[..., None]
BACKENDS = {
    "numba": (learn_commands, learn_outcome),
    "numpy": (learn_commands_reference, learn_outcome_reference),
}


@pytest.fixture(scope="module")
def tables() -> GreedyTables:
    policies = BehaviourPolicies.load_default()
    assert policies.tables is not None
    return policies.tables


@dataclasses.dataclass
class Learner:
    """One set of learner buffers for ``n`` robots and ``n_tables`` agent tables."""

    values: LearnedValues
    episodes: LearningEpisodes
    step: LearningStep
    outcome: LearningOutcome
    inputs: BehaviourInputs
    behaviour: np.ndarray
    out: np.ndarray


def make_learner(
    tables: GreedyTables, n: int = 1, n_tables: int = 1, dtype: type = np.float64,
    alpha: float = 0.1, gamma: float = 0.98, lam: float = 0.9, epsilon: float = 0.1,
) -> Learner:  # fmt: skip
    rows, n_actions = tables.table.shape
    t = tables.offsets.shape[1]
    values = LearnedValues(
        np.zeros((n_tables, rows, n_actions), dtype), np.full(n_tables, alpha),
        np.full(n_tables, gamma), np.full(n_tables, lam), np.full(n_tables, epsilon),
        np.zeros((n_tables, 3, 2)), np.zeros(n_tables, dtype=np.int64),
    )  # fmt: skip
    episodes = LearningEpisodes(
        np.zeros(n, bool), np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
        np.zeros((n, t), np.int64), np.zeros(n, np.int64), np.zeros(n), np.zeros(n),
        np.zeros((n, rows * n_actions)), np.zeros((n, rows * n_actions), np.int64),
        np.zeros(n, np.int64),
    )  # fmt: skip
    step = LearningStep(
        np.zeros(n, np.int64), np.ones(n, bool), np.zeros((n, 4)), 1e-3, 7,
        np.zeros(t, np.int64), np.zeros(n_actions),
    )  # fmt: skip
    outcome = LearningOutcome(np.zeros(n), np.zeros(n, bool), np.zeros(n, bool))
    inputs = BehaviourInputs(
        np.full((n, 2), 0.5), np.full((n, 2), 0.5), np.full((n, 2), 0.5), np.ones(n, bool),
        np.ones(n, bool),
    )  # fmt: skip
    return Learner(values, episodes, step, outcome, inputs, np.zeros(n, np.int64),
                   np.zeros(n, np.int64))  # fmt: skip


def decide(learner: Learner, kernel: Kernel, tables: GreedyTables) -> None:
    v = learner
    status = kernel(v.behaviour, v.inputs, tables, v.values, v.episodes, v.step, v.out)
    assert status == OK


def table_rows(tables: GreedyTables, behaviour: int) -> slice:
    base = [0, 8192, 16384][behaviour]
    return slice(base, base + 8192)


def next_action(learner: Learner, tables: GreedyTables, behaviour: int, x: np.ndarray,
                u0: float, u1: float) -> int:  # fmt: skip
    """The action the learner's ε-greedy choice takes at ``x`` with draws (u0, u1)."""
    coder = TileCoder(spec(("mate", "forage", "search")[behaviour]).coder)
    weights = learner.values.values[0, table_rows(tables, behaviour)].T
    q = weights[:, coder.indices(x)].sum(axis=1)
    if u0 < learner.values.epsilon[0]:
        return min(int(u1 * q.size), int(q.size) - 1)
    best = np.flatnonzero(q == q.max())
    return int(best[min(int(u1 * best.size), best.size - 1)])


@pytest.mark.parametrize("backend", sorted(BACKENDS))
def test_same_transitions_same_weights_as_sarsa_lambda(tables: GreedyTables, backend: str) -> None:
    """Episodes of Forage and Search that end at the goal, are cut by a change of behaviour,
    or go on: the learner and one SarsaLambda per behaviour, fed the same states, actions and
    rewards, hold bit-identical weights."""
    kernel, outcome = BACKENDS[backend]
    learner = make_learner(tables)
    config = SarsaConfig(alpha=0.1, gamma=0.98, lam=0.9, epsilon=0.1)
    sarsa = {
        b: SarsaLambda(TileCoder(spec(name).coder), 8, config, np.random.default_rng(0))
        for b, name in ((FORAGE, "forage"), (SEARCH, "search"))
    }
    rng = np.random.default_rng(7)
    open_behaviour: int | None = None
    reward = 0.0
    for _ in range(60):  # episodes
        b = int(rng.choice([FORAGE, SEARCH]))
        length = int(rng.integers(3, 40))
        for t in range(length):
            x = rng.random(2)
            learner.inputs.of(b)[0] = x
            learner.behaviour[0] = b
            u = rng.random(4)
            learner.step.uniforms[0] = u
            if open_behaviour is not None and open_behaviour != b:
                # The open episode is cut: its last transition bootstraps from where it is.
                y = learner.inputs.of(open_behaviour)[0]
                cut = next_action(learner, tables, open_behaviour, y, u[0], u[1])
                sarsa[open_behaviour].step(reward, y, action=cut)
                open_behaviour = None
            decide(learner, kernel, tables)
            action = int(learner.out[0])
            if open_behaviour is None:
                sarsa[b].begin_episode(x, action=action)
                open_behaviour = b
            else:
                sarsa[b].step(reward, x, action=action)
            reward = float(rng.normal())
            learner.outcome.reward[0] = reward
            goal = t == length - 1 and rng.random() < 0.5
            learner.outcome.goal[0] = goal
            outcome(learner.values, learner.episodes, learner.outcome)
            if goal:
                sarsa[b].step(reward, None, terminal=True)
                open_behaviour = None
    for b, learned in sarsa.items():
        assert np.count_nonzero(learned.weights) > 1000
        np.testing.assert_array_equal(learner.values.values[0, table_rows(tables, b)].T,
                                      learned.weights)  # fmt: skip


def test_shaped_step_by_hand(tables: GreedyTables) -> None:
    """One Forage transition from a zero table: α = 0.8, γ = 0.9, shaping (0, -1) (the pack's
    distance), step reward -0.02, distance 0.4 -> 0.3: r = -0.02 + 0.9 (-0.3) - (-0.4) = 0.11,
    δ = r (zero table), and each of the 8 tiles of (s, a) moves by 0.8 / 8 · 0.11 = 0.011."""
    learner = make_learner(tables, alpha=0.8, gamma=0.9, lam=0.5, epsilon=0.0)
    learner.values.shaping[0, FORAGE] = (0.0, -1.0)
    learner.behaviour[0] = FORAGE
    learner.inputs.forage[0] = (0.5, 0.4)
    learner.step.uniforms[0] = (0.9, 0.0, 0.9, 0.0)  # ties: the first action
    decide(learner, learn_commands, tables)
    assert learner.out[0] == 0 and learner.episodes.potential[0] == -0.4
    learner.outcome.reward[0] = -0.02
    learn_outcome(learner.values, learner.episodes, learner.outcome)
    first_rows = learner.episodes.rows[0].copy()
    learner.inputs.forage[0] = (0.5, 0.3)
    decide(learner, learn_commands, tables)
    moved = learner.values.values[0, first_rows, 0]
    np.testing.assert_allclose(moved, 0.011, rtol=1e-12)
    assert np.count_nonzero(learner.values.values) == 8  # only (s, a) moved
    # The trace of (s, a) decayed by γλ = 0.45; (s', a') is now traced at 1.
    trace = learner.episodes.trace[0].reshape(-1, 8)
    np.testing.assert_allclose(trace[first_rows, 0], 0.45)
    assert trace[learner.episodes.rows[0], learner.out[0]].tolist() == [1.0] * 8


def test_terminal_goal_by_hand(tables: GreedyTables) -> None:
    """Mate reaches its goal: r = goal 1 - step cost 0.02 + (0 - Φ(s)) with Φ(s) = 0.5 · 0.2
    = 0.1: r = 0.88 = δ; each tile of (s, a) moves by α/8 δ = 0.5 / 8 · 0.88 = 0.055, and the
    episode closes with its traces cleared."""
    learner = make_learner(tables, alpha=0.5, epsilon=0.0)
    learner.values.shaping[0, MATE] = (0.0, 0.5)
    learner.behaviour[0] = MATE
    learner.inputs.mate[0] = (0.3, 0.2)
    decide(learner, learn_commands, tables)
    rows = learner.episodes.rows[0].copy()
    learner.outcome.reward[0] = 1.0 - 0.02
    learner.outcome.goal[0] = True
    learn_outcome(learner.values, learner.episodes, learner.outcome)
    np.testing.assert_allclose(learner.values.values[0, rows, learner.out[0]], 0.055, rtol=1e-12)
    assert not learner.episodes.open[0] and learner.episodes.n_active[0] == 0
    assert not learner.episodes.trace[0].any()


def test_ended_life_and_newborn_do_not_learn(tables: GreedyTables) -> None:
    """A death closes the episode without an update; a newborn in the table (a new serial)
    never continues the previous agent's episode."""
    learner = make_learner(tables, epsilon=0.0)
    learner.behaviour[0] = SEARCH
    decide(learner, learn_commands, tables)
    learner.outcome.reward[0] = 5.0
    learner.outcome.ended[0] = True
    learn_outcome(learner.values, learner.episodes, learner.outcome)
    assert not learner.episodes.open[0] and not learner.values.values.any()
    learner.outcome.ended[0] = False
    decide(learner, learn_commands, tables)  # a new episode
    learner.values.serial[0] += 1  # a newborn takes the table
    learner.outcome.reward[0] = 5.0
    learn_outcome(learner.values, learner.episodes, learner.outcome)
    decide(learner, learn_commands, tables)
    assert not learner.values.values.any()  # the reward of the dead agent's episode is dropped
    assert learner.episodes.serial[0] == 1


def test_robots_that_do_not_act_send_the_idle_command(tables: GreedyTables) -> None:
    learner = make_learner(tables, n=3, n_tables=3)
    learner.step.table[:] = (0, 1, -1)
    learner.step.acting[:] = (True, False, True)
    decide(learner, learn_commands, tables)
    assert learner.episodes.open.tolist() == [True, False, False]
    assert learner.out[1] == learner.out[2] == 7


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_learner_matches_numpy_reference(tables: GreedyTables, dtype: type) -> None:
    """Four robots on six tables: random behaviours, agent switches, newborns, goals, deaths
    and robots that do not act; every buffer agrees bit for bit after every step."""
    learners = [make_learner(tables, n=4, n_tables=6, dtype=dtype) for _ in range(2)]
    rng = np.random.default_rng(3)
    params = {
        "alpha": rng.uniform(0.01, 0.5, 6), "gamma": rng.uniform(0.8, 1.0, 6),
        "lam": rng.uniform(0.0, 0.99, 6), "epsilon": rng.uniform(0.0, 0.3, 6),
        "shaping": rng.uniform(-1, 1, (6, 3, 2)),
    }  # fmt: skip
    for learner in learners:
        for name, array in params.items():
            getattr(learner.values, name)[:] = array
    kernels = [BACKENDS["numba"], BACKENDS["numpy"]]
    for _ in range(400):
        behaviour = rng.integers(0, 3, 4)
        inputs = rng.random((3, 4, 2))
        table = rng.integers(-1, 6, 4)
        acting = rng.random(4) < 0.85
        uniforms = rng.random((4, 4))
        newborn = rng.random(6) < 0.01
        reward = rng.normal(size=4)
        goal = rng.random(4) < 0.05
        ended = rng.random(4) < 0.02
        for learner, (kernel, outcome) in zip(learners, kernels, strict=True):
            learner.behaviour[:] = behaviour
            for b in range(3):
                learner.inputs.of(b)[:] = inputs[b]
            learner.step.table[:] = table
            learner.step.acting[:] = acting
            learner.step.uniforms[:] = uniforms
            learner.values.serial[:] += newborn
            decide(learner, kernel, tables)
            learner.outcome.reward[:] = reward
            learner.outcome.goal[:] = goal & learner.episodes.open
            learner.outcome.ended[:] = ended
            outcome(learner.values, learner.episodes, learner.outcome)
        first, second = learners
        np.testing.assert_array_equal(first.out, second.out)
        for name in ("values", "serial"):
            np.testing.assert_array_equal(getattr(first.values, name),
                                          getattr(second.values, name))  # fmt: skip
        for name, array in first.episodes._asdict().items():
            if name == "active":
                for i in range(4):
                    m = first.episodes.n_active[i]
                    assert sorted(array[i, :m]) == sorted(second.episodes.active[i, :m])
            else:
                np.testing.assert_array_equal(array, getattr(second.episodes, name),
                                              err_msg=name)  # fmt: skip
    assert np.count_nonzero(learners[0].values.values) > 1000


def test_float32_values_follow_float64_closely(tables: GreedyTables) -> None:
    """The same transitions learned in float32 and in float64 tables: the values differ by
    rounding only, and the actions chosen agree."""
    learners = [make_learner(tables, dtype=d) for d in (np.float32, np.float64)]
    rng = np.random.default_rng(11)
    agree = 0
    for _ in range(3000):
        b = int(rng.integers(0, 3))
        x = rng.random(2)
        u = rng.random(4)
        goal = rng.random() < 0.03
        r = float(rng.normal())
        chosen = []
        for learner in learners:
            learner.behaviour[0] = b
            learner.inputs.of(b)[0] = x
            learner.step.uniforms[0] = u
            decide(learner, learn_commands, tables)
            chosen.append(int(learner.out[0]))
            learner.outcome.reward[0] = r
            learner.outcome.goal[0] = goal and learner.episodes.open[0]
            learn_outcome(learner.values, learner.episodes, learner.outcome)
        agree += chosen[0] == chosen[1]
    single, double = (learner.values.values.astype(np.float64) for learner in learners)
    assert np.abs(single - double).max() < 1e-5 * max(1.0, np.abs(double).max())
    assert agree >= 0.99 * 3000


# --- genes ------------------------------------------------------------------------------------
def test_learning_genome_layout_and_random_draws() -> None:
    """The controller's weights are drawn first, as in a fixed genome; then four meta-genes in
    [0, 1] and six shaping weights in [-1, 1]."""
    fixed = Genome.random(np.random.default_rng(5))
    learning = Genome.random(np.random.default_rng(5), learning=True)
    assert learning.weights.shape == (LEARNING_GENOME_LENGTH,) and learning.learns
    np.testing.assert_array_equal(learning.controller, fixed.weights)
    assert ((learning.meta >= 0) & (learning.meta <= 1)).all()
    assert learning.shaping.shape == (3, 2) and (np.abs(learning.shaping) <= 1).all()
    assert not fixed.learns and fixed.controller.shape == (GENOME_LENGTH,)
    with pytest.raises(ValueError, match="no learning genes"):
        _ = fixed.meta


def test_meta_genes_must_lie_in_unit_interval() -> None:
    genes = np.zeros(LEARNING_GENOME_LENGTH)
    genes[META.start] = 1.2
    with pytest.raises(ValueError, match=r"meta-genes must lie in \[0, 1\]"):
        Genome(genes)
    with pytest.raises(ValueError, match="shape"):
        Genome(np.zeros(40))


def test_reflection_by_hand() -> None:
    assert reflect_unit(np.array([-0.05, 1.08, 0.4, 0.0, 1.0])).tolist() == pytest.approx(
        [0.05, 0.92, 0.4, 0.0, 1.0]
    )


def test_mutation_of_a_learning_genome() -> None:
    """Weights move by the increments drawn for them; a mutated meta-gene moves by its own
    U[-w, w] draw and is reflected into [0, 1]. The draws: the mask (49), the weights'
    increments (49), the meta increments (4)."""
    genetics = GeneticConfig(mutation_probability=0.5, meta_mutation_width=0.3)
    genes = np.concatenate((np.zeros(GENOME_LENGTH), [0.0, 1.0, 0.5, 0.95], np.ones(6)))
    genome = Genome(genes)
    child = genome.mutate(np.random.default_rng(9), genetics)
    rng = np.random.default_rng(9)
    mask = rng.random(LEARNING_GENOME_LENGTH) < 0.5
    delta = rng.uniform(-0.5, 0.5, LEARNING_GENOME_LENGTH)
    step = rng.uniform(-0.3, 0.3, 4)
    expected = np.where(mask, genes + delta, genes)
    meta = genes[META] + step
    meta = np.where(meta < 0, -meta, np.where(meta > 1, 2 - meta, meta))
    expected[META] = np.where(mask[META], meta, genes[META])
    np.testing.assert_array_equal(child.weights, expected)
    assert ((child.meta >= 0) & (child.meta <= 1)).all()
    assert mask[META].any() and mask[SHAPING].any() and mask[CONTROLLER].any()


def test_crossover_cuts_anywhere_in_the_learning_genome() -> None:
    a = Genome(np.concatenate((np.zeros(GENOME_LENGTH), [0.1] * 4, [0.0] * 6)))
    b = Genome(np.concatenate((np.ones(GENOME_LENGTH), [0.9] * 4, [1.0] * 6)))
    first, second = a.crossover(b, np.random.default_rng(0), point=41)
    assert first.weights[:41].tolist() == a.weights[:41].tolist()
    assert first.weights[41:].tolist() == b.weights[41:].tolist()
    assert second.weights[:41].tolist() == b.weights[:41].tolist()
    with pytest.raises(ValueError, match=r"\[1, 48\]"):
        a.crossover(b, np.random.default_rng(0), point=49)
    with pytest.raises(ValueError, match="different lengths"):
        a.crossover(Genome(np.zeros(GENOME_LENGTH)), np.random.default_rng(0))


def test_meta_genes_decode_onto_their_ranges() -> None:
    """Default ranges: α [0.01, 0.5], γ [0.8, 0.999], λ [0, 0.99], ε [0, 0.3]; genes 0.5 each
    give the midpoints, genes (0, 1, 0.2, 1) the ends and a fifth of λ's range."""
    config = LearningConfig()
    mid = decode_meta(np.full(4, 0.5), config)
    assert mid == pytest.approx({"alpha": 0.255, "gamma": 0.8995, "lam": 0.495, "epsilon": 0.15})
    ends = decode_meta(np.array([0.0, 1.0, 0.2, 1.0]), config)
    assert ends == pytest.approx({"alpha": 0.01, "gamma": 0.999, "lam": 0.198, "epsilon": 0.3})


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("alpha_high", 2.0, "alpha_high"),
        ("gamma_low", -0.1, "gamma_low"),
        ("epsilon_high", 1.5, "epsilon_high"),
        ("inheritance", "baldwinian", "inheritance"),
        ("init", "random", "init"),
    ],
)
def test_bad_learning_settings(field: str, value: Any, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        LearningConfig(**{field: value})


@pytest.mark.parametrize("inheritance", ["lamarckian", "darwinian"])
def test_lamarckian_ce_individuals_take_their_first_parents_values(inheritance: str) -> None:
    """In the centralised GA every new individual starts from the values its first parent had
    learned (``selection_parents``); Darwinian CE individuals start from ``init``."""
    evo = EvolutionConfig(**SMALL, learning=LearningConfig(  # type: ignore[arg-type]
        enabled=True, init="shipped", inheritance=inheritance))  # fmt: skip
    with EvolutionRunner(RunConfig(method="ce", evolution=evo), 3) as runner:
        learner, scheduler = runner.learning, runner.scheduler
        assert learner is not None
        load_births = learner.on_births
        checked: list[bool] = []

        def check(births: Any, genomes: Any, parents: Any) -> None:
            before = learner.values.values.copy()
            load_births(births, genomes, parents)
            for table in range(8):
                expected = (before[parents[table]] if inheritance == "lamarckian"
                            else learner.initial_values)  # fmt: skip
                checked.append(np.array_equal(learner.values.values[table], expected))
            learned = [not np.array_equal(before[t], learner.initial_values) for t in parents]
            assert any(learned)  # the parents had learned something to pass on

        learner.on_births = check  # type: ignore[method-assign, assignment]
        runner.run(1)
        assert len(scheduler.selection_parents) == 8
        assert len(checked) == 8 and all(checked)


def test_a_range_must_not_be_upside_down() -> None:
    with pytest.raises(ValueError, match=r"learning.alpha_low must be <= learning.alpha_high"):
        LearningConfig(alpha_low=0.6, alpha_high=0.5)


# --- runs ---------------------------------------------------------------------------------------
SMALL = dict(population_size=8, n_robots=4, lifetime_steps=60, time_sharing_steps=20)


def learning_config(**learning: Any) -> RunConfig:
    evo = EvolutionConfig(**SMALL, learning=LearningConfig(enabled=True, **learning))  # type: ignore[arg-type]
    return RunConfig(method="ee", evolution=evo)


def test_learning_run_learns_and_records_its_lives() -> None:
    with EvolutionRunner(learning_config(init="shipped"), 2) as runner:
        runner.run(4)
        for _ in range(30):  # generations close as both slots of every robot take newborns
            runner.step()
        learner = runner.learning
        assert learner is not None
        shipped = learner.initial_values
        changed = np.any(learner.values.values != shipped[None], axis=(1, 2))
        assert changed.sum() >= 4  # every robot's active agent learned from its own rewards
        rows = learner.record_rows()
        assert [row["generation"] for row in rows][:4] == [0, 1, 2, 3]
        first = rows[0]
        assert first["lives"] >= 1
        assert 0.01 <= first["alpha_mean"] <= 0.5 and first["alpha_std"] >= 0
        assert {"batteries_age_0_100", "matings_age_0_100"} <= set(first)


@pytest.mark.parametrize("method", ["ee", "ce"])
def test_recorded_lives_are_the_full_lives_of_the_statistics(method: str) -> None:
    """Every agent that lived its full lifetime is in the learning record once, and no agent
    that died: CE's record equals the statistics' full lifetimes; EE's may count more, the
    lives that lagging slots finish after their generation closed."""
    # Lives of 80 steps on an energy of 40: agents that do not dock in time die.
    lives = dict(SMALL, lifetime_steps=80, time_sharing_steps=40, initial_energy=40.0)
    evo = EvolutionConfig(**lives, learning=LearningConfig(enabled=True, init="shipped"))  # type: ignore[arg-type]
    with EvolutionRunner(RunConfig(method=method, evolution=evo), 5) as runner:
        runner.run(4)
        learner = runner.learning
        assert learner is not None
        statistics = runner.statistics()
        deaths = int(statistics["deaths"].sum())
        assert deaths > 0  # agents that learn from zero die: the rule is exercised
        for row in statistics.itertuples():
            recorded = int(learner.records.get(row.generation, {"lives": [0]})["lives"][0])
            if method == "ce":
                assert recorded == row.full_lifetimes
            else:
                assert recorded >= row.full_lifetimes


@pytest.mark.parametrize("inheritance", ["darwinian", "lamarckian"])
def test_inheritance_rule(inheritance: str) -> None:
    """Lamarckian: an offspring (origin 1) keeps its slot's values, those its parent learned;
    spare (2) and random (3) genomes start from ``init``. Darwinian: every newborn does."""
    with EvolutionRunner(learning_config(inheritance=inheritance), 4) as runner:
        learner = runner.learning
        assert learner is not None
        genome = Genome.random(np.random.default_rng(0), learning=True)
        for origin in (1, 2, 3):
            learner.values.values[2] = 0.25
            serial = int(learner.values.serial[2])
            learner.on_births([(0, 1, 0, 1, origin)], [genome])  # robot 1, slot 0 -> table 2
            inherited = bool((learner.values.values[2] == 0.25).all())
            assert inherited == (inheritance == "lamarckian" and origin == 1)
            assert learner.values.serial[2] == serial + 1
            assert learner.values.alpha[2] == decode_meta(genome.meta, LearningConfig())["alpha"]


def test_lamarckian_offspring_start_from_learned_values_in_a_run() -> None:
    """In a run, every offspring's table holds, right after its birth, exactly the values its
    parent had learned (and they differ from the shipped ones it started from)."""
    with EvolutionRunner(learning_config(inheritance="lamarckian", init="shipped"), 2) as runner:
        learner = runner.learning
        assert learner is not None
        load_births = learner.on_births
        seen: list[bool] = []

        def check(births: Any, genomes: Any, parents: Any = ()) -> None:
            offspring = [robot * 2 + slot for _, robot, slot, _, origin in births if origin == 1]
            before = {table: learner.values.values[table].copy() for table in offspring}
            load_births(births, genomes, parents)
            for table, learned in before.items():
                kept = np.array_equal(learner.values.values[table], learned)
                seen.append(kept and not np.array_equal(learned, learner.initial_values))

        learner.on_births = check  # type: ignore[method-assign, assignment]
        while len(seen) < 3 and runner.steps < 20_000:
            runner.step()
        assert len(seen) >= 3 and all(seen)


def test_resume_of_a_learning_run_is_bit_identical(tmp_path: Path) -> None:
    """Stop at a mid-run checkpoint, restore it in a fresh runner, and finish: the statistics,
    the learning record and every learned value equal those of the uninterrupted run."""
    config = learning_config(init="shipped", inheritance="lamarckian")
    with EvolutionRunner(config, 6) as whole:
        whole.run(4, checkpoint_dir=tmp_path, keep_checkpoints=0)
        expected = (whole.statistics(), whole.learning.record_rows(),  # type: ignore[union-attr]
                    whole.learning.values.values.copy())  # type: ignore[union-attr]
    middle = tmp_path / "gen_00002.ckpt"
    with EvolutionRunner.from_checkpoint(middle, expect=(config, 6)) as resumed:
        resumed.run(4)
        learner = resumed.learning
        assert learner is not None
        assert resumed.statistics().equals(expected[0])
        assert learner.record_rows() == expected[1]
        np.testing.assert_array_equal(learner.values.values, expected[2])


def test_a_fixed_checkpoint_cannot_resume_in_learning_mode(tmp_path: Path) -> None:
    from evolution.checkpoint import CheckpointError

    fixed = RunConfig(method="ee", evolution=EvolutionConfig(**SMALL))  # type: ignore[arg-type]
    with EvolutionRunner(fixed, 1) as runner:
        runner.run(1, checkpoint_dir=tmp_path)
    with pytest.raises(CheckpointError):
        EvolutionRunner.from_checkpoint(tmp_path / "gen_00001.ckpt",
                                        expect=(learning_config(), 1))  # fmt: skip


def test_fixed_mode_runs_are_unchanged_by_the_learning_code() -> None:
    """Outside learning mode no learner exists and no learning draw is made."""
    fixed = RunConfig(method="ee", evolution=EvolutionConfig(**SMALL))  # type: ignore[arg-type]
    with EvolutionRunner(fixed, 1) as runner:
        assert runner.learning is None
        assert runner.scheduler.population()[0].weights.shape == (GENOME_LENGTH,)


def _learning_run(backend: str, stepwise: bool, steps: int) -> tuple[Any, np.ndarray]:
    config = learning_config(init="shipped")
    with EvolutionRunner(config, 8, backend=backend) as runner:  # type: ignore[arg-type]
        if stepwise:
            runner.sense_decide_act = runner.sense_decide_act_stepwise
        for _ in range(steps):
            runner.step()
        assert runner.learning is not None
        return runner.events.to_frame(), runner.learning.values.values.copy()


@pytest.mark.parametrize("backend, stepwise", [("numpy", False), ("numba", True)])
def test_learning_runs_agree_across_backends_and_paths(backend: str, stepwise: bool) -> None:
    """The fused compiled step, its numpy reference and the step-by-step path (rendered or
    noisy vision) make the same learning run: events and learned values."""
    events, values = _learning_run("numba", False, 250)
    other_events, other_values = _learning_run(backend, stepwise, 250)
    assert len(events) > 0 and events.equals(other_events)
    np.testing.assert_array_equal(values, other_values)


def test_deploy_refuses_a_learning_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bundle carries genomes and the shipped behaviours, not an agent's learned values."""
    import json

    from evolution.cli import main

    run = tmp_path / "run"
    run.mkdir()
    record = {"config": {"evolution": {"learning": {"enabled": True}}}, "policies": "learned:x",
              "seed": 0, "target_generations": 1}  # fmt: skip
    (run / "run.json").write_text(json.dumps(record))
    status = main(["deploy", "--from", str(run), "--out", str(tmp_path / "bundle")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and "is a learning-mode run" in err[0]
    assert not (tmp_path / "bundle").exists()


@pytest.mark.parametrize("damage", ["missing", "corrupt"])
def test_shipped_values_missing_or_corrupt_is_one_line(
    damage: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """``learning.init = shipped`` needs the shipped values: without them, or with a damaged
    file, the run stops in one line before anything is written."""
    import shutil

    from behaviours.definitions import VALUES_DIR_ENV_VAR, default_values_dir
    from evolution.cli import main

    values = tmp_path / "values"
    values.mkdir()
    if damage == "corrupt":
        for name in ("mate", "forage", "search"):
            shutil.copy(default_values_dir() / f"{name}.npz", values)
        (values / "forage.npz").write_bytes(b"junk")
    monkeypatch.setenv(VALUES_DIR_ENV_VAR, str(values))
    out = tmp_path / "run"
    status = main(["evolve", "--set", "learning.enabled=true", "--set", "learning.init=shipped",
                   "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and not out.exists()
    assert ("not found" if damage == "missing" else "cannot read action values") in err[0]
