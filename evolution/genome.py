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

In learning mode (docs/design.md §11) the genome grows by the learning genes, after the
controller weights so that the controller's layout and every crossover cut within it stay the
same:

- ``[39:43]`` four meta-genes in [0, 1] (:data:`META`): learning rate, discount, trace decay and
  exploration ε, each mapped linearly onto its range in
  :class:`~evolution.config.LearningConfig`;
- ``[43:49]`` six shaping weights (:data:`SHAPING`): the potential of each behaviour's two
  inputs (Mate, Forage, Search in turn), real numbers like the controller weights.

A :class:`Genome` is immutable: its array is read-only, and every operator returns new genomes.
That lets agents, spare lists and mating records share one genome object without copies and
without the risk that mutating an offspring silently changes a partner's stored genome.
"""

from __future__ import annotations

import numpy as np

from evolution.config import (
    GENOME_LENGTH,
    LEARNING_GENOME_LENGTH,
    N_META_GENES,
    GeneticConfig,
)

#: Slice of the recharge weights (energy, steps recharged, bias).
RECHARGE = slice(0, 3)
#: Slice of the selection weights, output-major (Mate, Forage, Search) x 12 inputs.
SELECTION = slice(3, GENOME_LENGTH)
#: Slice of the controller's weights (the whole genome outside learning mode).
CONTROLLER = slice(0, GENOME_LENGTH)
#: Learning mode: the meta-genes (learning rate, discount, trace decay, ε), each in [0, 1].
META = slice(GENOME_LENGTH, GENOME_LENGTH + N_META_GENES)
#: Learning mode: the shaping weights, (Mate, Forage, Search) x their two inputs.
SHAPING = slice(GENOME_LENGTH + N_META_GENES, LEARNING_GENOME_LENGTH)
#: The genome lengths there are.
LENGTHS = (GENOME_LENGTH, LEARNING_GENOME_LENGTH)


def reflect_unit(x: np.ndarray) -> np.ndarray:
    """Fold values in [-1, 2] back into [0, 1] by reflection at 0 and 1 (a mutated meta-gene).

    Example: -0.05 -> 0.05, 1.08 -> 0.92, 0.4 -> 0.4.
    """
    folded: np.ndarray = np.where(x < 0.0, -x, np.where(x > 1.0, 2.0 - x, x))
    return folded


class Genome:
    """An immutable vector of the controller's 39 weights (49 genes in learning mode).

    Args:
        weights: 39 (or, with the learning genes, 49) finite real numbers (copied, then
            frozen); learning meta-genes must lie in [0, 1].

    Raises:
        ValueError: another shape, a weight that is not finite, or a meta-gene outside [0, 1].
    """

    __slots__ = ("_weights",)

    def __init__(self, weights: np.ndarray) -> None:
        array = np.array(weights, dtype=np.float64, copy=True)
        if array.ndim != 1 or array.shape[0] not in LENGTHS:
            raise ValueError(
                f"weights must have shape ({GENOME_LENGTH},) or ({LEARNING_GENOME_LENGTH},), "
                f"got {array.shape}"
            )
        if not np.all(np.isfinite(array)):
            raise ValueError("weights must all be finite")
        if array.shape[0] == LEARNING_GENOME_LENGTH:
            meta = array[META]
            if not (meta.min() >= 0.0 and meta.max() <= 1.0):
                raise ValueError(f"learning meta-genes must lie in [0, 1], got {meta.tolist()}")
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
        """The read-only gene vector: (39,), or (49,) with the learning genes."""
        return self._weights

    @property
    def controller(self) -> np.ndarray:
        """The (39,) read-only controller weights (the whole genome outside learning mode)."""
        return self._weights[CONTROLLER]

    @property
    def learns(self) -> bool:
        """The genome carries the learning genes."""
        return bool(self._weights.shape[0] == LEARNING_GENOME_LENGTH)

    @property
    def meta(self) -> np.ndarray:
        """(4,) the learning meta-genes in [0, 1] (learning rate, discount, trace decay, ε).

        Raises:
            ValueError: the genome has no learning genes.
        """
        if not self.learns:
            raise ValueError("this genome has no learning genes")
        return self._weights[META]

    @property
    def shaping(self) -> np.ndarray:
        """(3, 2) the shaping weights of Mate, Forage and Search (two inputs each).

        Raises:
            ValueError: the genome has no learning genes.
        """
        if not self.learns:
            raise ValueError("this genome has no learning genes")
        return self._weights[SHAPING].reshape(3, 2)

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        genetics: GeneticConfig | None = None,
        learning: bool = False,
    ) -> Genome:
        """A genome with independent U[low, high] weights (paper: U[-1, 1]).

        With ``learning`` the learning genes follow, drawn after the controller's weights (so
        the controller's draw is the same either way): the meta-genes U[0, 1], the shaping
        weights U[low, high] like the controller's.
        """
        g = genetics or GeneticConfig()
        weights = rng.uniform(g.initial_weight_low, g.initial_weight_high, GENOME_LENGTH)
        if not learning:
            return cls._trusted(weights)
        meta = rng.random(N_META_GENES)
        shaping = rng.uniform(
            g.initial_weight_low, g.initial_weight_high, LEARNING_GENOME_LENGTH - META.stop
        )
        return cls._trusted(np.concatenate((weights, meta, shaping)))

    def mutate(self, rng: np.random.Generator, genetics: GeneticConfig | None = None) -> Genome:
        """A copy in which each gene, independently with p = 0.1, is mutated.

        A weight (controller or shaping) gets += U[-0.5, 0.5]. A learning meta-gene gets +=
        U[-w, w] (``meta_mutation_width``) and is reflected back into [0, 1]
        (:func:`reflect_unit`).

        The mask and every increment are always drawn (the mask and the weights' increments
        over the whole genome, then the meta-genes' own increments), so the number of random
        numbers consumed does not depend on the outcome: a run's random stream stays aligned
        no matter which genes happened to mutate.
        """
        g = genetics or GeneticConfig()
        n = self._weights.shape[0]
        mask = np.less(rng.random(n), g.mutation_probability)
        delta = rng.uniform(g.mutation_low, g.mutation_high, n)
        mutated = np.where(mask, self._weights + delta, self._weights)
        if n == LEARNING_GENOME_LENGTH:
            width = g.meta_mutation_width
            step = rng.uniform(-width, width, N_META_GENES)
            meta = self._weights[META]
            mutated[META] = np.where(mask[META], reflect_unit(meta + step), meta)
        return Genome._trusted(mutated)

    def crossover(
        self, other: Genome, rng: np.random.Generator, point: int | None = None
    ) -> tuple[Genome, Genome]:
        """Standard one-point crossover; returns both children.

        The cut point ``k`` is drawn uniformly from 1..L-1 (L = 39, or 49 with the learning
        genes), so each child takes at least one gene from each parent:
        ``(self[:k] + other[k:], other[:k] + self[k:])``.

        Args:
            other: the second parent (of the same length).
            rng: source of the cut point (one ``integers`` draw), unused if ``point`` is given.
            point: force the cut point (for hand-computed cases); must be in [1, L-1].

        Raises:
            ValueError: ``point`` outside [1, L-1], or parents of different lengths.
        """
        n = self._weights.shape[0]
        if other._weights.shape[0] != n:
            raise ValueError(
                f"parents of different lengths ({n} and {other._weights.shape[0]} genes)"
            )
        if point is None:
            point = int(rng.integers(1, n))
        elif not isinstance(point, int | np.integer) or not 1 <= point <= n - 1:
            raise ValueError(f"point must be an integer in [1, {n - 1}], got {point!r}")
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
        self._weights = Genome(state["weights"])._weights
