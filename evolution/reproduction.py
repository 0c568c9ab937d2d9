"""Selection and reproduction: the EE offspring and replacement rules, and the CE generation.

Embodied evolution (paper §2, docs/design.md §5) reproduces locally, at the end of one agent's life,
from the genomes that agent collected at its matings:

- :func:`make_offspring` — an agent that lived its full lifetime and mated at least once takes
  its fittest partner's genome P. With the crossover probability (0.6) it makes both one-point
  children of (own, P) and keeps one at random; otherwise it keeps the fitter of own genome (own
  fitness at the end of life) and P. The child not kept goes to the robot's spare list. Both are
  mutated.
- :func:`draw_replacement` — an agent that died or never mated leaves no offspring; its slot gets
  a genome drawn at random (and removed) from the spare list, or a fresh random genome only if the
  list is empty.

The centralised GA (paper §4.1) replaces the whole population at once: :func:`next_generation`
fills it with pairs of tournament winners (size 2), crossed over with the same probability and
mutated the same way.

Every function draws from the ``rng`` it is given, in a fixed order that does not depend on the
random outcomes' values beyond the branch taken, so a seed fixes the whole history.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from evolution.agent import MatingRecord, Origin
from evolution.config import GeneticConfig
from evolution.genome import Genome, GenomeLayout


@dataclass(frozen=True, slots=True)
class Offspring:
    """The result of one EE reproduction.

    Attributes:
        offspring: the mutated genome that takes over the parent's slot.
        spare: the mutated genome that was not chosen; it goes to the robot's spare list.
        crossover: True if the crossover branch was taken, False for reproduction (copying).
    """

    offspring: Genome
    spare: Genome
    crossover: bool


def make_offspring(
    own: Genome,
    own_fitness: float,
    partner: MatingRecord,
    rng: np.random.Generator,
    genetics: GeneticConfig | None = None,
) -> Offspring:
    """The EE offspring rule for one agent at the end of its full lifetime.

    Random draws, in order: one uniform for the branch; in the crossover branch the cut point
    and then one integer choosing the child; then the offspring's mutation and the spare's.

    Args:
        own: the agent's genome.
        own_fitness: the agent's fitness at the end of its life.
        partner: the fittest partner's record (genome and fitness at the mating).
        rng: the robot's random generator.
        genetics: operator settings (paper defaults if None).

    Returns:
        The offspring and the spare genome, both mutated. In the reproduction branch a tie in
        fitness keeps the agent's own genome as the offspring.
    """
    g = genetics or GeneticConfig()
    crossed = bool(rng.random() < g.crossover_probability)
    if crossed:
        first, second = own.crossover(partner.genome, rng)
        if rng.integers(2) == 0:
            chosen, unused = first, second
        else:
            chosen, unused = second, first
    elif partner.fitness > own_fitness:
        chosen, unused = partner.genome, own
    else:
        chosen, unused = own, partner.genome
    return Offspring(chosen.mutate(rng, g), unused.mutate(rng, g), crossed)


def draw_replacement(
    spare_list: list[Genome],
    rng: np.random.Generator,
    genetics: GeneticConfig | None = None,
    learning: bool = False,
    *,
    layout: GenomeLayout | None = None,
) -> tuple[Genome, Origin]:
    """A new genome for the slot of an agent that died or never mated.

    Removes a uniformly chosen genome from ``spare_list`` (in place) and returns it with
    :attr:`Origin.SPARE`; only if the list is empty makes a random genome (:attr:`Origin.RANDOM`,
    of ``layout``, default the paper's controller's with the learning genes if ``learning``).
    Spare genomes were already mutated when they were made, so they are not mutated again.
    """
    if spare_list:
        index = int(rng.integers(len(spare_list)))
        return spare_list.pop(index), Origin.SPARE
    return Genome.random(rng, genetics, learning, layout=layout), Origin.RANDOM


def tournament(fitness: np.ndarray, rng: np.random.Generator, size: int = 2) -> int:
    """Index of the winner of one tournament: ``size`` distinct individuals, the fittest wins.

    The contenders are drawn without replacement (one ``rng.choice`` call); a tie goes to the
    contender drawn first.
    """
    contenders = rng.choice(len(fitness), size=size, replace=False)
    return int(contenders[int(np.argmax(fitness[contenders]))])


def next_generation(
    genomes: Sequence[Genome],
    fitness: np.ndarray,
    rng: np.random.Generator,
    genetics: GeneticConfig | None = None,
    parents: list[int] | None = None,
) -> tuple[list[Genome], list[bool]]:
    """The centralised GA's generational replacement.

    Repeats until the new population is full: two tournament winners (parents may coincide);
    with the crossover probability both one-point children, otherwise copies of both parents;
    each mutated. With an odd population the last pair's second child is dropped.

    Args:
        genomes: the current population.
        fitness: (len(genomes),) fitness per individual (0 for agents that failed the task).
        rng: the central random generator.
        genetics: operator settings (paper defaults if None).
        parents: if given, filled with each new individual's first parent: the index in
            ``genomes`` of the first tournament winner of its pair for the pair's first child
            (a copy of it, or the crossover child that starts with its genes), of the second
            for the second child (what Lamarckian learning inherits from). Draws nothing.

    Returns:
        The new population (``len(genomes)`` genomes) and, per new individual, whether it was
        made by crossover.
    """
    g = genetics or GeneticConfig()
    fitness = np.asarray(fitness, dtype=float)
    if fitness.shape != (len(genomes),):
        raise ValueError(f"fitness must have shape ({len(genomes)},), got {fitness.shape}")
    if g.tournament_size > len(genomes):
        raise ValueError(
            f"tournament_size must be in [1, {len(genomes)}] (the population), "
            f"got {g.tournament_size}"
        )
    new: list[Genome] = []
    crossed: list[bool] = []
    if parents is not None:
        parents.clear()
    while len(new) < len(genomes):
        first = tournament(fitness, rng, g.tournament_size)
        second = tournament(fitness, rng, g.tournament_size)
        a, b = genomes[first], genomes[second]
        cross = bool(rng.random() < g.crossover_probability)
        if cross:
            a, b = a.crossover(b, rng)
        new.append(a.mutate(rng, g))
        crossed.append(cross)
        if parents is not None:
            parents.append(first)
        if len(new) < len(genomes):
            new.append(b.mutate(rng, g))
            crossed.append(cross)
            if parents is not None:
                parents.append(second)
    return new, crossed
