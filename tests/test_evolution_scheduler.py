"""The EE and CE time-sharing schedulers, driven by scripted event sequences (no physics).

Each test feeds per-robot event arrays by hand (or from a small seeded stand-in colony for
the long-run properties) and checks the paper's rules: round-robin switching after the time-share
or a mating, the generation counter only on full lifetimes, offspring and replacement, the spare
list before random genomes, CE's generational replacement, statistics, determinism and resuming
from a saved state.
"""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np
import pytest

from evolution.agent import Origin, fitness
from evolution.config import GENOME_LENGTH, EvolutionConfig, GeneticConfig
from evolution.genome import Genome
from evolution.reproduction import make_offspring, next_generation
from evolution.scheduler import (
    NO_PARTNER,
    CentralisedEvolution,
    EmbodiedEvolution,
    TimeSharingScheduler,
)

EXACT = GeneticConfig(crossover_probability=0.0, mutation_probability=0.0)


def _step(
    scheduler: TimeSharingScheduler,
    energy: dict[int, float] | None = None,
    died: tuple[int, ...] = (),
    captured: tuple[int, ...] = (),
    mated: tuple[tuple[int, int], ...] = (),
) -> np.ndarray:
    """One control step in which nothing happens except the listed events.

    Energy stays at the active agent's level unless given; a death sets it to 0.
    """
    n = scheduler.n_robots
    energy_after = scheduler.active_energy.copy()
    for robot, value in (energy or {}).items():
        energy_after[robot] = value
    died_mask = np.zeros(n, dtype=bool)
    died_mask[list(died)] = True
    energy_after[died_mask] = 0.0
    captured_mask = np.zeros(n, dtype=bool)
    captured_mask[list(captured)] = True
    partner = np.full(n, NO_PARTNER)
    for a, b in mated:
        partner[a], partner[b] = b, a
    return scheduler.on_step(energy_after, died_mask, captured_mask, partner).copy()


def _no_events(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return (
        np.full(n, 100.0),
        np.zeros(n, dtype=bool),
        np.zeros(n, dtype=bool),
        np.full(n, NO_PARTNER),
    )


def _run(scheduler: TimeSharingScheduler, steps: int) -> None:
    for _ in range(steps):
        _step(scheduler)


def _genome(value: float) -> Genome:
    return Genome(np.full(GENOME_LENGTH, value))


def _numbered(population: int) -> list[Genome]:
    return [_genome(float(i)) for i in range(population)]


# --- time sharing --------------------------------------------------------------------------
def test_initial_state() -> None:
    cfg = EvolutionConfig(population_size=8, n_robots=2)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0), _numbered(8))
    np.testing.assert_array_equal(ee.active_slot, [0, 0])
    assert ee.switched.all()  # the runner loads every robot's first agent like any switch
    np.testing.assert_array_equal(ee.active_energy, [100.0, 100.0])
    # Robot-major assignment: robot 1 slot 0 holds genome 4.
    np.testing.assert_array_equal(ee.active_weights[:, 0], [0.0, 4.0])
    assert not ee.active_weights.flags.writeable


def test_round_robin_switch_after_time_sharing_steps() -> None:
    cfg = EvolutionConfig(population_size=8, n_robots=2)  # 4 agents per robot
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0), _numbered(8))
    for _ in range(99):
        switched = _step(ee, energy={0: 50.0, 1: 60.0})
        assert not switched.any()
    np.testing.assert_array_equal(ee.active_slot, [0, 0])
    switched = _step(ee, energy={0: 40.0, 1: 70.0})  # step 100
    assert switched.all()
    np.testing.assert_array_equal(ee.active_slot, [1, 1])
    np.testing.assert_array_equal(ee.active_energy, [100.0, 100.0])  # the next agents' own
    np.testing.assert_array_equal(ee.active_weights[:, 0], [1.0, 5.0])
    old = ee.agent(0, 0)
    assert (old.age, old.energy) == (100, 40.0)  # saved for its next turn
    # Slots 1, 2, 3 each run 100 steps, then slot 0 returns with its saved energy.
    _run(ee, 300)
    np.testing.assert_array_equal(ee.active_slot, [0, 0])
    np.testing.assert_array_equal(ee.active_energy, [40.0, 70.0])
    assert ee.agent(0, 0).age == 100


def test_mating_ends_both_slots_and_stores_genome_and_fitness() -> None:
    cfg = EvolutionConfig(population_size=16, n_robots=4)
    genomes = _numbered(16)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0), genomes)
    _run(ee, 9)
    _step(ee, captured=(0,))  # step 10
    _run(ee, 19)
    switched = _step(ee, captured=(0,), mated=((0, 1),))  # step 30
    np.testing.assert_array_equal(switched, [True, True, False, False])
    np.testing.assert_array_equal(ee.active_slot, [1, 1, 0, 0])  # 2 and 3 are unaffected
    a, b = ee.agent(0, 0), ee.agent(1, 0)
    assert (a.age, a.batteries, a.matings) == (30, 2, 1)
    assert (b.age, b.batteries, b.matings) == (30, 0, 1)
    # Fitness at the mating = batteries so far / (age / 100), the step's capture included.
    assert a.partners[0].genome is genomes[4] and a.partners[0].fitness == 0.0
    assert b.partners[0].genome is genomes[0]
    assert b.partners[0].fitness == pytest.approx(2 / 0.3)
    # The new agents get a full time share; robots 2 and 3 still switch at step 100.
    switched = _step(ee)
    assert not switched.any()
    _run(ee, 69)  # step 100
    np.testing.assert_array_equal(ee.active_slot, [1, 1, 1, 1])
    _run(ee, 30)  # step 130: robots 0 and 1 have run slot 1 for 100 steps
    np.testing.assert_array_equal(ee.active_slot, [2, 2, 1, 1])


def test_bad_mating_reports_are_rejected() -> None:
    cfg = EvolutionConfig(population_size=8, n_robots=2)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0))
    energy, died, captured, partner = _no_events(2)
    partner[0] = 1  # robot 1 does not report robot 0
    with pytest.raises(ValueError, match="symmetric"):
        ee.on_step(energy, died, captured, partner)
    partner[0] = 0  # a robot cannot mate with itself
    with pytest.raises(ValueError, match="symmetric"):
        ee.on_step(energy, died, captured, partner)
    partner[:] = [5, NO_PARTNER]  # no such robot
    with pytest.raises(ValueError, match="symmetric"):
        ee.on_step(energy, died, captured, partner)


# --- EE lifetimes, generations, offspring ---------------------------------------------------
def _small(**genetics) -> EvolutionConfig:
    """2 robots x 2 agents, lifetime 4, time share 2: short enough to script by hand."""
    return EvolutionConfig(
        lifetime_steps=4,
        time_sharing_steps=2,
        population_size=4,
        n_robots=2,
        genetics=GeneticConfig(**genetics) if genetics else GeneticConfig(),
    )


def test_generation_counter_rises_only_on_full_lifetimes() -> None:
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    # steps 1-2: slot 0 (age 2); 3-4: slot 1 (age 2); 5-6: slot 0 again, reaching age 4.
    _run(ee, 5)
    assert ee.slot_generation.sum() == 0
    _step(ee)  # step 6
    np.testing.assert_array_equal(ee.slot_generation, [[1, 0], [1, 0]])
    # Step 7: robot 0's slot 1 agent (age 3) dies: replaced, its counter does not rise.
    _step(ee, died=(0,))
    np.testing.assert_array_equal(ee.slot_generation, [[1, 0], [1, 0]])
    assert ee.agent(0, 1).age == 0 and ee.agent(0, 1).origin is Origin.RANDOM
    assert ee.stats.rows == []
    # Step 8: robot 1's slot 1 agent completes its lifetime; robot 0's fresh agent runs slot 0.
    _step(ee)
    np.testing.assert_array_equal(ee.slot_generation, [[1, 0], [1, 1]])
    assert ee.completed_generations() == 0


def test_death_on_the_last_step_is_a_death() -> None:
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    _run(ee, 5)
    _step(ee, died=(0,))  # robot 0's slot 0 agent would have completed its lifetime now
    np.testing.assert_array_equal(ee.slot_generation[0], [0, 0])
    np.testing.assert_array_equal(ee.slot_generation[1], [1, 0])


def test_offspring_from_the_fittest_partner_and_spare_list_before_random() -> None:
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    # Step 1: robot 0 captures. Step 2: the slot-0 agents of both robots mate.
    _step(ee, captured=(0,))
    _step(ee, mated=((0, 1),))
    # Steps 3-4: slot 1 agents; they mate too (with fitness 0).
    _step(ee)
    _step(ee, mated=((0, 1),))
    agent = ee.agent(1, 0)
    assert [p.fitness for p in agent.partners] == [50.0]  # 1 battery / (2 / 100)
    # Steps 5-6: slot 0 agents complete their lifetime. Replay robot 1's reproduction.
    _step(ee)
    rng_before = copy.deepcopy(ee.robot_rngs[1])
    own_fitness = fitness(0, 4)
    expected = make_offspring(agent.genome, own_fitness, agent.partners[0], rng_before)
    _step(ee)
    child = ee.agent(1, 0)
    assert child.origin is Origin.OFFSPRING and child.generation == 1
    assert child.genome == expected.offspring
    assert ee.spare_lists[1] == [expected.spare]
    assert len(ee.spare_lists[0]) == 1
    # Steps 7-8: slot 1 agents (mated) also reproduce: two spares per robot.
    _run(ee, 2)
    assert [len(s) for s in ee.spare_lists] == [2, 2]
    assert ee.completed_generations() == 1
    # Generation 1: nobody mates. Each unmated full lifetime takes a spare genome, removing it;
    # only the third replacement on a robot has to make a random genome.
    spares_robot0 = list(ee.spare_lists[0])
    _run(ee, 8)  # both slots live 4 steps each
    new = [ee.agent(0, s) for s in range(2)]
    assert all(a.origin is Origin.SPARE for a in new)
    assert {id(a.genome) for a in new} == {id(g) for g in spares_robot0}
    assert ee.spare_lists[0] == []
    _run(ee, 6)  # slot 0 completes again at step 22: the list is empty now
    assert ee.agent(0, 0).origin is Origin.RANDOM


def test_completed_lives_are_recorded_with_their_genome_and_fitness() -> None:
    """Agents are replaced by their offspring when their life ends, so the scheduler keeps
    each completed life (what transfer ranks); only the newest generations are kept."""
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    _step(ee, captured=(0,))  # step 1: robot 0's slot-0 agent captures a battery
    _step(ee, mated=((0, 1),))  # step 2: the slot-0 agents mate
    _step(ee)
    _step(ee, mated=((0, 1),))  # step 4: the slot-1 agents mate
    _run(ee, 4)  # steps 5-8: every agent completes its 4-step life
    lives = ee.lives_of(0)
    assert [(life.robot, life.slot) for life in lives] == [(0, 0), (1, 0), (0, 1), (1, 1)]
    # Robot 0 slot 0: 1 battery in a 4-step life -> 1 / (4 / 100) = 25; the others caught none.
    assert [life.fitness for life in lives] == [25.0, 0.0, 0.0, 0.0]
    assert [(life.batteries, life.matings) for life in lives] == [(1, 1), (0, 1), (0, 1), (0, 1)]
    assert [life.genome for life in lives] == [_genome(0.0), _genome(2.0), _genome(1.0),
                                               _genome(3.0)]  # fmt: skip
    assert all(life.generation == 0 for life in lives)
    assert ee.agent(0, 0).genome != _genome(0.0)  # the living agent is its offspring
    _run(ee, 24)  # generations 1, 2 and 3; 3 is recorded when 0, 1 and 2 have closed
    assert ee.completed_generations() == 4
    assert sorted(ee.completed_lives) == [1, 2, 3]  # generation 0's records were dropped
    assert ee.lives_of(0) == []
    assert len(ee.lives_of(2)) == 4
    restored = EmbodiedEvolution(ee.config, np.random.default_rng(1))
    restored.load_state(ee.state())  # what a checkpoint stores and restores
    assert restored.lives_of(2) == ee.lives_of(2)


def test_completed_lives_are_kept_while_their_generation_is_open() -> None:
    """EE slots run ahead of the last closed generation: lives are pruned relative to the
    closed generations, so the generation a checkpoint closes still has its lives."""
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    for _ in range(24):  # robot 1's agents keep dying: no generation can close
        _step(ee, died=(1,))
    assert ee.completed_generations() == 0
    np.testing.assert_array_equal(ee.slot_generation, [[3, 3], [0, 0]])
    assert sorted(ee.completed_lives) == [0, 1, 2]  # robot 0 lived generations 0-2
    assert [(life.robot, life.slot) for life in ee.lives_of(0)] == [(0, 0), (0, 1)]


def test_statistics_hand_computed() -> None:
    # 2 robots x 1 agent, lifetime 4, time share 2; no crossover and no mutation so the
    # offspring are hand-predictable.
    cfg = EvolutionConfig(
        lifetime_steps=4, time_sharing_steps=2, population_size=2, n_robots=2, genetics=EXACT
    )
    genomes = _numbered(2)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0), genomes)
    _step(ee, captured=(0,))  # step 1
    _step(ee, mated=((0, 1),))  # step 2: robot 0's fitness 1/(2/100) = 50, robot 1's 0
    _step(ee, captured=(1,))  # step 3
    _step(ee, captured=(1,))  # step 4: both complete the lifetime
    assert len(ee.stats.rows) == 1
    row = ee.stats.rows[0]
    assert (row.generation, row.completed, row.full_lifetimes, row.unmated) == (0, 2, 2, 0)
    assert (row.batteries_mean, row.batteries_std) == (1.5, 0.5)  # batteries 1 and 2
    assert (row.matings_mean, row.matings_std) == (1.0, 0.0)
    assert row.batteries_full_life_mean == 1.5
    assert (row.deaths, row.reproductions, row.crossovers) == (0, 2, 0)
    assert math.isnan(row.random_share)  # only the initial population was born into gen 0
    assert row.spare_list_size == 2
    # Reproduction branch: robot 0 own 1/(4/100) = 25 > partner's 0 -> keeps its own genome;
    # robot 1 own 2/(4/100) = 50 == partner's 50 -> a tie keeps its own genome too.
    assert ee.agent(0, 0).genome == genomes[0] and ee.agent(1, 0).genome == genomes[1]
    assert ee.spare_lists == [[genomes[1]], [genomes[0]]]
    # Generation 1: robot 0 dies at step 5 and takes robot 1's genome from its spare list;
    # robot 1 lives steps 5-8 unmated (spare); robot 0's newcomer lives 6-9 unmated (random).
    _step(ee, died=(0,))
    assert ee.agent(0, 0).genome == genomes[1] and ee.agent(0, 0).origin is Origin.SPARE
    _run(ee, 3)  # step 8
    assert ee.agent(1, 0).origin is Origin.SPARE
    assert len(ee.stats.rows) == 1
    _step(ee)  # step 9
    assert ee.agent(0, 0).origin is Origin.RANDOM
    row = ee.stats.rows[1]
    assert (row.generation, row.completed, row.full_lifetimes, row.unmated) == (1, 0, 2, 2)
    assert math.isnan(row.batteries_mean) and math.isnan(row.matings_std)
    assert row.batteries_full_life_mean == 0.0
    assert (row.deaths, row.reproductions) == (1, 0)
    assert (row.new_offspring, row.new_from_spare, row.new_random) == (2, 1, 0)
    assert row.random_share == 0.0
    assert row.spare_list_size == 0


def test_statistics_csv(tmp_path) -> None:
    ee = EmbodiedEvolution(_small(), np.random.default_rng(0))
    _run(ee, 8)
    path = tmp_path / "stats.csv"
    ee.stats.write_csv(path)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("generation,completed,batteries_mean")
    assert len(lines) == 1 + len(ee.stats.rows) == 2


# --- CE ------------------------------------------------------------------------------------
def test_ce_finished_agents_leave_the_round_robin_and_robots_idle() -> None:
    ce = CentralisedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    _step(ce, died=(0,))  # step 1: robot 0's slot 0 dies -> finished
    np.testing.assert_array_equal(ce.active_slot, [1, 0])
    _step(ce)  # step 2: robot 1 switches to slot 1 after its time share
    np.testing.assert_array_equal(ce.active_slot, [1, 1])
    _step(ce, died=(0,))  # step 3: robot 0's slot 1 dies -> nothing left: robot 0 idles
    assert not ce.active[0] and ce.active[1]
    assert ce.active_agent(0) is None
    assert ce.switched[0]
    energy, died, captured, partner = _no_events(2)
    captured[0] = True
    with pytest.raises(ValueError, match="idle"):
        copy.deepcopy(ce).on_step(energy, died, captured, partner)
    captured[0] = False
    partner[:] = [1, 0]
    with pytest.raises(ValueError, match="idle"):
        copy.deepcopy(ce).on_step(energy, died, captured, partner)
    # Robot 1: slot 1 steps 3-4, slot 0 steps 5-6 (age 4, finished), slot 1 from step 7.
    _run(ce, 4)
    assert ce.generation == 0 and ce.finished[1, 0] and not ce.finished[1, 1]
    np.testing.assert_array_equal(ce.active_slot, [1, 1])


def test_ce_generational_replacement_by_tournament() -> None:
    ce = CentralisedEvolution(_small(), np.random.default_rng(0), _numbered(4))
    # Step 1: the slot-0 agents mate (ending their time share); robot 0 captured a battery.
    _step(ce, captured=(0,), mated=((0, 1),))
    # Steps 2-3: slot 1 agents (robot 1's captures one); 4-5: slot 0 agents (age 3).
    _step(ce, captured=(1,))
    _step(ce)
    np.testing.assert_array_equal(ce.active_slot, [0, 0])
    _run(ce, 2)
    np.testing.assert_array_equal(ce.active_slot, [1, 1])
    _step(ce, died=(0,))  # step 6: robot 0's slot 1 agent dies at age 3 -> finished
    np.testing.assert_array_equal(ce.active_slot, [0, 1])
    _step(ce)  # step 7: robot 0's slot 0 and robot 1's slot 1 reach age 4 -> finished
    assert not ce.active[0] and ce.active[1] and ce.active_slot[1] == 0
    agents = [ce.agent(r, s) for r in range(2) for s in range(2)]
    # CE fitness: mated and survived -> batteries / (age / 100); unmated or dead -> 0.
    fit = [ce.ce_fitness(a) for a in agents]
    assert fit == [25.0, 0.0, 0.0, 0.0]
    rng_before = copy.deepcopy(ce._rng)
    expected, _ = next_generation([a.genome for a in agents], np.array(fit), rng_before)
    switched = _step(ce)  # step 8: robot 1's slot 0 completes -> everyone finished
    assert switched.all() and ce.active.all()
    assert ce.generation == 1 and ce.completed_generations() == 1
    np.testing.assert_array_equal(ce.active_slot, [0, 0])
    np.testing.assert_array_equal(ce.slot_generation, [[1, 1], [1, 1]])
    assert ce.population() == expected
    assert all(ce.agent(r, s).origin is Origin.SELECTED for r in range(2) for s in range(2))
    assert all(ce.agent(r, s).age == 0 for r in range(2) for s in range(2))
    np.testing.assert_array_equal(ce.active_energy, [100.0, 100.0])
    assert not ce.finished.any()
    row = ce.stats.rows[0]
    assert (row.completed, row.full_lifetimes, row.unmated, row.deaths) == (2, 3, 1, 1)
    assert (row.batteries_mean, row.matings_mean) == (0.5, 1.0)
    assert row.reproductions == 4 and row.spare_list_size == 0


def test_ce_fitness_of_a_dead_mated_agent_follows_the_config() -> None:
    for requires_survival, expected in ((True, 0.0), (False, 100.0)):
        cfg = EvolutionConfig(
            lifetime_steps=4,
            time_sharing_steps=2,
            population_size=4,
            n_robots=2,
            ce_fitness_requires_survival=requires_survival,
        )
        ce = CentralisedEvolution(cfg, np.random.default_rng(0))
        _step(ce, captured=(0,), mated=((0, 1),))  # step 1: robot 0 fitness 1 / (1/100)
        agent = ce.agent(0, 0)
        agent.dead = True
        assert ce.ce_fitness(agent) == expected


# --- long runs with a seeded stand-in colony ------------------------------------------------
class _StandInColony:
    """Seeded random events with the paper's energy arithmetic, in place of physics.

    Energy falls by 1 per step; a capture (probability rising with one gene, the Forage bias
    weight, so selection has something to act on) adds a compressed recharge of +60 up to 200;
    a random pair of robots mates now and then. Only for exercising the schedulers.
    """

    FORAGE_BIAS = 3 + 12 + 10

    def __init__(self, n_robots: int, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.energy = np.zeros(n_robots)
        self.died = np.zeros(n_robots, dtype=bool)
        self.captured = np.zeros(n_robots, dtype=bool)
        self.partner = np.full(n_robots, NO_PARTNER)

    def step(self, scheduler: TimeSharingScheduler) -> None:
        switched = scheduler.switched
        self.energy[switched] = scheduler.active_energy[switched]
        active = scheduler.active
        gene = scheduler.active_weights[:, self.FORAGE_BIAS]
        p_capture = 0.004 + 0.02 / (1.0 + np.exp(-3.0 * gene))
        self.captured[:] = (self.rng.random(len(gene)) < p_capture) & active
        self.energy -= 1.0
        self.energy[self.captured] = np.minimum(self.energy[self.captured] + 60.0, 200.0)
        self.died[:] = (self.energy <= 0.0) & active
        self.energy[self.died] = 0.0
        self.partner[:] = NO_PARTNER
        candidates = np.flatnonzero(active)
        if len(candidates) >= 2 and self.rng.random() < 0.03:
            a, b = self.rng.choice(candidates, size=2, replace=False)
            self.partner[a], self.partner[b] = b, a
        scheduler.on_step(self.energy, self.died, self.captured, self.partner)


def _evolve(scheduler: TimeSharingScheduler, colony: _StandInColony, generations: int) -> None:
    while scheduler.completed_generations() < generations:
        colony.step(scheduler)


def test_ee_long_run_has_nontrivial_statistics_and_selection_works() -> None:
    # Quorum 1.0: rows close only when every slot has passed, so the per-row birth accounting
    # below is exact (with a quorum < 1, lagging slots' late events are counted apart).
    cfg = EvolutionConfig(ee_close_quorum=1.0)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(1))
    colony = _StandInColony(cfg.n_robots, seed=2)
    _evolve(ee, colony, 4)
    rows = ee.stats.rows
    assert len(rows) == 4
    assert all(r.completed > 0 and r.deaths > 0 and r.reproductions > 0 for r in rows)
    assert sum(r.new_random for r in rows) > 0
    assert rows[0].random_share > rows[-1].random_share
    assert rows[-1].spare_list_size > 0
    # Every slot ending makes exactly one new agent: deaths in generation g are replaced in g,
    # full lifetimes of g by agents of g + 1 (EE offspring are one per reproduction).
    for g, row in enumerate(rows):
        born = row.new_offspring + row.new_from_spare + row.new_random
        previous_full = rows[g - 1].full_lifetimes if g else 0
        assert born == previous_full + row.deaths
        assert row.new_offspring == (rows[g - 1].reproductions if g else 0)
    # The gene that raises the capture rate is selected for.
    gene = _StandInColony.FORAGE_BIAS
    assert np.mean([g.weights[gene] for g in ee.population()]) > 0.1


def test_ce_long_run_has_nontrivial_statistics() -> None:
    cfg = EvolutionConfig()
    ce = CentralisedEvolution(cfg, np.random.default_rng(1))
    colony = _StandInColony(cfg.n_robots, seed=2)
    _evolve(ce, colony, 3)
    rows = ce.stats.rows
    assert len(rows) == 3
    for row in rows:
        assert row.full_lifetimes + row.deaths == cfg.population_size
        assert row.completed > 0 and row.reproductions == cfg.population_size
        assert row.new_random == 0 and row.spare_list_size == 0
        assert 0 < row.crossovers < cfg.population_size


@pytest.mark.parametrize("method", [EmbodiedEvolution, CentralisedEvolution])
def test_same_seed_same_statistics_and_restored_state_resumes_identically(method) -> None:
    cfg = EvolutionConfig(population_size=20, n_robots=4)

    def fresh() -> tuple[TimeSharingScheduler, _StandInColony]:
        return method(cfg, np.random.default_rng(11)), _StandInColony(4, seed=12)

    a, colony_a = fresh()
    for _ in range(12_000):
        colony_a.step(a)
    b, colony_b = fresh()
    for _ in range(5_000):
        colony_b.step(b)
    state = b.state()  # the scheduler's checkpoint state; the stand-in colony is the test's
    b = method(cfg, np.random.default_rng(99))
    b.load_state(state)
    colony_b = pickle.loads(pickle.dumps(colony_b))
    for _ in range(7_000):
        colony_b.step(b)
    assert len(a.stats.rows) >= 2
    assert _nan_equal(a, b)
    assert a.population() == b.population()
    np.testing.assert_array_equal(a.slot_generation, b.slot_generation)
    c, colony_c = method(cfg, np.random.default_rng(13)), _StandInColony(4, seed=12)
    for _ in range(12_000):
        colony_c.step(c)
    assert a.population() != c.population()


def _nan_equal(a: TimeSharingScheduler, b: TimeSharingScheduler) -> bool:
    """Row equality where NaN equals NaN (dict equality treats NaN != NaN)."""
    ra, rb = a.stats.to_records(), b.stats.to_records()
    if len(ra) != len(rb):
        return False
    for x, y in zip(ra, rb, strict=True):
        for key in x:
            u, v = x[key], y[key]
            if not (u == v or (isinstance(u, float) and math.isnan(u) and math.isnan(v))):
                return False
    return True


def test_bad_constructor_input() -> None:
    cfg = EvolutionConfig(population_size=8, n_robots=2)
    with pytest.raises(ValueError, match="initial_genomes"):
        EmbodiedEvolution(cfg, np.random.default_rng(0), _numbered(7))
    with pytest.raises(ValueError, match="rng"):
        EmbodiedEvolution(cfg, 0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="config"):
        EmbodiedEvolution({}, np.random.default_rng(0))  # type: ignore[arg-type]


def test_ee_rows_close_at_the_quorum_of_slots() -> None:
    """4 robots x 5 slots = 20 slots; quorum 0.9 -> 18 slots must have passed a generation."""
    cfg = EvolutionConfig(population_size=20, ee_close_quorum=0.9)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0))
    assert ee._quorum == 18
    ee.slot_generation[:] = 3
    ee.slot_generation[0, :2] = 0  # two lagging slots: 18 slots have reached generation 3
    assert ee._quorum_generation() == 3
    ee.slot_generation[0, 2] = 1  # a third laggard: only 17 slots at 3, 18 at >= 1
    assert ee._quorum_generation() == 1
    exact = EmbodiedEvolution(
        EvolutionConfig(population_size=20, ee_close_quorum=1.0), np.random.default_rng(0)
    )
    exact.slot_generation[:] = 3
    exact.slot_generation[0, 0] = 0
    assert exact._quorum_generation() == 0 and exact._quorum == 20


def test_ee_quorum_run_counts_late_events_and_finishes() -> None:
    cfg = EvolutionConfig(ee_close_quorum=0.9)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(1))
    colony = _StandInColony(cfg.n_robots, seed=2)
    _evolve(ee, colony, 4)
    assert len(ee.stats.rows) == 4 and ee.completed_generations() == 4
    # A tenth of the slots may still be behind the last closed row.
    passed = (ee.slot_generation >= 4).sum()
    assert passed >= 90 and ee.slot_generation.size == 100
    assert ee.stats.late >= 0


def _assert_same_state(a: object, b: object, where: str = "state") -> None:
    """Nested plain state (dicts, lists, arrays, scalars) equal, exactly."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for key in a:
            _assert_same_state(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list | tuple):
        assert isinstance(b, list | tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same_state(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where  # an empty statistic is NaN
    else:
        assert a == b, where


@pytest.mark.parametrize("method", [EmbodiedEvolution, CentralisedEvolution])
def test_compiled_tick_equals_numpy(method) -> None:
    """The compiled per-step bookkeeping (backend "numba") changes nothing against its numpy
    reference: the same random event stream gives the same switches, ages, statistics, agents,
    spare lists and RNG states."""

    def drive(backend: str) -> tuple[list[np.ndarray], TimeSharingScheduler]:
        config = EvolutionConfig(
            lifetime_steps=30, time_sharing_steps=10, population_size=12, n_robots=4
        )
        scheduler = method(config, np.random.default_rng(5), backend=backend)
        events = np.random.default_rng(6)
        switches = []
        for _ in range(600):
            n = scheduler.n_robots
            energy = events.uniform(1.0, 200.0, n)
            died = scheduler.active & (events.random(n) < 0.02)
            energy[died] = 0.0
            captured = scheduler.active & ~died & (events.random(n) < 0.05)
            partner = np.full(n, NO_PARTNER)
            free = np.flatnonzero(scheduler.active & ~died).tolist()
            if len(free) >= 2 and events.random() < 0.05:
                a, b = free[0], free[-1]
                partner[a], partner[b] = b, a
            switches.append(scheduler.on_step(energy, died, captured, partner).copy())
        return switches, scheduler

    fast, a = drive("numba")
    slow, b = drive("numpy")
    np.testing.assert_array_equal(np.array(fast), np.array(slow))
    assert np.array(fast).sum() > 100  # slots ended often: not vacuous
    np.testing.assert_array_equal(a.active_age, b.active_age)
    np.testing.assert_array_equal(a.active_energy, b.active_energy)
    _assert_same_state(a.stats.state(), b.stats.state())
    _assert_same_state(a.state(), b.state())  # agents, RNGs and spare lists too


# --- reproduction variants -----------------------------------------------------------------
def test_candidate_probability_by_hand() -> None:
    """p = clip(E / energy_full, 0, 1): energy 150 of 200 -> 0.75; 250 -> 1; 0 -> 0; off -> 1."""
    from evolution.config import ReproductionConfig

    variant = ReproductionConfig(energy_dependent=True, energy_full=200.0)
    assert variant.candidate_probability(150.0) == 0.75
    assert variant.candidate_probability(250.0) == 1.0
    assert variant.candidate_probability(0.0) == 0.0
    assert ReproductionConfig().candidate_probability(0.0) == 1.0


@pytest.mark.parametrize("method", ["ee", "ce"])
def test_energy_dependent_matings_yield_candidates_by_draw(method: str) -> None:
    """Robot 0 (energy 150) and robot 1 (energy 30) mate: robot 1 keeps robot 0's genome with
    p = 0.75, robot 0 keeps robot 1's with p = 0.15; each side draws once, in robot order, from
    its robot's generator (EE) or the central one (CE). Both count the mating either way."""
    from evolution.config import ReproductionConfig

    cfg = EvolutionConfig(
        population_size=8, n_robots=2,
        reproduction=ReproductionConfig(energy_dependent=True, energy_full=200.0),
    )  # fmt: skip
    scheduler_cls = EmbodiedEvolution if method == "ee" else CentralisedEvolution
    outcomes = set()
    for seed in range(40):
        scheduler = scheduler_cls(cfg, np.random.default_rng(seed), _numbered(8))
        if isinstance(scheduler, EmbodiedEvolution):
            draws = [copy.deepcopy(scheduler.robot_rngs[r]).random() for r in (0, 1)]
        else:
            twin = copy.deepcopy(scheduler._rng)
            draws = [twin.random(), twin.random()]
        _step(scheduler, energy={0: 150.0, 1: 30.0}, mated=((0, 1),))
        a, b = scheduler.agent(0, 0), scheduler.agent(1, 0)
        assert a.matings == b.matings == 1
        assert len(a.partners) == int(draws[0] < 0.15)  # robot 0 keeps robot 1's genome
        assert len(b.partners) == int(draws[1] < 0.75)
        outcomes.add((len(a.partners), len(b.partners)))
    assert len(outcomes) >= 3  # the draws decide


def test_paper_rule_keeps_every_mating_as_a_candidate() -> None:
    cfg = EvolutionConfig(population_size=8, n_robots=2)
    ee = EmbodiedEvolution(cfg, np.random.default_rng(0), _numbered(8))
    state = copy.deepcopy(ee.robot_rngs[0].bit_generator.state)
    _step(ee, energy={0: 1.0, 1: 1.0}, mated=((0, 1),))
    assert len(ee.agent(0, 0).partners) == len(ee.agent(1, 0).partners) == 1
    assert ee.robot_rngs[0].bit_generator.state == state  # no draw
