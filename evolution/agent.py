"""Virtual agents: the individuals that time-share a physical robot (paper §2, §3.3).

Each robot carries a subpopulation of virtual agents and runs one of them at a time. An agent is
its genome plus the life record that selection needs: energy (its own virtual battery, saved while
another agent uses the robot), age, batteries captured, matings, and the (genome, fitness) of every
partner met at a mating.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from evolution.genome import Genome


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


@dataclass(frozen=True, slots=True)
class MatingRecord:
    """What an agent keeps from one mating: the partner's genome and its fitness at that time."""

    genome: Genome
    fitness: float


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
