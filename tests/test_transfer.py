"""Transfer of evolved agents to a hardware-like colony (paper §4.3, Fig. 7)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from behaviours import BehaviourPolicies
from cyber_rodent.profiles import HardwareProfile
from evolution.config import EvolutionConfig
from evolution.genome import Genome
from evolution.lab.api import RunOutput, RunSpec, execute
from evolution.lab.transfer import (
    ROBOT_STATISTICS_FILE,
    TRANSFER_FILE,
    TransferSpec,
    checkpoint_of_generation,
    fittest_individuals,
    hardware_run_config,
    transfer,
)
from evolution.runner import RunConfig
from evolution.scheduler import EmbodiedEvolution

SMALL = dict(population_size=8, n_robots=4, lifetime_steps=80, time_sharing_steps=40)


@pytest.fixture(scope="module")
def source_run(tmp_path_factory):
    """A short EE run that keeps every generation's checkpoint (generations 1-3)."""
    out = tmp_path_factory.mktemp("source")
    spec = RunSpec("ee", 3, 1, overrides=SMALL, policies=BehaviourPolicies.reactive())
    execute(spec, RunOutput(out, keep_checkpoints=0))
    return out


def test_missing_generation_fails_with_a_clear_message(source_run, tmp_path) -> None:
    with pytest.raises(
        ValueError, match=r"has no checkpoint of generation 40 \(available: 1, 2, 3\)"
    ):
        transfer(TransferSpec(source_run, generation=40), RunOutput(tmp_path / "out"))
    assert not (tmp_path / "out").exists()  # nothing written
    with pytest.raises(ValueError, match=r"--keep-checkpoints 0"):
        checkpoint_of_generation(source_run, 7)
    with pytest.raises(ValueError, match=r"is not a run directory"):
        transfer(TransferSpec(tmp_path, generation=1), RunOutput(tmp_path / "out2"))


def test_fittest_individuals_rank_mated_agents_first() -> None:
    config = EvolutionConfig(population_size=4, n_robots=2)
    genomes = [Genome(np.full(39, float(i))) for i in range(4)]
    scheduler = EmbodiedEvolution(config, np.random.default_rng(0), genomes)
    records = {  # (robot, slot): (age, batteries, matings)
        (0, 0): (100, 2, 0),  # fitness 2, never mated
        (0, 1): (200, 2, 1),  # fitness 1, mated
        (1, 0): (100, 3, 1),  # fitness 3, mated
        (1, 1): (0, 0, 0),
    }
    for (robot, slot), (age, batteries, matings) in records.items():
        agent = scheduler.slots[robot][slot]
        agent.age, agent.batteries, agent.matings = age, batteries, matings
    scheduler._load(0)  # the active agents' counters live in the scheduler's arrays
    scheduler._load(1)
    chosen = fittest_individuals(scheduler, 3)
    assert [(c.robot, c.slot) for c in chosen] == [(1, 0), (0, 1), (0, 0)]
    assert [c.fitness for c in chosen] == [3.0, 1.0, 2.0]
    assert chosen[0].genome == genomes[2]
    with pytest.raises(ValueError, match=r"top must be in \[1, 4\]"):
        fittest_individuals(scheduler, 5)


def test_fittest_individuals_of_a_generation_rank_its_completed_lives() -> None:
    config = EvolutionConfig(population_size=4, n_robots=2, lifetime_steps=4, time_sharing_steps=2)
    genomes = [Genome(np.full(39, float(i))) for i in range(4)]
    scheduler = EmbodiedEvolution(config, np.random.default_rng(0), genomes)
    n = 2

    def step(captured=(), mated=False) -> None:
        partner = np.array([1, 0]) if mated else np.full(n, -1)
        mask = np.zeros(n, dtype=bool)
        mask[list(captured)] = True
        scheduler.on_step(np.full(n, 100.0), np.zeros(n, dtype=bool), mask, partner)

    # Slot-0 agents: robot 1 captures twice (steps 1 and 5), robot 0 once (step 5); slot-1
    # agents: robot 0 captures once (step 3) and both mate (step 4).
    step(captured=(1,))
    step()
    step(captured=(0,))
    step(mated=True)
    step(captured=(0, 1))
    step()
    step()
    step()
    # Fitness over 4-step lives: robot 1 slot 0: 2 / 0.04 = 50; robot 0 slot 0: 25;
    # robot 0 slot 1: 25 with one mating; robot 1 slot 1: 0 with one mating. Agents that mated
    # come first (the paper's fitness of an unmated agent is 0), then the rest by fitness.
    chosen = fittest_individuals(scheduler, 4, generation=0)
    assert [(c.robot, c.slot) for c in chosen] == [(0, 1), (1, 1), (1, 0), (0, 0)]
    assert [c.fitness for c in chosen] == [25.0, 0.0, 50.0, 25.0]
    assert [c.mated for c in chosen] == [True, True, False, False]
    assert chosen[2].genome == genomes[2]  # robot-major: robot 1, slot 0
    # The living agents are the newborns; without a generation they are what is ranked.
    assert all(c.fitness == 0.0 for c in fittest_individuals(scheduler, 4))
    with pytest.raises(ValueError, match=r"top must be in \[1, 4\] \(completed lives"):
        fittest_individuals(scheduler, 5, generation=0)


def test_hardware_run_config_is_consistent() -> None:
    base = RunConfig(evolution=EvolutionConfig(population_size=100, n_robots=4))
    config = hardware_run_config(base, HardwareProfile(), robots=3, agents_per_robot=5)
    assert (config.evolution.n_robots, config.evolution.population_size) == (3, 15)
    assert (config.world.n_robots, config.world.n_packs) == (3, 6)
    assert config.camera.noise == HardwareProfile().vision.noise()
    assert config.evolution.lifetime_steps == base.evolution.lifetime_steps
    plain = hardware_run_config(base, None, robots=3, agents_per_robot=5)
    assert plain.profile is None and plain.world.n_packs == base.world.n_packs
    assert plain.camera == base.camera


def test_transfer_seeds_the_new_colony_and_writes_fig7(source_run, tmp_path) -> None:
    out = tmp_path / "hw"
    spec = TransferSpec(
        source_run, generation=2, top=3, robots=3, agents_per_robot=2, generations=2,
        profile=HardwareProfile(), seed=0,
    )  # fmt: skip
    result = transfer(spec, RunOutput(out))
    meta = json.loads((out / TRANSFER_FILE).read_text())
    assert meta["source_generation"] == 2 and len(meta["individuals"]) == 3
    # The checkpoint of generation 2 is written when generation index 1 closes: its lives.
    assert meta["ranked"] == "lives completed in generation 1 (0-based)"
    assert meta["actuator_sample"]["wheel_gain"][2][0] < 0.8  # the weak robot
    per_robot = pd.read_csv(out / ROBOT_STATISTICS_FILE)
    assert set(per_robot["robot"]) == {0, 1, 2}
    assert list(per_robot.columns[:3]) == ["generation", "robot", "batteries_mean"]
    pooled = pd.read_csv(out / "statistics.csv")
    assert len(pooled) == 2
    # the per-robot means, weighted by lifetimes, are the pooled Fig. 7 measure
    for g, rows in per_robot.groupby("generation"):
        weighted = (rows["batteries_mean"] * rows["full_lifetimes"]).sum()
        total = rows["full_lifetimes"].sum()
        assert weighted / total == pytest.approx(pooled.loc[g, "batteries_full_life_mean"])
    assert all(p.exists() for p in result.figure) and result.figure
    # the new colony started from the chosen individuals, in rank order on every robot
    first = [np.array(i["genome"]) for i in meta["individuals"]]
    record = json.loads((out / "run.json").read_text())
    assert record["config"]["evolution"]["population_size"] == 6
    np.testing.assert_array_equal(result.individuals[0].genome.weights, first[0])
    with pytest.raises(ValueError, match=r"already holds a run"):
        again = TransferSpec(source_run, generation=2, top=3, robots=3, agents_per_robot=2,
                             generations=1)  # fmt: skip
        transfer(again, RunOutput(out))


def test_transfer_is_deterministic(source_run, tmp_path) -> None:
    kwargs = dict(generation=3, top=2, robots=3, agents_per_robot=2, generations=1,
                  profile=HardwareProfile(), seed=4)  # fmt: skip
    spec = TransferSpec(source_run, **kwargs)
    a = transfer(spec, RunOutput(tmp_path / "a"))
    b = transfer(spec, RunOutput(tmp_path / "b"))
    pd.testing.assert_frame_equal(a.per_robot, b.per_robot)
    assert (tmp_path / "a" / "events.csv").read_text() == (
        tmp_path / "b" / "events.csv"
    ).read_text()


def test_cli_transfer_reports_a_missing_generation_in_one_line(source_run, tmp_path, capsys):
    from evolution.cli import main

    code = main(["transfer", "--from", str(source_run), "--generation", "40",
                 "--out", str(tmp_path / "t")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("cyber-rodent transfer: error: ") and err.count("\n") == 1
    assert "no checkpoint of generation 40 (available: 1, 2, 3)" in err
