"""The genome: the real-valued genes of a controller (paper §3.5), then learning mode's.

A genome's :class:`GenomeLayout` says where its parts lie: the controller's genes first (their
number and blocks follow from the run's controller, :mod:`evolution.controllers`), then, in
learning mode, the learning genes. The paper's controller has 39 (fixed, because one-point
crossover cuts the vector at a position and the position decides which traits travel
together):

- ``[0:3]`` the recharge part: weights of energy, steps recharged and bias (:data:`RECHARGE`).
- ``[3:39]`` the selection part, output-major: 12 weights into Mate, then 12 into Forage, then
  12 into Search (:data:`SELECTION`); within each output the inputs follow the input table's
  order (:data:`evolution.input_kernels.INPUTS`).

Output-major order keeps each output neuron's incoming weights contiguous, so a crossover mostly
exchanges whole "decision rules" (how strongly the situation calls for Mate, Forage or Search)
rather than interleaving them; it also matches the paper's figure, which draws the recharge part
and then the selection part. Another controller (``mlp``) has its own blocks; initial draw,
mutation and crossover treat every controller gene alike (U[low, high] times the block's
``initial_scale``, += U[-0.5, 0.5], a cut anywhere), so they follow from the layout alone.

In learning mode (docs/design.md §11) the genome grows by the learning genes, after the
controller's genes so that the controller's layout and every crossover cut within it stay the
same (for the paper's controller):

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

from dataclasses import dataclass

import numpy as np

from evolution.config import (
    GENOME_LENGTH,
    LEARNING_GENOME_LENGTH,
    N_LEARNING_GENES,
    N_META_GENES,
    EvolutionConfig,
    GeneticConfig,
)
from evolution.controllers import resolve


@dataclass(frozen=True)
class GenomeLayout:
    """Where a genome's parts lie: the controller's genes, then learning mode's.

    Attributes:
        controller_genes: the controller's genes (39 for the paper's).
        learning: the learning genes follow (four meta-genes, six shaping weights).
        initial_scale: per controller gene, the factor of the initial range; None: 1 for all
            (every built-in controller).
    """

    controller_genes: int = GENOME_LENGTH
    learning: bool = False
    initial_scale: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.controller_genes < 1:
            raise ValueError(f"controller_genes must be >= 1, got {self.controller_genes}")
        if self.initial_scale is not None and len(self.initial_scale) != self.controller_genes:
            raise ValueError("initial_scale must have one factor per controller gene")

    @classmethod
    def of(cls, config: EvolutionConfig) -> GenomeLayout:
        """The layout of ``config``'s genomes (its controller, learning mode)."""
        controller = resolve(config)
        return cls(controller.length, config.learning.enabled, controller.initial_scale())

    @property
    def length(self) -> int:
        """Genes in all."""
        return self.controller_genes + (N_LEARNING_GENES if self.learning else 0)

    @property
    def controller(self) -> slice:
        """The controller's genes."""
        return slice(0, self.controller_genes)

    @property
    def meta(self) -> slice:
        """Learning mode's meta-genes (learning rate, discount, trace decay, ε)."""
        return slice(self.controller_genes, self.controller_genes + N_META_GENES)

    @property
    def shaping(self) -> slice:
        """Learning mode's shaping weights."""
        return slice(self.controller_genes + N_META_GENES, self.length)


#: The paper's controller, without and with the learning genes.
PAPER_LAYOUT = GenomeLayout()
PAPER_LEARNING_LAYOUT = GenomeLayout(learning=True)
#: Slice of the recharge weights (energy, steps recharged, bias).
RECHARGE = slice(0, 3)
#: Slice of the paper's selection weights, output-major (Mate, Forage, Search) x 12 inputs.
SELECTION = slice(3, GENOME_LENGTH)
#: Slice of the paper's controller weights (the whole genome outside learning mode).
CONTROLLER = PAPER_LAYOUT.controller
#: Learning mode (paper's controller): the meta-genes, each in [0, 1].
META = PAPER_LEARNING_LAYOUT.meta
#: Learning mode (paper's controller): the shaping weights, (Mate, Forage, Search) x 2 inputs.
SHAPING = PAPER_LEARNING_LAYOUT.shaping
#: The lengths a genome without an explicit layout may have (the paper's controller's).
LENGTHS = (GENOME_LENGTH, LEARNING_GENOME_LENGTH)
assert LEARNING_GENOME_LENGTH == PAPER_LEARNING_LAYOUT.length


def reflect_unit(x: np.ndarray) -> np.ndarray:
    """Fold values in [-1, 2] back into [0, 1] by reflection at 0 and 1 (a mutated meta-gene).

    Example: -0.05 -> 0.05, 1.08 -> 0.92, 0.4 -> 0.4.
    """
    folded: np.ndarray = np.where(x < 0.0, -x, np.where(x > 1.0, 2.0 - x, x))
    return folded


class Genome:
    """An immutable vector of a controller's genes, then learning mode's (see the module).

    Args:
        weights: finite real numbers (copied, then frozen): as many as ``layout`` has; learning
            meta-genes must lie in [0, 1].
        layout: where the parts lie; default: the paper's controller's, with the learning genes
            if there are 49 weights (39 without).

    Raises:
        ValueError: another shape, a weight that is not finite, or a meta-gene outside [0, 1].
    """

    __slots__ = ("_layout", "_weights")

    def __init__(self, weights: np.ndarray, layout: GenomeLayout | None = None) -> None:
        array = np.array(weights, dtype=np.float64, copy=True)
        if layout is None:
            if array.ndim != 1 or array.shape[0] not in LENGTHS:
                raise ValueError(
                    f"weights must have shape ({GENOME_LENGTH},) or ({LEARNING_GENOME_LENGTH},), "
                    f"got {array.shape} (another controller's genome needs its layout)"
                )
            learning = array.shape[0] == LEARNING_GENOME_LENGTH
            layout = PAPER_LEARNING_LAYOUT if learning else PAPER_LAYOUT
        elif array.ndim != 1 or array.shape[0] != layout.length:
            raise ValueError(f"weights must have shape ({layout.length},), got {array.shape}")
        if not np.all(np.isfinite(array)):
            raise ValueError("weights must all be finite")
        if layout.learning:
            meta = array[layout.meta]
            if not (meta.min() >= 0.0 and meta.max() <= 1.0):
                raise ValueError(f"learning meta-genes must lie in [0, 1], got {meta.tolist()}")
        array.flags.writeable = False
        self._weights = array
        self._layout = layout

    @classmethod
    def _trusted(cls, array: np.ndarray, layout: GenomeLayout) -> Genome:
        """Wrap an array the caller has just created and will not touch again (no copy)."""
        genome = cls.__new__(cls)
        array.flags.writeable = False
        genome._weights = array
        genome._layout = layout
        return genome

    @property
    def weights(self) -> np.ndarray:
        """The read-only gene vector (39 genes for the paper's controller, 49 with the learning
        genes)."""
        return self._weights

    @property
    def layout(self) -> GenomeLayout:
        """Where its parts lie."""
        return self._layout

    @property
    def controller(self) -> np.ndarray:
        """The read-only controller genes (the whole genome outside learning mode)."""
        return self._weights[self._layout.controller]

    @property
    def learns(self) -> bool:
        """The genome carries the learning genes."""
        return self._layout.learning

    @property
    def meta(self) -> np.ndarray:
        """(4,) the learning meta-genes in [0, 1] (learning rate, discount, trace decay, ε).

        Raises:
            ValueError: the genome has no learning genes.
        """
        if not self.learns:
            raise ValueError("this genome has no learning genes")
        return self._weights[self._layout.meta]

    @property
    def shaping(self) -> np.ndarray:
        """(3, 2) the shaping weights of Mate, Forage and Search (two inputs each).

        Raises:
            ValueError: the genome has no learning genes.
        """
        if not self.learns:
            raise ValueError("this genome has no learning genes")
        return self._weights[self._layout.shaping].reshape(3, 2)

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        genetics: GeneticConfig | None = None,
        learning: bool = False,
        *,
        layout: GenomeLayout | None = None,
    ) -> Genome:
        """A genome with independent U[low, high] weights (paper: U[-1, 1]).

        ``layout`` (default: the paper's controller, with the learning genes if ``learning``)
        gives the controller's genes and their initial scale (each U[low, high] draw times
        it). With the learning genes they follow, drawn after the controller's weights (so
        the controller's draw is the same either way): the meta-genes U[0, 1], the shaping
        weights U[low, high] like the paper's controller's.

        Raises:
            ValueError: ``learning`` with a layout that has no learning genes.
        """
        if layout is None:
            layout = PAPER_LEARNING_LAYOUT if learning else PAPER_LAYOUT
        elif learning and not layout.learning:
            raise ValueError("learning=True needs a layout with the learning genes")
        g = genetics or GeneticConfig()
        low, high = g.initial_weight_low, g.initial_weight_high
        weights = rng.uniform(low, high, layout.controller_genes)
        if layout.initial_scale is not None:
            weights *= np.asarray(layout.initial_scale)
        if not layout.learning:
            return cls._trusted(weights, layout)
        meta = rng.random(N_META_GENES)
        shaping = rng.uniform(low, high, layout.length - layout.meta.stop)
        return cls._trusted(np.concatenate((weights, meta, shaping)), layout)

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
        if self._layout.learning:
            width = g.meta_mutation_width
            step = rng.uniform(-width, width, N_META_GENES)
            meta_slice = self._layout.meta
            meta = self._weights[meta_slice]
            mutated[meta_slice] = np.where(mask[meta_slice], reflect_unit(meta + step), meta)
        return Genome._trusted(mutated, self._layout)

    def crossover(
        self, other: Genome, rng: np.random.Generator, point: int | None = None
    ) -> tuple[Genome, Genome]:
        """Standard one-point crossover; returns both children.

        The cut point ``k`` is drawn uniformly from 1..L-1 (L the genome's length: 39 for the
        paper's controller, 49 with the learning genes), so each child takes at least one gene
        from each parent: ``(self[:k] + other[k:], other[:k] + self[k:])``.

        Args:
            other: the second parent (of the same layout).
            rng: source of the cut point (one ``integers`` draw), unused if ``point`` is given.
            point: force the cut point (for hand-computed cases); must be in [1, L-1].

        Raises:
            ValueError: ``point`` outside [1, L-1], or parents of different lengths or layouts.
        """
        n = self._weights.shape[0]
        if other._weights.shape[0] != n:
            raise ValueError(
                f"parents of different lengths ({n} and {other._weights.shape[0]} genes)"
            )
        if other._layout != self._layout:
            raise ValueError("parents of different layouts (controllers or learning mode)")
        if point is None:
            point = int(rng.integers(1, n))
        elif not isinstance(point, int | np.integer) or not 1 <= point <= n - 1:
            raise ValueError(f"point must be an integer in [1, {n - 1}], got {point!r}")
        a, b = self._weights, other._weights
        first = np.concatenate((a[:point], b[point:]))
        second = np.concatenate((b[:point], a[point:]))
        return Genome._trusted(first, self._layout), Genome._trusted(second, self._layout)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Genome):
            return NotImplemented
        return self._layout == other._layout and bool(
            np.array_equal(self._weights, other._weights)
        )

    def __hash__(self) -> int:
        return hash(self._weights.tobytes())

    def __repr__(self) -> str:
        w = self._weights
        return f"Genome([{w[0]:.3f}, {w[1]:.3f}, {w[2]:.3f}, ... {w[-1]:.3f}])"

    def __getstate__(self) -> dict[str, object]:
        return {"weights": self._weights, "layout": self._layout}

    def __setstate__(self, state: dict[str, object]) -> None:
        layout = state.get("layout")
        genome = Genome(state["weights"], layout if isinstance(layout, GenomeLayout) else None)  # type: ignore[arg-type]
        self._weights, self._layout = genome._weights, genome._layout
