"""The evolution config holds the paper's numbers and rejects bad input with a named error."""

from __future__ import annotations

import dataclasses

import pytest

from evolution.config import GENOME_LENGTH, EvolutionConfig, GeneticConfig, default_config


def test_defaults_are_the_papers_tables() -> None:
    cfg = default_config()
    # Table 1
    assert cfg.lifetime_steps == 400
    assert cfg.time_sharing_steps == 100
    assert cfg.initial_energy == 100.0
    assert cfg.max_energy == 200.0
    assert cfg.max_recharge_steps == 40
    assert cfg.population_size == 100
    assert cfg.n_robots == 4
    assert cfg.subpopulation_size == 25
    # §3.3: fitness = batteries / (time / 100)
    assert cfg.fitness_time_unit == 100.0
    # Table 2 and §4.1
    g = cfg.genetics
    assert (g.initial_weight_low, g.initial_weight_high) == (-1.0, 1.0)
    assert g.crossover_probability == 0.6
    assert g.mutation_probability == 0.1
    assert (g.mutation_low, g.mutation_high) == (-0.5, 0.5)
    assert g.tournament_size == 2
    assert GENOME_LENGTH == 39


def test_configs_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        default_config().lifetime_steps = 10  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        GeneticConfig().crossover_probability = 0.1  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"population_size": 10, "n_robots": 4}, "population_size"),
        ({"population_size": 2, "n_robots": 4}, "population_size"),
        ({"n_robots": 0}, "n_robots"),
        ({"lifetime_steps": 0}, "lifetime_steps"),
        ({"lifetime_steps": 2.5}, "lifetime_steps"),
        ({"time_sharing_steps": 0}, "time_sharing_steps"),
        ({"time_sharing_steps": 500}, "time_sharing_steps"),
        ({"initial_energy": -1.0}, "initial_energy"),
        ({"initial_energy": 300.0}, "initial_energy"),
        ({"max_energy": float("nan")}, "max_energy"),
        ({"ee_close_quorum": 0.0}, "ee_close_quorum"),
        ({"ee_close_quorum": 1.5}, "ee_close_quorum"),
        ({"max_recharge_steps": 0}, "max_recharge_steps"),
        ({"fitness_time_unit": 0.0}, "fitness_time_unit"),
        ({"ce_fitness_requires_survival": 1}, "ce_fitness_requires_survival"),
    ],
)
def test_bad_evolution_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        EvolutionConfig(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"crossover_probability": 1.5}, "crossover_probability"),
        ({"crossover_probability": -0.1}, "crossover_probability"),
        ({"mutation_probability": 2.0}, "mutation_probability"),
        ({"mutation_probability": float("nan")}, "mutation_probability"),
        ({"initial_weight_low": 1.0, "initial_weight_high": -1.0}, "initial_weight_low"),
        ({"mutation_low": 0.5, "mutation_high": -0.5}, "mutation_low"),
        ({"tournament_size": 0}, "tournament_size"),
    ],
)
def test_bad_genetic_config_names_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        GeneticConfig(**kwargs)


def test_probability_error_states_the_allowed_range() -> None:
    with pytest.raises(ValueError, match=r"crossover_probability must be a number in \[0, 1\]"):
        GeneticConfig(crossover_probability=1.5)


def test_tournament_larger_than_population_is_rejected() -> None:
    with pytest.raises(ValueError, match="tournament_size"):
        EvolutionConfig(population_size=4, n_robots=2, genetics=GeneticConfig(tournament_size=5))
