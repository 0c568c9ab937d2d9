"""The EE offspring and replacement rules and the CE tournament, with hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from evolution.agent import MatingRecord, Origin, VirtualAgent, fitness
from evolution.config import GENOME_LENGTH, GeneticConfig
from evolution.genome import Genome
from evolution.reproduction import (
    draw_replacement,
    make_offspring,
    next_generation,
    tournament,
)

NO_MUTATION = dict(mutation_probability=0.0)
ZEROS = Genome(np.zeros(GENOME_LENGTH))
ONES = Genome(np.ones(GENOME_LENGTH))


def test_fitness_rule_hand_computed() -> None:
    # batteries / (time / 100)
    assert fitness(6, 400) == 1.5
    assert fitness(2, 50) == 4.0
    assert fitness(0, 400) == 0.0
    assert fitness(0, 0) == 0.0
    agent = VirtualAgent(ZEROS, 100.0, age=200, batteries=3)
    assert agent.fitness() == 1.5


def test_fittest_partner_and_tie_goes_to_the_earliest() -> None:
    agent = VirtualAgent(ZEROS, 100.0)
    assert agent.fittest_partner() is None
    a, b, c = (Genome(np.full(GENOME_LENGTH, float(i))) for i in (1, 2, 3))
    agent.partners += [MatingRecord(a, 1.0), MatingRecord(b, 4.0), MatingRecord(c, 4.0)]
    assert agent.fittest_partner().genome == b


def test_crossover_branch_child_selection_under_a_fixed_rng() -> None:
    genetics = GeneticConfig(crossover_probability=1.0, **NO_MUTATION)
    partner = MatingRecord(ONES, 0.0)
    result = make_offspring(ZEROS, 0.0, partner, np.random.default_rng(1), genetics)
    assert result.crossover
    # Replay the documented draw order: branch uniform, cut point, child index.
    replay = np.random.default_rng(1)
    replay.random()
    point = int(replay.integers(1, GENOME_LENGTH))
    pick = int(replay.integers(2))
    assert (point, pick) == (29, 1)  # numpy's PCG64 stream for seed 1 (pinned)
    # first child = own[:29] + partner[29:], second = partner[:29] + own[29:]; pick 1 = second.
    expected_offspring = np.array([1.0] * 29 + [0.0] * 10)
    np.testing.assert_array_equal(result.offspring.weights, expected_offspring)
    np.testing.assert_array_equal(result.spare.weights, 1.0 - expected_offspring)
    # Seed 2 draws point 5 and pick 0: the first child becomes the offspring.
    result = make_offspring(ZEROS, 0.0, partner, np.random.default_rng(2), genetics)
    np.testing.assert_array_equal(result.offspring.weights, [0.0] * 5 + [1.0] * 34)
    np.testing.assert_array_equal(result.spare.weights, [1.0] * 5 + [0.0] * 34)


def test_crossover_branch_picks_each_child_half_the_time() -> None:
    genetics = GeneticConfig(crossover_probability=1.0, **NO_MUTATION)
    rng = np.random.default_rng(1)
    first_child = 0
    n = 4000
    for _ in range(n):
        result = make_offspring(ZEROS, 0.0, MatingRecord(ONES, 0.0), rng, genetics)
        first_child += result.offspring.weights[0] == 0.0  # own genome's head
    assert abs(first_child / n - 0.5) < 0.04  # 5 sigma


@pytest.mark.parametrize(
    ("own_fitness", "partner_fitness", "offspring_is_partner"),
    [(1.0, 2.0, True), (3.0, 2.0, False), (2.0, 2.0, False)],
)
def test_reproduction_branch_keeps_the_fitter(
    own_fitness: float, partner_fitness: float, offspring_is_partner: bool
) -> None:
    genetics = GeneticConfig(crossover_probability=0.0, **NO_MUTATION)
    result = make_offspring(
        ZEROS, own_fitness, MatingRecord(ONES, partner_fitness), np.random.default_rng(0), genetics
    )
    assert not result.crossover
    assert result.offspring == (ONES if offspring_is_partner else ZEROS)
    assert result.spare == (ZEROS if offspring_is_partner else ONES)


def test_both_offspring_and_spare_are_mutated() -> None:
    genetics = GeneticConfig(crossover_probability=0.0, mutation_probability=1.0)
    result = make_offspring(ZEROS, 0.0, MatingRecord(ONES, 1.0), np.random.default_rng(2), genetics)
    assert np.all(result.offspring.weights != 1.0)
    assert np.all(np.abs(result.offspring.weights - 1.0) <= 0.5)
    assert np.all(result.spare.weights != 0.0)
    assert np.all(np.abs(result.spare.weights) <= 0.5)


def test_crossover_probability_measured() -> None:
    rng = np.random.default_rng(4)
    n = 5000
    crossed = sum(
        make_offspring(ZEROS, 0.0, MatingRecord(ONES, 0.0), rng).crossover for _ in range(n)
    )
    assert abs(crossed / n - 0.6) < 0.035  # 5 sigma of a binomial(5000, 0.6) share


def test_replacement_takes_from_the_spare_list_before_random_genomes() -> None:
    spares = [Genome(np.full(GENOME_LENGTH, float(i))) for i in range(3)]
    spare_list = list(spares)
    expected_list = list(spares)
    rng = np.random.default_rng(0)
    replay = np.random.default_rng(0)  # one integers(len) draw per spare-list pick
    for remaining in (3, 2, 1):
        genome, origin = draw_replacement(spare_list, rng)
        assert origin is Origin.SPARE
        assert genome is expected_list.pop(int(replay.integers(remaining)))
        assert spare_list == expected_list  # the drawn genome was removed
    assert spare_list == []
    genome, origin = draw_replacement(spare_list, rng)
    assert origin is Origin.RANDOM  # only now, with the list empty
    assert np.all(np.abs(genome.weights) <= 1.0)
    assert genome not in spares


def test_tournament_hand_computed() -> None:
    # With two individuals a size-2 tournament always compares both.
    assert all(tournament(np.array([1.0, 2.0]), np.random.default_rng(s)) == 1 for s in range(20))
    # Under a fixed rng the winner is the fitter of the two drawn contenders.
    fit = np.array([0.0, 5.0, 3.0, 1.0])
    replay = np.random.default_rng(9)
    contenders = replay.choice(4, size=2, replace=False)
    winner = tournament(fit, np.random.default_rng(9))
    assert winner in contenders and fit[winner] == fit[contenders].max()


def test_tournament_selection_probabilities() -> None:
    # Size 2 without replacement over 3 individuals: the worst never wins, the best wins
    # every pair it is in (2 of 3 pairs), the middle wins only against the worst (1 of 3).
    fit = np.array([3.0, 1.0, 2.0])
    rng = np.random.default_rng(5)
    wins = np.bincount([tournament(fit, rng) for _ in range(9000)], minlength=3) / 9000
    assert wins[1] == 0.0
    assert abs(wins[0] - 2 / 3) < 0.025
    assert abs(wins[2] - 1 / 3) < 0.025


def test_tournament_tie_goes_to_the_first_drawn() -> None:
    fit = np.zeros(5)
    replay = np.random.default_rng(3)
    first = replay.choice(5, size=2, replace=False)[0]
    assert tournament(fit, np.random.default_rng(3)) == first


def test_next_generation_selects_copies_with_tournament_odds() -> None:
    # One individual of 10 has fitness 10: a tournament includes it with p = 1 - C(9,2)/C(10,2)
    # = 0.2, and then it wins. Without crossover and mutation each new individual is a copy.
    genomes = [Genome(np.full(GENOME_LENGTH, float(i))) for i in range(10)]
    fit = np.zeros(10)
    fit[9] = 10.0
    genetics = GeneticConfig(crossover_probability=0.0, **NO_MUTATION)
    rng = np.random.default_rng(8)
    copies_of_best = 0
    total = 0
    for _ in range(300):
        new, crossed = next_generation(genomes, fit, rng, genetics)
        assert len(new) == 10 and not any(crossed)
        assert all(g in genomes for g in new)
        copies_of_best += sum(g == genomes[9] for g in new)
        total += len(new)
    assert abs(copies_of_best / total - 0.2) < 0.025  # 5 sigma over 3000 draws


def test_next_generation_crosses_and_mutates() -> None:
    genomes = [ZEROS, ONES]
    new, crossed = next_generation(genomes, np.array([1.0, 1.0]), np.random.default_rng(0))
    assert len(new) == 2 and len(crossed) == 2
    with pytest.raises(ValueError, match="fitness"):
        next_generation(genomes, np.zeros(3), np.random.default_rng(0))
    with pytest.raises(ValueError, match="tournament_size"):
        next_generation(
            genomes, np.zeros(2), np.random.default_rng(0), GeneticConfig(tournament_size=3)
        )


def test_next_generation_names_each_childs_first_parent() -> None:
    """Without crossover or mutation every child is a copy of the parent it names; with
    crossover the child starts with that parent's genes; the list draws nothing."""
    genomes = [Genome(np.full(GENOME_LENGTH, float(i))) for i in range(7)]
    fit = np.arange(7.0)
    parents: list[int] = [99]
    copies = GeneticConfig(crossover_probability=0.0, **NO_MUTATION)
    new, _ = next_generation(genomes, fit, np.random.default_rng(4), copies, parents)
    assert len(parents) == 7 and all(new[i] == genomes[p] for i, p in enumerate(parents))
    again, _ = next_generation(genomes, fit, np.random.default_rng(4), copies)
    assert again == new  # the same draws with or without the list
    crossing = GeneticConfig(crossover_probability=1.0, **NO_MUTATION)
    new, _ = next_generation(genomes, fit, np.random.default_rng(5), crossing, parents)
    assert all(new[i].weights[0] == float(p) for i, p in enumerate(parents))
