"""Virtual agents: the individuals that time-share a physical robot (paper §2, §3.3).

Each robot carries a subpopulation of virtual agents and runs one of them at a time. An agent is
its genome plus the life record that selection needs: energy (its own virtual battery, saved while
another agent uses the robot), age, batteries captured, matings, and the (genome, fitness) of every
partner met at a mating.

Genomes are shared between objects (an agent, the partner records that hold its genome, a spare
list, a life record), so checkpoint states refer to them by index into one (G, L) array built
by a :class:`GenomePool` (docs/design.md §10): each genome is stored once, and a restore shares
them again exactly as the run did.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from evolution.config import GENOME_LENGTH
from evolution.genome import Genome, GenomeLayout


def fitness(batteries: int | float, age: int | float, time_unit: float = 100.0) -> float:
    """The paper's fitness: batteries captured / (time lived / 100) (§3.3).

    Evaluated at a mating occasion with the batteries and age so far, and at the end of life
    with the final record. An agent that has not lived a step yet has fitness 0 (it cannot have
    captured a battery either).
    """
    if age <= 0:
        return 0.0
    return float(batteries) / (float(age) / time_unit)


class Origin(enum.IntEnum):
    """How an agent's genome came to be; the statistics count new agents by origin."""

    INITIAL = 0  #: the random initial population
    OFFSPRING = 1  #: offspring made by the previous agent of the slot at the end of its life
    SPARE = 2  #: drawn from the robot's spare list (the unused child of an earlier offspring)
    RANDOM = 3  #: a fresh random genome, made because the spare list was empty
    SELECTED = 4  #: made by the centralised GA's tournament selection
    RECEIVED = 5  #: mEDEA: a genome the robot received by broadcast, mutated


class GenomePool:
    """Numbers the genomes of a state by identity, for states that refer to them by index."""

    def __init__(self) -> None:
        self._index: dict[int, int] = {}
        self._genomes: list[Genome] = []

    def index(self, genome: Genome) -> int:
        """The genome's index (a new one the first time this object is seen)."""
        found = self._index.get(id(genome))
        if found is None:
            found = self._index[id(genome)] = len(self._genomes)
            self._genomes.append(genome)  # keeps the object, and so its id, alive
        return found

    def array(self, length: int = GENOME_LENGTH) -> np.ndarray:
        """(G, L) the genes of every genome seen, by index (L their length, ``length`` if
        there are none: 39 for the paper's controller, 49 in learning mode)."""
        if not self._genomes:
            return np.zeros((0, length))
        return np.stack([genome.weights for genome in self._genomes])


def genomes_from_array(weights: np.ndarray, layout: GenomeLayout | None = None) -> list[Genome]:
    """The genomes of a :meth:`GenomePool.array` (one object per row), of ``layout`` (default:
    the paper's controller's, with the learning genes if there are 49 columns).

    Raises:
        ValueError: not a (G, L) array of finite numbers of the layout's length.
    """
    if not isinstance(weights, np.ndarray) or weights.ndim != 2:
        raise ValueError("genomes must be a (G, L) array")
    return [Genome(row, layout) for row in weights]


def genome_at(genomes: Sequence[Genome], index: object) -> Genome:
    """``genomes[index]`` for an index read from a state (no negative indexing).

    Raises:
        ValueError: ``index`` is not an integer in range.
    """
    if type(index) is not int or not 0 <= index < len(genomes):
        raise ValueError(f"genome index {index!r} is out of range (pool of {len(genomes)})")
    return genomes[index]


@dataclass(frozen=True, slots=True)
class MatingRecord:
    """What an agent keeps from one mating: the partner's genome and its fitness at that time."""

    genome: Genome
    fitness: float

    def state(self, pool: GenomePool) -> dict[str, Any]:
        """Plain state; the genome as its index in ``pool``."""
        return {"genome": pool.index(self.genome), "fitness": self.fitness}

    @classmethod
    def from_state(cls, state: dict[str, Any], genomes: Sequence[Genome]) -> MatingRecord:
        """Rebuild a record from :meth:`state` and the pool's genomes."""
        return cls(genome_at(genomes, state["genome"]), float(state["fitness"]))


@dataclass(slots=True)
class VirtualAgent:
    """One individual of the population.

    Attributes:
        genome: the controller weights.
        energy: current virtual battery level; the world applies energy while the agent is
            active, the agent keeps it while another agent uses the robot.
        age: control steps lived (only steps while active count).
        batteries: battery packs captured (dockings).
        matings: successful matings.
        partners: one record per mating, in order.
        origin: how the genome came to be.
        generation: the generation of the slot the agent was born into.
        dead: the agent's energy reached 0.
    """

    genome: Genome
    energy: float
    generation: int = 0
    origin: Origin = Origin.INITIAL
    age: int = 0
    batteries: int = 0
    matings: int = 0
    partners: list[MatingRecord] = field(default_factory=list)
    dead: bool = False

    def fitness(self, time_unit: float = 100.0) -> float:
        """batteries / (age / 100) for this agent's record so far."""
        return fitness(self.batteries, self.age, time_unit)

    def fittest_partner(self) -> MatingRecord | None:
        """The partner record with the highest fitness; the earliest wins a tie; None if none."""
        best: MatingRecord | None = None
        for record in self.partners:
            if best is None or record.fitness > best.fitness:
                best = record
        return best

    def state(self, pool: GenomePool) -> dict[str, Any]:
        """Plain state; genomes as their indices in ``pool``."""
        return {
            "genome": pool.index(self.genome),
            "energy": self.energy,
            "generation": self.generation,
            "origin": int(self.origin),
            "age": self.age,
            "batteries": self.batteries,
            "matings": self.matings,
            "partners": [record.state(pool) for record in self.partners],
            "dead": self.dead,
        }

    @classmethod
    def from_state(cls, state: dict[str, Any], genomes: Sequence[Genome]) -> VirtualAgent:
        """Rebuild an agent from :meth:`state` and the pool's genomes."""
        return cls(
            genome=genome_at(genomes, state["genome"]),
            energy=float(state["energy"]),
            generation=int(state["generation"]),
            origin=Origin(int(state["origin"])),
            age=int(state["age"]),
            batteries=int(state["batteries"]),
            matings=int(state["matings"]),
            partners=[MatingRecord.from_state(p, genomes) for p in state["partners"]],
            dead=bool(state["dead"]),
        )
