"""The greedy policy of learned action values: what a robot runs once learning is over.

Separate from the learner on purpose: the evolution runner executes a behaviour millions of times
and must not carry traces, an exploration rate or a random generator, and must never change the
saved values. A :class:`GreedyPolicy` is stateless (a pure function of its inputs), so one object
serves every robot and every virtual agent at once, batched over robots.

Ties between equal action values go to the lowest action index (``argmax``), the same rule as
``torch.argmax`` in the exported module, so both always pick the same action.
"""

from __future__ import annotations

import os

import numpy as np

from behaviours.action_values import ActionValues
from behaviours.tile_coding import TileCoderConfig


class GreedyPolicy:
    """Greedy (argmax-Q) policy over tile-coded linear action values.

    Args:
        values: the learned action values.
    """

    def __init__(self, values: ActionValues) -> None:
        self.values = values
        self.coder = values.make_coder()
        # (table_size, n_actions): one row gather per active tile, summed over tilings in tiling
        # order, which is also the order torch's EmbeddingBag sums in.
        self.table = np.ascontiguousarray(values.weights.T)

    @classmethod
    def from_file(
        cls,
        path: str | os.PathLike[str],
        *,
        expect_coder: TileCoderConfig | None = None,
        expect_n_actions: int | None = None,
    ) -> GreedyPolicy:
        """Load verified values from ``path`` (see :meth:`ActionValues.load` for the errors)."""
        return cls(
            ActionValues.load(path, expect_coder=expect_coder, expect_n_actions=expect_n_actions)
        )

    @property
    def n_actions(self) -> int:
        """Number of discrete actions."""
        return self.values.n_actions

    @property
    def action_names(self) -> tuple[str, ...]:
        """Name of each action index."""
        return self.values.action_names

    def q_values(self, states: np.ndarray) -> np.ndarray:
        """Action values of a batch of states.

        Args:
            states: (batch, n_dims) or (n_dims,) normalised inputs in [0, 1].

        Returns:
            (batch, n_actions) float64, or (n_actions,) for a single state.
        """
        idx = self.coder.indices(states)
        # Reduction over a non-innermost axis: numpy adds the tilings strictly in order.
        q: np.ndarray = self.table[idx].sum(axis=-2)
        return q

    def act(self, states: np.ndarray) -> np.ndarray:
        """Greedy actions of a batch of states.

        Args:
            states: (batch, n_dims) or (n_dims,) normalised inputs in [0, 1].

        Returns:
            int64 array (batch,) of action indices, or a 0-d array for a single state.
        """
        actions: np.ndarray = np.argmax(self.q_values(states), axis=-1)
        return actions
