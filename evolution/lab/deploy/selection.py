"""Which agents a deployment bundle carries: the fittest of a run that have mated.

The paper's fitness (batteries / (time / 100)) ranks an agent that never mated like any other,
yet such an agent has not completed the survival task (docs/design.md §5: "at least one
mating") and leaves no offspring. A bundle is meant to run on robots that must survive *and*
mate, so by default it holds only agents that mated; ``include_unmated`` restores the plain
fitness ranking.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cyber_rodent.validation import check_integer
from evolution.lab.transfer import fittest_individuals

if TYPE_CHECKING:
    from evolution.lab.transfer import Individual
    from evolution.scheduler import TimeSharingScheduler


@dataclass(frozen=True)
class Selection:
    """The agents chosen for a bundle and how they were chosen.

    Attributes:
        agents: the chosen individuals, fittest first (empty if none qualified).
        requested: the number asked for (``--top``).
        ranked: candidates ranked.
        mated: candidates that had mated at least once.
        include_unmated: unmated candidates were eligible.
        source: what was ranked (a generation's completed lives, or the living population).
    """

    agents: tuple[Individual, ...]
    requested: int
    ranked: int
    mated: int
    include_unmated: bool
    source: str

    @property
    def short(self) -> bool:
        """Fewer agents qualified than were requested."""
        return len(self.agents) < self.requested

    def note(self) -> str:
        """One sentence saying what was bundled, and why fewer than requested if so."""
        rule = "fittest" if self.include_unmated else "fittest that mated"
        text = (
            f"{len(self.agents)} {rule} of {self.ranked} ranked agents ({self.source}; "
            f"{self.mated} mated)"
        )
        if self.short:
            text += f"; {self.requested} were requested, only {len(self.agents)} qualified"
        return text


def ranked_candidates(
    scheduler: TimeSharingScheduler, generation: int | None
) -> tuple[list[Individual], str]:
    """Every candidate of a checkpoint, fittest first, and what was ranked.

    The ranking is :func:`evolution.lab.transfer.fittest_individuals`' (the lives of the last closed
    generation, or the living population without one, docs/design.md §9.25).
    """

    lives = scheduler.lives_of(generation) if generation is not None else []
    if lives:
        source = f"completed lives of generation {generation}"
        count = len(lives)
    else:
        source = "the population"
        count = scheduler.n_robots * scheduler.subpopulation_size
    return fittest_individuals(scheduler, count, generation if lives else None), source


def choose_agents(
    candidates: Sequence[Individual],
    top: int,
    *,
    include_unmated: bool = False,
    source: str = "candidates",
) -> Selection:
    """The ``top`` first of ``candidates`` (fittest first) that mated, or of all of them.

    Fewer than ``top`` (possibly none) are chosen when fewer qualify; the caller reports it.

    Raises:
        ValueError: ``top`` is not an integer in [1, number of candidates].
    """
    candidates = list(candidates)
    top = check_integer("top", top, 1, max(len(candidates), 1))
    mated = [c for c in candidates if c.mated]
    pool = candidates if include_unmated else mated
    return Selection(
        agents=tuple(pool[:top]),
        requested=top,
        ranked=len(candidates),
        mated=len(mated),
        include_unmated=include_unmated,
        source=source,
    )


__all__ = ["Selection", "choose_agents", "ranked_candidates"]
