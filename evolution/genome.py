"""The genome: the 39 real-valued weights of the neural controller (paper §3.5).

Layout of the weight vector (fixed, because one-point crossover cuts it at a position and the
position decides which traits travel together):

- ``[0:3]`` the recharge part: weights of energy, steps recharged and bias (:data:`RECHARGE`).
- ``[3:39]`` the selection part, output-major: 12 weights into Mate, then 12 into Forage, then
  12 into Search (:data:`SELECTION`); within each output the inputs follow
  :mod:`evolution.controller`'s documented order.

Output-major order keeps each output neuron's incoming weights contiguous, so a crossover mostly
exchanges whole "decision rules" (how strongly the situation calls for Mate, Forage or Search)
rather than interleaving them; it also matches the paper's figure, which draws the recharge part
and then the selection part.

A :class:`Genome` is immutable: its array is read-only, and every operator returns new genomes.
That lets agents, spare lists and mating records share one genome object without copies and
without the risk that mutating an offspring silently changes a partner's stored genome.
"""

from __future__ import annotations

import numpy as np

from evolution.config import GENOME_LENGTH, GeneticConfig

#: Slice of the recharge weights (energy, steps recharged, bias).
RECHARGE = slice(0, 3)
#: Slice of the selection weights, output-major (Mate, Forage, Search) x 12 inputs.
SELECTION = slice(3, GENOME_LENGTH)


class Genome:
    """An immutable vector of the controller's 39 weights.

    Args:
        weights: 39 finite real numbers (copied, then frozen).

    Raises:
        ValueError: the shape is not (39,) or a weight is not finite.
    """

    __slots__ = ("_weights",)

    def __init__(self, weights: np.ndarray) -> None:
        array = np.array(weights, dtype=np.float64, copy=True)
        if array.shape != (GENOME_LENGTH,):
            raise ValueError(f"weights must have shape ({GENOME_LENGTH},), got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ValueError("weights must all be finite")
        array.flags.writeable = False
        self._weights = array

    @classmethod
    def _trusted(cls, array: np.ndarray) -> Genome:
        """Wrap an array the caller has just created and will not touch again (no copy)."""
        genome = cls.__new__(cls)
        array.flags.writeable = False
        genome._weights = array
        return genome

    @property
    def weights(self) -> np.ndarray:
        """The (39,) read-only weight vector."""
        return self._weights

    @classmethod
    def random(cls, rng: np.random.Generator, genetics: GeneticConfig | None = None) -> Genome:
        """A genome with independent U[low, high] weights (paper: U[-1, 1])."""
        g = genetics or GeneticConfig()
        return cls._trusted(rng.uniform(g.initial_weight_low, g.initial_weight_high, GENOME_LENGTH))

    def mutate(self, rng: np.random.Generator, genetics: GeneticConfig | None = None) -> Genome:
        """A copy in which each weight, independently with p = 0.1, gets += U[-0.5, 0.5].

        Both the mask and the 39 increments are always drawn, so the number of random numbers
        consumed does not depend on the outcome: a run's random stream stays aligned no matter
        which weights happened to mutate.
        """
        g = genetics or GeneticConfig()
        mask = rng.random(GENOME_LENGTH) < g.mutation_probability
        delta = rng.uniform(g.mutation_low, g.mutation_high, GENOME_LENGTH)
        return Genome._trusted(np.where(mask, self._weights + delta, self._weights))

    def crossover(
        self, other: Genome, rng: np.random.Generator, point: int | None = None
    ) -> tuple[Genome, Genome]:
        """Standard one-point crossover; returns both children.

        The cut point ``k`` is drawn uniformly from 1..38, so each child takes at least one
        weight from each parent: ``(self[:k] + other[k:], other[:k] + self[k:])``.

        Args:
            other: the second parent.
            rng: source of the cut point (one ``integers`` draw), unused if ``point`` is given.
            point: force the cut point (for hand-computed cases); must be in [1, 38].

        Raises:
            ValueError: ``point`` outside [1, 38].
        """
        if point is None:
            point = int(rng.integers(1, GENOME_LENGTH))
        elif not isinstance(point, int | np.integer) or not 1 <= point <= GENOME_LENGTH - 1:
            raise ValueError(f"point must be an integer in [1, {GENOME_LENGTH - 1}], got {point!r}")
        a, b = self._weights, other._weights
        first = np.concatenate((a[:point], b[point:]))
        second = np.concatenate((b[:point], a[point:]))
        return Genome._trusted(first), Genome._trusted(second)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Genome):
            return NotImplemented
        return bool(np.array_equal(self._weights, other._weights))

    def __hash__(self) -> int:
        return hash(self._weights.tobytes())

    def __repr__(self) -> str:
        w = self._weights
        return f"Genome([{w[0]:.3f}, {w[1]:.3f}, {w[2]:.3f}, ... {w[-1]:.3f}])"

    def __getstate__(self) -> dict[str, np.ndarray]:
        return {"weights": self._weights}

    def __setstate__(self, state: dict[str, np.ndarray]) -> None:
        array = np.array(state["weights"], dtype=np.float64, copy=True)
        array.flags.writeable = False
        self._weights = array
