"""The genome's operators: random initialisation, one-point crossover, mutation."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from evolution.config import GENOME_LENGTH, GeneticConfig
from evolution.genome import RECHARGE, SELECTION, Genome


def test_layout_is_recharge_then_selection() -> None:
    assert (RECHARGE.start, RECHARGE.stop) == (0, 3)
    assert (SELECTION.start, SELECTION.stop) == (3, 39)


def test_genome_is_immutable_and_validated() -> None:
    source = np.zeros(GENOME_LENGTH)
    genome = Genome(source)
    source[0] = 5.0  # the genome copied its input
    assert genome.weights[0] == 0.0
    with pytest.raises(ValueError):
        genome.weights[0] = 1.0
    with pytest.raises(ValueError, match="shape"):
        Genome(np.zeros(38))
    with pytest.raises(ValueError, match="finite"):
        Genome(np.full(GENOME_LENGTH, np.nan))


def test_random_weights_are_uniform_in_minus_one_one() -> None:
    rng = np.random.default_rng(0)
    weights = np.stack([Genome.random(rng).weights for _ in range(2000)])
    assert weights.min() >= -1.0 and weights.max() < 1.0
    # U[-1, 1]: mean 0, std 1/sqrt(3); 78,000 samples give a standard error of ~0.002.
    assert abs(weights.mean()) < 0.01
    assert abs(weights.std() - 1 / np.sqrt(3)) < 0.01


def test_random_is_reproducible() -> None:
    a = Genome.random(np.random.default_rng(7))
    b = Genome.random(np.random.default_rng(7))
    assert a == b


def test_crossover_at_a_given_point_hand_computed() -> None:
    zeros, ones = Genome(np.zeros(GENOME_LENGTH)), Genome(np.ones(GENOME_LENGTH))
    first, second = zeros.crossover(ones, np.random.default_rng(0), point=5)
    expected_first = np.array([0.0] * 5 + [1.0] * 34)
    np.testing.assert_array_equal(first.weights, expected_first)
    np.testing.assert_array_equal(second.weights, 1.0 - expected_first)


def test_crossover_point_under_a_fixed_rng() -> None:
    parent_a = Genome(np.arange(GENOME_LENGTH, dtype=float))
    parent_b = Genome(-np.arange(GENOME_LENGTH, dtype=float) - 1.0)
    first, second = parent_a.crossover(parent_b, np.random.default_rng(42))
    # The cut point is one integers(1, 39) draw from the given generator.
    point = int(np.random.default_rng(42).integers(1, GENOME_LENGTH))
    assert point == 4  # numpy's PCG64 stream for seed 42 (pinned so a change is noticed)
    np.testing.assert_array_equal(first.weights[:4], [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(first.weights[4:], -np.arange(4, 39) - 1.0)
    np.testing.assert_array_equal(second.weights[:4], [-1.0, -2.0, -3.0, -4.0])
    np.testing.assert_array_equal(second.weights[4:], np.arange(4, 39))


def test_crossover_points_cover_1_to_38_and_never_the_ends() -> None:
    zeros, ones = Genome(np.zeros(GENOME_LENGTH)), Genome(np.ones(GENOME_LENGTH))
    rng = np.random.default_rng(1)
    points = []
    for _ in range(4000):
        first, _ = zeros.crossover(ones, rng)
        points.append(int(np.argmax(first.weights)))
    assert set(points) == set(range(1, GENOME_LENGTH))


def test_crossover_rejects_a_bad_point() -> None:
    genome = Genome(np.zeros(GENOME_LENGTH))
    for bad in (0, 39, -1):
        with pytest.raises(ValueError, match="point"):
            genome.crossover(genome, np.random.default_rng(0), point=bad)


def test_mutation_rate_and_range_measured_over_many_genomes() -> None:
    rng = np.random.default_rng(3)
    n = 10_000
    base = Genome(np.zeros(GENOME_LENGTH))
    deltas = np.stack([base.mutate(rng).weights for _ in range(n)])
    changed = deltas != 0.0
    # p = 0.1 over 390,000 weights: standard error 0.00048, so ±0.002 is > 4 sigma.
    assert abs(changed.mean() - 0.1) < 0.002
    moved = deltas[changed]
    assert moved.min() >= -0.5 and moved.max() < 0.5
    # U[-0.5, 0.5]: std 1/sqrt(12) = 0.2887; 39,000 samples give a standard error ~0.001.
    assert abs(moved.mean()) < 0.006
    assert abs(moved.std() - 1 / np.sqrt(12)) < 0.005
    # The mutated weights are spread over all positions, not a fixed subset.
    assert changed.any(axis=0).all()


def test_mutation_leaves_the_parent_untouched_and_respects_the_config() -> None:
    parent = Genome(np.ones(GENOME_LENGTH))
    never = parent.mutate(np.random.default_rng(0), GeneticConfig(mutation_probability=0.0))
    assert never == parent
    always = parent.mutate(np.random.default_rng(0), GeneticConfig(mutation_probability=1.0))
    assert np.all(always.weights != 1.0)
    assert np.all(np.abs(always.weights - 1.0) <= 0.5)
    np.testing.assert_array_equal(parent.weights, np.ones(GENOME_LENGTH))


def test_genome_pickles() -> None:
    genome = Genome.random(np.random.default_rng(5))
    copy = pickle.loads(pickle.dumps(genome))
    assert copy == genome
    assert not copy.weights.flags.writeable
