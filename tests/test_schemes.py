"""Evolution schemes as components (evolution.schemes): the registry, mEDEA's rules on
hand-built cases (who receives a genome, who is replaced, and from what), EE's spare list
shared by a robot, the colony or the robots at one position in their arenas, and runs of the
new schemes that resume bit for bit."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from behaviours import BehaviourPolicies
from evolution.agent import Origin
from evolution.config import EvolutionConfig, MedeaConfig
from evolution.genome import Genome
from evolution.runner import EvolutionRunner, RunConfig
from evolution.runner.events import EventKind
from evolution.runner.settings import apply
from evolution.scheduler import CentralisedEvolution, EmbodiedEvolution, spare_groups
from evolution.schemes import (
    SCHEMES,
    MedeaEvolution,
    SchemeSpec,
    register_scheme,
    scheme,
    scheme_names,
    unregister_scheme,
)


def medea_config(n: int = 3, lifetime: int = 5, **changes) -> EvolutionConfig:
    return EvolutionConfig(population_size=n, n_robots=n, lifetime_steps=lifetime,
                           time_sharing_steps=lifetime, **changes)  # fmt: skip


def quiet(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A step in which nothing happens: energy 100, no death, capture or mating."""
    return np.full(n, 100.0), np.zeros(n, bool), np.zeros(n, bool), np.full(n, -1)


# --- the registry ---------------------------------------------------------------------------------
def test_the_registry_holds_the_paper_schemes_and_medea() -> None:
    assert scheme_names()[:3] == ("ee", "ce", "medea")
    assert SCHEMES["ee"].scheduler is EmbodiedEvolution
    assert SCHEMES["ce"].scheduler is CentralisedEvolution
    assert SCHEMES["medea"].scheduler is MedeaEvolution and SCHEMES["medea"].broadcasts
    with pytest.raises(ValueError, match=r"^method must be one of ee, ce, medea.*, got 'x'$"):
        scheme("x")
    with pytest.raises(ValueError, match="method must be one of"):
        RunConfig(method="x")


def test_a_scheme_registered_here_is_a_method() -> None:
    class Cloning(EmbodiedEvolution):
        """EE whose dead agents are replaced by a copy of the robot's next agent."""

        def _on_death(self, robot: int, slot: int) -> None:
            k = self.subpopulation_size
            genome = self.slots[robot][(slot + 1) % k].genome
            self._new_agent(robot, slot, genome, Origin.SPARE)

    register_scheme(SchemeSpec("cloning", "copies on death", Cloning))
    try:
        assert "cloning" in scheme_names()
        config = RunConfig(method="cloning")
        built = scheme(config.method).build(config.evolution, np.random.default_rng(0))
        assert isinstance(built, Cloning)
        with pytest.raises(ValueError, match="exists"):
            register_scheme(SchemeSpec("cloning", "again", Cloning))
    finally:
        unregister_scheme("cloning")
    with pytest.raises(ValueError, match="not a registered scheme"):
        unregister_scheme("ee")


def test_medea_refuses_time_sharing_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"^evolution\.population_size \(100\) must equal "
                       r"evolution\.n_robots \(4\) for method medea"):  # fmt: skip
        RunConfig(method="medea")
    with pytest.raises(ValueError, match=r"^evolution\.time_sharing_steps \(100\) must equal "
                       r"evolution\.lifetime_steps \(400\) for method medea"):  # fmt: skip
        RunConfig(method="medea", evolution=EvolutionConfig(population_size=4))
    RunConfig(method="medea", evolution=medea_config(4, 400))
    with pytest.raises(ValueError, match=r"^evolution\.medea\.broadcast_range must be a number"):
        MedeaConfig(broadcast_range=0.0)


# --- mEDEA by hand --------------------------------------------------------------------------------
def test_medea_receives_from_active_robots_in_range_in_its_arena() -> None:
    """Robots 0 and 1 share arena 0, robot 2 is in arena 1: all in range of each other, yet
    only 0 and 1 exchange; a repeated broadcast is kept once per sender (its latest genome)."""
    sched = MedeaEvolution(medea_config(3), np.random.default_rng(0),
                           robot_arena=np.array([0, 0, 1]))  # fmt: skip
    everyone = np.ones((3, 3), dtype=bool)
    sched.receive(everyone)
    genomes = [sched.slots[r][0].genome for r in range(3)]
    assert sched.received[0] == {1: genomes[1]} and sched.received[1] == {0: genomes[0]}
    assert sched.received[2] == {}
    assert sched.receive_log == [(1, 0, 1), (1, 1, 0)]
    sched.receive(everyone)  # heard again: kept once, not logged again
    assert len(sched.received[0]) == 1 and len(sched.receive_log) == 2
    out_of_range = np.zeros((3, 3), dtype=bool)
    out_of_range[2, 0] = True  # in range but across arenas
    sched.receive(out_of_range)
    assert sched.received[2] == {}


def test_medea_end_of_life_runs_a_received_genome_mutated() -> None:
    """Robot 0 heard robot 1 only: at the end of its 5-step life its new agent is robot 1's
    genome, drawn and mutated with robot 0's own generator; its list is emptied."""
    sched = MedeaEvolution(medea_config(2), np.random.default_rng(3))
    heard = np.zeros((2, 2), dtype=bool)
    heard[0, 1] = True
    sched.receive(heard)
    sent = sched.slots[1][0].genome
    expected_rng = np.random.default_rng()
    expected_rng.bit_generator.state = sched.robot_rngs[0].bit_generator.state
    assert int(expected_rng.integers(1)) == 0
    expected = sent.mutate(expected_rng, sched.config.genetics)
    energy, died, captured, mated = quiet(2)
    for _ in range(5):
        sched.on_step(energy, died, captured, mated)
    agent = sched.slots[0][0]
    assert agent.origin == Origin.RECEIVED and agent.genome == expected
    assert agent.genome != sent  # mutated
    assert sched.received[0] == {} and sched.slot_generation[0, 0] == 1
    assert sched.active[0] and not sched.listening[0]


def test_medea_silent_robot_listens_then_takes_what_it_heard_or_restarts() -> None:
    """Nobody heard anybody: both robots fall silent at the end of their lives (parked,
    logged), and silent robots broadcast nothing, so after a silent lifetime both restart with
    random genomes (listen_lifetimes = 1). With listen_lifetimes = 2 robot 0 stays silent a
    second lifetime and takes the genome it hears in it."""
    sched = MedeaEvolution(medea_config(2), np.random.default_rng(5))
    energy, died, captured, mated = quiet(2)
    for _ in range(5):
        sched.on_step(energy, died, captured, mated)
    assert sched.listening.tolist() == [True, True] and not sched.active.any()
    assert sched.listen_log == [(5, 0), (5, 1)]
    assert sched.active_energy.tolist() == [0.0, 0.0]  # parked
    sched.receive(np.ones((2, 2), dtype=bool))  # silent robots broadcast nothing
    assert sched.received == [{}, {}]
    for _ in range(5):
        sched.on_step(energy, died, captured, mated)
    assert sched.active.all() and not sched.listening.any()
    assert [sched.slots[r][0].origin for r in range(2)] == [Origin.RANDOM] * 2
    assert sched.slot_generation[:, 0].tolist() == [2, 2]  # a life, then a silent life

    waiting = MedeaEvolution(medea_config(2, medea=MedeaConfig(listen_lifetimes=2)),
                             np.random.default_rng(5))  # fmt: skip
    for _ in range(5):
        waiting.on_step(energy, died, captured, mated)
    for _ in range(5):  # the first silent lifetime passes: nothing heard, still silent
        waiting.on_step(energy, died, captured, mated)
    assert waiting.listening.all()
    waiting.listening[1] = False  # robot 1 comes back by hand and broadcasts to robot 0
    waiting.active[1] = True
    heard = np.zeros((2, 2), dtype=bool)
    heard[0, 1] = True
    waiting.receive(heard)
    for _ in range(5):
        waiting.on_step(energy, died, captured, mated)
    assert waiting.active[0] and waiting.slots[0][0].origin == Origin.RECEIVED


def test_medea_death_renews_without_advancing_the_generation() -> None:
    sched = MedeaEvolution(medea_config(2), np.random.default_rng(1))
    sched.receive(np.ones((2, 2), dtype=bool))
    energy, died, captured, mated = quiet(2)
    sched.on_step(energy, died, captured, mated)
    sched.on_step(np.array([0.0, 100.0]), np.array([True, False]), captured, mated)
    assert sched.slots[0][0].origin == Origin.RECEIVED and sched.slot_generation[0, 0] == 0
    assert sched.received[0] == {}  # the list is emptied by the renewal


def test_medea_mating_counts_but_carries_no_genome() -> None:
    sched = MedeaEvolution(medea_config(2), np.random.default_rng(1))
    energy, died, captured, _ = quiet(2)
    sched.on_step(energy, died, captured, np.array([1, 0]))
    assert [sched.agent(r, 0).matings for r in range(2)] == [1, 1]
    assert [sched.agent(r, 0).partners for r in range(2)] == [[], []]


# --- EE's spare list ------------------------------------------------------------------------------
def test_spare_groups() -> None:
    arena = np.array([0, 0, 1, 1, 2, 2])
    assert spare_groups("robot", arena).tolist() == [0, 1, 2, 3, 4, 5]
    assert spare_groups("colony", arena).tolist() == [0] * 6
    assert spare_groups("position", arena).tolist() == [0, 1, 0, 1, 0, 1]
    assert spare_groups("position", np.zeros(3, dtype=np.int64)).tolist() == [0, 1, 2]


@pytest.mark.parametrize("rule", ["robot", "colony", "position"])
def test_a_dead_agent_is_replaced_from_its_group_spare_list(rule: str) -> None:
    """Two arenas of two robots; one spare genome waits in robot 0's group's list. Robot 2's
    agent dies: it takes that genome if it shares robot 0's group (colony; position: robot 2
    is robot 0's twin), else a random one."""
    config = EvolutionConfig(population_size=4, n_robots=4, lifetime_steps=50,
                             time_sharing_steps=50, spare_list=rule)  # fmt: skip
    ee = EmbodiedEvolution(config, np.random.default_rng(2), robot_arena=np.array([0, 0, 1, 1]))
    spare = Genome.random(np.random.default_rng(99))
    ee._spares(0).append(spare)
    energy, died, captured, mated = quiet(4)
    died[2] = True
    ee.on_step(energy, died, captured, mated)
    agent = ee.slots[2][0]
    if rule == "robot":
        assert agent.origin == Origin.RANDOM and ee.spare_lists[0] == [spare]
    else:
        assert agent.origin == Origin.SPARE and agent.genome is spare
        assert sum(len(s) for s in ee.spare_lists) == 0
    assert len(ee.spare_lists) == {"robot": 4, "colony": 1, "position": 2}[rule]


# --- whole runs -----------------------------------------------------------------------------------
def run_config(method: str, **values) -> RunConfig:
    base = {"evolution.n_robots": 8, "world.field_size": 3.3, "world.n_packs": 10,
            "evolution.lifetime_steps": 60, "evolution.time_sharing_steps": 60}  # fmt: skip
    return apply(RunConfig(), {**base, **values}).replace(method=method)


@pytest.mark.parametrize(
    "config",
    [
        pytest.param(run_config("medea", **{"evolution.population_size": 8}), id="medea"),
        pytest.param(run_config("ee", **{"evolution.population_size": 16,
                                         "evolution.spare_list": "colony",
                                         "evolution.time_sharing_steps": 30}),
                     id="ee-colony"),  # fmt: skip
    ],
)
def test_new_schemes_resume_bit_identically(config: RunConfig, tmp_path: Path) -> None:
    def start() -> EvolutionRunner:
        return EvolutionRunner(config, 4, BehaviourPolicies.load_default(), backend="numpy")

    straight = start()
    for _ in range(260):
        straight.step()
    first = start()
    for _ in range(111):
        first.step()
    path = first.save_checkpoint(tmp_path / "mid.ckpt")
    first.close()
    resumed = EvolutionRunner.from_checkpoint(path, BehaviourPolicies.load_default(),
                                              backend="numpy")  # fmt: skip
    for _ in range(260 - 111):
        resumed.step()
    rows = straight.events.state()["rows"]
    np.testing.assert_array_equal(rows, resumed.events.state()["rows"])
    assert straight.scheduler.population() == resumed.scheduler.population()
    kinds = set(rows[:, 2].tolist())
    assert EventKind.BIRTH in kinds
    if config.method == "medea":
        assert EventKind.RECEIVE in kinds
        births = rows[rows[:, 2] == EventKind.BIRTH]
        assert set(births[:, 5].tolist()) <= {Origin.RECEIVED, Origin.RANDOM}
    straight.close()
    resumed.close()


def test_the_paper_schemes_are_untouched_by_the_new_settings() -> None:
    """spare_list and medea at their defaults leave EE the paper's: the fingerprint of the
    default run is the one it had before them (tests/test_controller_memory.py records it)."""
    config = EvolutionConfig()
    assert config.spare_list == "robot" and config.medea == MedeaConfig()
    assert dataclasses.replace(config, spare_list="robot") == config


# --- from the command line ------------------------------------------------------------------------
@pytest.mark.slow  # four sweeps (about a minute); test_plugins covers two workers in the fast suite
def test_a_sweep_of_the_new_schemes_is_the_same_on_one_and_two_workers(tmp_path: Path) -> None:
    """mEDEA and EE with one colony-wide spare list, 8 robots, one generation each: the same
    files from one worker and from two, and a bad scheme is refused in one line."""
    from evolution.cli import main

    common = ["--seeds", "0-1", "--generations", "1", "--no-progress",
              "--set", "evolution.n_robots=8", "--set", "world.field_size=3.3",
              "--set", "world.n_packs=10", "--set", "evolution.lifetime_steps=60",
              "--set", "evolution.time_sharing_steps=60"]  # fmt: skip
    for name, extra in (("medea", ["--methods", "medea", "--set",
                                   "evolution.population_size=8"]),
                        ("pooled", ["--methods", "ee", "--set", "evolution.population_size=16",
                                    "--set", "evolution.spare_list=colony"])):  # fmt: skip
        outs = []
        for workers in (1, 2):
            out = tmp_path / f"{name}-{workers}"
            assert main(["sweep", *common, *extra, "--workers", str(workers),
                         "--out", str(out)]) == 0  # fmt: skip
            outs.append(out)
        runs = sorted(p.relative_to(outs[0]) for p in outs[0].rglob("*.csv"))
        assert len(runs) >= 4
        for relative in runs:
            assert (outs[0] / relative).read_bytes() == (outs[1] / relative).read_bytes()
    events = (tmp_path / "medea-1" / "medea-seed000" / "events.csv").read_text()
    assert ",receive," in events and ",birth," in events


def test_a_bad_scheme_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    from evolution.cli import main

    assert main(["evolve", "--method", "nope", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "method must be one of ee, ce, medea" in err
    assert main(["evolve", "--method", "medea", "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "evolution.population_size (100) must equal" in err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
