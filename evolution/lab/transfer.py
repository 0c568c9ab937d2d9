"""Transfer evolved agents to a hardware-like colony and continue evolution (paper §4.3, Fig. 7).

The paper took the 5 fittest individuals of generation 40 of a simulated run onto 3 real CRs,
5 virtual agents each, and evolved them about 10 more generations; sensors were noisier,
behaviours slower and one robot weaker. :func:`transfer` does the same in simulation with a
:class:`~cyber_rodent.profiles.HardwareProfile` (or without one, for a control):

1. read the source run's checkpoint of the requested generation (``gen_NNNNN.ckpt`` is written
   when that many generations have completed; run the source with ``--keep-checkpoints 0`` so
   that every generation's checkpoint is kept);
2. rank the agents that lived the full lifetime in the last generation that closed (the
   checkpoint ``gen_00040`` is written when generation index 39, the 40th, closes) by the
   paper's fitness over their whole life, batteries / (lifetime / 100), agents that mated
   first (the paper's fitness exists only at a mating: an agent that never mated scores 0),
   and take the ``top``.
   Those agents have already been replaced by their offspring, so the scheduler keeps their
   records (:attr:`~evolution.scheduler.TimeSharingScheduler.completed_lives`); a checkpoint
   from before that record existed falls back to the living agents, mated ones first;
3. seed every robot's ``agents_per_robot`` slots with those individuals in rank order
   (cycling if there are more slots than individuals), the world built with the profile;
4. run ``generations`` generations of the same method and write a run directory with
   ``statistics.csv``, the per-robot table ``statistics_per_robot.csv`` (Fig. 7 measure: mean
   batteries over each robot's full lifetimes, unmated agents scored 0), ``events.csv``,
   ``transfer.json`` (source, the chosen individuals, the profile, the actuator sample) and
   ``figures/fig7.png``/``.pdf``.

A transfer run directory cannot be continued with ``cyber-rodent resume`` (its initial
population is not in ``run.json``); rerun the transfer, which is deterministic for a seed.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output, write_text
from cyber_rodent.profiles import HardwareProfile, apply_field, apply_vision
from cyber_rodent.validation import check_integer
from evolution.genome import Genome
from evolution.lab.api import (
    CHECKPOINT_DIR,
    EVENTS_FILE,
    ROBOT_STATISTICS_FILE,
    RUN_FILE,
    RunOutput,
    extra_tables,
    robot_table,
    run_record,
    write_tables,
)
from evolution.lab.experiment import policies_for_identity, read_run_record
from evolution.lab.figures import plot_per_robot
from evolution.runner import EvolutionRunner, RunConfig, list_checkpoints
from evolution.scheduler import TimeSharingScheduler

TRANSFER_FILE = "transfer.json"
FIGURE_BASE = "figures/fig7"


def hardware_run_config(
    base: RunConfig,
    profile: HardwareProfile | None,
    *,
    robots: int | None = None,
    agents_per_robot: int | None = None,
) -> RunConfig:
    """``base`` moved to the hardware-like world of ``profile``.

    Args:
        base: the source configuration (method, evolution rules, survival, camera).
        profile: the hardware-like profile (None: the plain simulation, only the counts change).
        robots: robots of the new colony (default: the profile's field, else ``base``'s).
        agents_per_robot: virtual agents per robot (default: ``base``'s).

    Returns:
        A consistent config: ``n_robots`` and ``population_size`` updated, the field's packs,
        the camera's noise and the profile itself set.
    """
    evo = base.evolution
    if robots is None:
        robots = profile.field.n_robots if profile is not None and profile.field.enabled else None
        robots = robots if robots is not None else evo.n_robots
    robots = check_integer("robots", robots, 1)
    k = check_integer(
        "agents_per_robot",
        agents_per_robot if agents_per_robot is not None else evo.subpopulation_size,
        1,
    )
    world = dataclasses.replace(base.world, n_robots=robots)
    camera = base.camera
    if profile is not None:
        layout = dataclasses.replace(profile.field, n_robots=robots)
        profile = dataclasses.replace(profile, field=layout)
        world = apply_field(world, layout)
        camera = apply_vision(camera, profile.vision)
    evolution = dataclasses.replace(evo, n_robots=robots, population_size=robots * k)
    return base.replace(evolution=evolution, world=world, camera=camera, profile=profile)


def checkpoint_of_generation(run_dir: str | os.PathLike[str], generation: int) -> Path:
    """The checkpoint written when ``generation`` generations had completed.

    Raises:
        ValueError: ``run_dir`` has no such checkpoint; the message lists the generations it
            has and how to keep them all.
    """
    generation = check_integer("generation", generation, 0)
    directory = Path(run_dir) / CHECKPOINT_DIR
    found = list_checkpoints(directory)
    for path in found:
        if int(path.stem.split("_")[1]) == generation:
            return path
    have = [int(p.stem.split("_")[1]) for p in found]
    available = ", ".join(map(str, have)) if have else "none"
    raise ValueError(
        f"{run_dir} has no checkpoint of generation {generation} (available: {available}); "
        "evolve the source run with --keep-checkpoints 0 to keep every generation, or choose "
        "an available generation"
    )


@dataclass(frozen=True)
class Individual:
    """One individual chosen for transfer.

    Attributes:
        genome: its controller weights.
        fitness: batteries / (age / 100) of its record (its whole life, for a completed life).
        mated: it had mated at least once.
        robot, slot: where it lived in the source run.
    """

    genome: Genome
    fitness: float
    mated: bool
    robot: int
    slot: int


def fittest_individuals(
    scheduler: TimeSharingScheduler, top: int, generation: int | None = None
) -> list[Individual]:
    """The ``top`` fittest individuals of ``generation``, or of the living population.

    With ``generation``, the agents that completed their lifetime in it are ranked by the
    paper's fitness over their whole life, agents that mated first (ties: more matings first,
    then the order in which the lives ended). The paper computes fitness at a mating and scores
    an agent that never mated 0 (its Fig. 7), so a forager that never mated, however many
    batteries it captured, ranks below every agent that did. The lives, not the living agents,
    are what "the fittest individuals of generation 40" means: when a generation closes, most
    of its agents have already been replaced by their newborn offspring, whose records are
    still empty. The scheduler keeps the lives of its newest generations
    (:attr:`~evolution.scheduler.TimeSharingScheduler.completed_lives`).

    Without ``generation`` (or for a generation of which no full life is recorded), every
    living agent is ranked by its record so far, agents that have mated first; ties keep the
    robot-major slot order.

    Raises:
        ValueError: ``top`` is not in [1, number of candidates].
    """
    top = check_integer("top", top, 1)
    lives = scheduler.lives_of(generation) if generation is not None else []
    if lives:
        order = sorted(
            range(len(lives)),
            key=lambda i: (lives[i].matings == 0, -lives[i].fitness, -lives[i].matings, i),
        )
        candidates = [
            Individual(life.genome, life.fitness, life.matings > 0, life.robot, life.slot)
            for life in (lives[i] for i in order)
        ]
        what = f"completed lives of generation {generation}"
    else:
        unit = scheduler.config.fitness_time_unit
        agents = []
        for robot in range(scheduler.n_robots):
            for slot in range(scheduler.subpopulation_size):
                agent = scheduler.agent(robot, slot)
                agents.append(
                    Individual(agent.genome, agent.fitness(unit), agent.matings > 0, robot, slot)
                )
        order = sorted(
            range(len(agents)), key=lambda i: (not agents[i].mated, -agents[i].fitness, i)
        )
        candidates = [agents[i] for i in order]
        what = "the population"
    if top > len(candidates):
        raise ValueError(f"top must be in [1, {len(candidates)}] ({what}), got {top}")
    return candidates[:top]


def ranked_generation(checkpoint_generation: int) -> int | None:
    """The generation whose lives a checkpoint ``gen_NNNNN`` ranks: the last one that closed
    (N - 1, 0-based), or None for the initial checkpoint."""
    return checkpoint_generation - 1 if checkpoint_generation > 0 else None


@dataclass(frozen=True)
class TransferResult:
    """What :func:`transfer` produced.

    Attributes:
        out: the run directory.
        statistics: the pooled per-generation table.
        per_robot: the per-robot table (Fig. 7).
        individuals: the transferred individuals.
        figure: the Fig. 7-style figure's paths (empty if no generation completed).
    """

    out: Path
    statistics: pd.DataFrame
    per_robot: pd.DataFrame
    individuals: list[Individual]
    figure: list[Path]


def _write_json(path: Path, record: dict[str, Any]) -> None:
    write_text(path, json.dumps(record, indent=2, sort_keys=True, default=repr) + "\n")


@dataclass(frozen=True)
class TransferSpec:
    """What a transfer runs: whose individuals, how many, on which colony, for how long."""

    source: str | os.PathLike[str]
    """the source run directory (``run.json`` and ``checkpoints/``)"""
    generation: int = 40
    """the source generation whose population is transferred (its checkpoint)"""
    top: int = 5
    """how many of the fittest individuals are transferred"""
    robots: int = 3
    """robots of the new colony"""
    agents_per_robot: int = 5
    """virtual agents per robot"""
    generations: int = 10
    """generations to evolve after the transfer"""
    profile: HardwareProfile | None = None
    """the hardware-like profile (None: the plain simulation)"""
    seed: int = 0
    """the new run's seed"""
    max_steps: int | None = None
    """stop after this many control steps in all, even if the generations are not complete
    (None: no budget)"""


def transfer(spec: TransferSpec, output: RunOutput) -> TransferResult:
    """Seed a new colony with the fittest individuals of ``spec.source`` and continue
    evolution.

    Args:
        spec: the source, its generation and how many individuals, the new colony, its
            profile, seed and length.
        output: ``directory``, the new run directory (must not hold a run); its checkpoint
            cadence, the checkpoints kept (0: all) and a progress bar. A transfer writes no
            TensorBoard files.

    Raises:
        ValueError: bad arguments, ``spec.source`` is not a run directory or lacks the
            generation, the output directory already holds a run or is not given.
    """

    if output.directory is None:
        raise ValueError("a transfer needs an output directory, the new run directory")
    if output.tensorboard is not None:
        raise ValueError("a transfer writes no TensorBoard files; leave tensorboard unset")
    generation, robots, agents_per_robot = spec.generation, spec.robots, spec.agents_per_robot
    profile = spec.profile
    top = check_integer("top", spec.top, 1)
    generations = check_integer("generations", spec.generations, 1)
    seed = check_integer("seed", spec.seed, 0)
    src, dst = Path(spec.source), Path(output.directory)
    record = read_run_record(src)
    checkpoint = checkpoint_of_generation(src, generation)
    if (dst / RUN_FILE).exists() or list_checkpoints(dst / CHECKPOINT_DIR):
        raise ValueError(f"--out {dst} already holds a run; choose an empty directory")
    policies = policies_for_identity(record["policies"])
    ranked = ranked_generation(generation)
    with EvolutionRunner.from_checkpoint(checkpoint, policies) as source_runner:
        chosen = fittest_individuals(source_runner.scheduler, top, ranked)
        if ranked is not None and not source_runner.scheduler.lives_of(ranked):
            ranked = None  # no full life of that generation: the living population was ranked
        base = source_runner.config
    config = hardware_run_config(base, profile, robots=robots, agents_per_robot=agents_per_robot)
    genomes = [
        chosen[s % len(chosen)].genome for _ in range(robots) for s in range(agents_per_robot)
    ]
    dst.mkdir(parents=True, exist_ok=True)
    with EvolutionRunner(config, seed, policies, initial_genomes=genomes) as runner:
        sample = runner.actuator_sample
        meta = {
            "source": str(src.resolve()),
            "source_checkpoint": checkpoint.name,
            "source_generation": generation,
            "ranked": (
                f"lives completed in generation {ranked} (0-based)"
                if ranked is not None
                else "the population living at the checkpoint"
            ),
            "individuals": [
                {
                    "fitness": i.fitness,
                    "mated": i.mated,
                    "robot": i.robot,
                    "slot": i.slot,
                    "genome": i.genome.weights.tolist(),
                }
                for i in chosen
            ],  # fmt: skip
            "robots": robots,
            "agents_per_robot": agents_per_robot,
            "profile": dataclasses.asdict(profile) if profile is not None else None,
            "actuator_sample": (
                {k: np.asarray(v).tolist() for k, v in dataclasses.asdict(sample).items()}
                if sample is not None
                else None
            ),
            "seed": seed,
        }
        _write_json(dst / TRANSFER_FILE, meta)

        def write_results(r: EvolutionRunner) -> None:
            write_tables(dst, r.statistics(), robot_table(r), extra=extra_tables(r))

        _write_json(dst / RUN_FILE, _run_record(runner, generations))
        table = runner.run(
            generations,
            checkpoint_dir=dst / CHECKPOINT_DIR,
            checkpoint_every=output.checkpoint_every,
            keep_checkpoints=output.keep_checkpoints,
            max_steps=spec.max_steps,
            progress=output.progress,
            on_generation=write_results,
        )
        write_results(runner)
        with atomic_output(dst / EVENTS_FILE) as temp:
            runner.events.write_csv(temp)
        _write_json(dst / RUN_FILE, _run_record(runner, generations))
        per_robot = robot_table(runner)
    figure: list[Path] = []
    if len(per_robot):

        label = "hardware-like profile" if profile is not None else "simulation"
        figure = plot_per_robot(
            per_robot,
            dst / FIGURE_BASE,
            title=f"After transfer ({label}): batteries per robot, unmated scored 0",
        )
    return TransferResult(dst, table, per_robot, chosen, figure)


def _run_record(runner: EvolutionRunner, generations: int) -> dict[str, Any]:
    return {**run_record(runner, generations), "transfer": True}


__all__ = [
    "ROBOT_STATISTICS_FILE",
    "TRANSFER_FILE",
    "Individual",
    "TransferResult",
    "TransferSpec",
    "checkpoint_of_generation",
    "fittest_individuals",
    "hardware_run_config",
    "transfer",
]
