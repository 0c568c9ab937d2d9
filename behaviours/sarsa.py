"""Sarsa(λ) with replacing traces and ε-greedy exploration over tile-coded linear Q.

This is the learner of the paper's basic behaviours (§3.4: "Sarsa(λ) with tile coding function
approximation and replacing traces", after Sutton & Barto 1998). It follows "Linear,
gradient-descent Sarsa(λ) with binary features and ε-greedy policy" (Sutton & Barto 1998,
Fig. 8.8) with these specifics:

* **Linear Q over tiles.** ``Q(s, a) = Σ_{i ∈ F(s)} w[a, i]``, where ``F(s)`` are the
  ``n_tilings`` hashed tile indices of ``s``; weights have shape (n_actions, table_size).
* **Step size.** ``alpha`` is the step for the whole feature vector; each active weight moves by
  ``alpha / n_tilings`` times its trace, so a single update moves Q(s, a) by about ``alpha · δ``
  regardless of the number of tilings (the usual tile-coding convention).
* **Replacing traces.** A visited feature's trace is *set* to 1 (not incremented), and, as
  Sutton & Barto (1998, §7.8) recommend for control, the traces of the *other* actions at the
  visited features are set to 0 (``clear_other_action_traces``).
* **Sparse traces.** Only features with a trace ≥ ``trace_cutoff`` are kept, in a compact index
  list, so one update costs O(active traces), about ``n_tilings · log(cutoff)/log(γλ)``, never
  O(table). Traces below the cutoff are set to exactly zero (with the defaults a trace is dropped
  after ~42 steps, when its weight in the update is < 0.1 % of a fresh one).
* **Exploration.** ε-greedy with an explicit :class:`numpy.random.Generator`; ties between
  greedy actions are broken uniformly at random with the same generator (so an untrained,
  all-zero table still explores), which keeps runs bit-identical for a given seed.
* **Episodes.** :meth:`SarsaLambda.begin_episode` starts one (clears the traces), :meth:`step`
  feeds each transition. ``terminal=True`` means a true terminal state (target 0 after it).
  For a time-limit cut-off, do *not* pass ``terminal``: the last step still bootstraps from the
  next state's value, and the next :meth:`begin_episode` clears the traces.

Two learners may share one weight array (pass ``weights=``), e.g. two robots learning Mate with a
common Q table: each keeps its own traces and exploration, and both update the shared weights.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, overload

import numpy as np

from behaviours.action_values import ActionValues
from behaviours.tile_coding import TileCoder
from cyber_rodent.validation import boolean, number, validate_fields


@dataclass(frozen=True)
class SarsaConfig:
    """Learning parameters of Sarsa(λ). The paper gives none; these defaults are ours.

    Attributes:
        alpha: step size for the whole feature vector, in (0, 1]; each of the ``n_tilings``
            active weights moves by ``alpha / n_tilings``. 0.1 is a safe default for tile coding
            with rewards of order 1.
        gamma: discount factor in [0, 1]. 0.95 values a reward 20 steps (2 s) ahead at ~36 %,
            which suits behaviours that reach their goal within ~100 control steps.
        lam: trace decay λ in [0, 1]. 0.9 is the value Sutton & Barto found good on tasks like
            mountain car.
        epsilon: exploration rate of the ε-greedy policy in [0, 1].
        trace_cutoff: traces below this are dropped (set to 0), in (0, 1).
        clear_other_action_traces: on a visit, zero the other actions' traces at the active
            features (Sutton & Barto 1998, §7.8).
    """

    alpha: float = number(0.1, 0.0, 1.0, low_open=True)
    gamma: float = number(0.95, 0.0, 1.0)
    lam: float = number(0.9, 0.0, 1.0)
    epsilon: float = number(0.1, 0.0, 1.0)
    trace_cutoff: float = number(1e-3, 0.0, 1.0, low_open=True, high_open=True)
    clear_other_action_traces: bool = boolean(True)

    def __post_init__(self) -> None:
        validate_fields(self)


def epsilon_greedy(q: np.ndarray, epsilon: float, rng: np.random.Generator) -> int:
    """Pick an action ε-greedily from one state's action values.

    With probability ``epsilon`` a uniformly random action (any of them, the greedy one
    included), otherwise a greedy one, ties broken uniformly at random. So the greedy action
    (if unique) has probability ``1 - ε + ε / n_actions``.

    Args:
        q: (n_actions,) action values.
        epsilon: exploration rate in [0, 1].
        rng: the generator every random choice is drawn from.
    """
    n = q.shape[0]
    if epsilon > 0.0 and rng.random() < epsilon:
        return int(rng.integers(n))
    best = np.flatnonzero(q == q.max())
    if best.size == 1:
        return int(best[0])
    return int(best[rng.integers(best.size)])


class SarsaLambda:
    """Sarsa(λ) learner with replacing traces over a hashed tile coder.

    Args:
        coder: maps normalised states to the active tile indices.
        n_actions: number of discrete actions (≥ 1).
        config: learning parameters.
        rng: generator for all exploration draws (never the global random state).
        weights: optional (n_actions, table_size) float64 array to learn *in place*, e.g. shared
            between learners or resumed from a checkpoint; zeros by default (all actions equal).

    Raises:
        ValueError: bad ``n_actions``, or ``weights`` of the wrong shape or type.
    """

    def __init__(
        self,
        coder: TileCoder,
        n_actions: int,
        config: SarsaConfig,
        rng: np.random.Generator,
        weights: np.ndarray | None = None,
    ) -> None:
        if not 1 <= n_actions <= 1024:
            raise ValueError(f"n_actions: must be in [1, 1024], got {n_actions}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng: must be a numpy.random.Generator, got {type(rng).__name__}")
        shape = (n_actions, coder.table_size)
        if weights is None:
            weights = np.zeros(shape)
        elif (
            not isinstance(weights, np.ndarray)
            or weights.shape != shape
            or weights.dtype != np.float64
            or not weights.flags.c_contiguous
            or not weights.flags.writeable
        ):
            raise ValueError(
                f"weights: need a writable C-contiguous float64 array of shape {shape}, got "
                f"{getattr(weights, 'dtype', type(weights))} {np.shape(weights)}"
            )
        self.coder = coder
        self.n_actions = n_actions
        self.config = config
        self.rng = rng
        self.weights = weights
        self._flat_weights = weights.reshape(-1)  # a view: updates land in `weights`
        self._action_offset = np.arange(n_actions, dtype=np.int64)[:, None] * coder.table_size
        self._step = config.alpha / coder.n_tilings
        self._decay = config.gamma * config.lam
        self._trace = np.zeros(n_actions * coder.table_size)
        self._active = np.empty(0, dtype=np.int64)  # flat indices with a nonzero trace
        self._features: np.ndarray | None = None  # F(s) of the current state
        self._action = -1

    # -- values ------------------------------------------------------------------------------

    def q_values(self, state: np.ndarray) -> np.ndarray:
        """Current action values (n_actions,) of one normalised state."""
        return self._q(self.coder.indices(state))

    def _q(self, features: np.ndarray) -> np.ndarray:
        q: np.ndarray = self.weights[:, features].sum(axis=1)
        return q

    def action_values(
        self, action_names: tuple[str, ...] | None = None, metadata: dict[str, Any] | None = None
    ) -> ActionValues:
        """An immutable snapshot of the current weights, ready to save or act greedily on."""
        return ActionValues(self.coder.config, self.weights, action_names, metadata)

    def traces(self) -> np.ndarray:
        """Dense copy (n_actions, table_size) of the eligibility traces (for inspection/tests)."""
        return self._trace.reshape(self.n_actions, -1).copy()

    @property
    def n_active_traces(self) -> int:
        """How many weights the next update touches."""
        return int(self._active.size)

    # -- learning ----------------------------------------------------------------------------

    def begin_episode(self, state: np.ndarray, action: int | None = None) -> int:
        """Start an episode in ``state``: clear the traces and choose the first action.

        Args:
            state: the first state.
            action: take this action instead of choosing one (no random draw): to replay
                recorded transitions, e.g. those of the in-life learner.
        """
        self._trace[self._active] = 0.0
        self._active = np.empty(0, dtype=np.int64)
        features = self.coder.indices(state)
        if action is None:
            action = epsilon_greedy(self._q(features), self.config.epsilon, self.rng)
        action = self._check_action(action)
        self._visit(features, action)
        return action

    def _check_action(self, action: int) -> int:
        if not 0 <= action < self.n_actions:
            raise ValueError(f"action: must be in [0, {self.n_actions - 1}], got {action}")
        return int(action)

    @overload
    def step(
        self,
        reward: float,
        next_state: np.ndarray,
        terminal: Literal[False] = False,
        action: int | None = None,
    ) -> int: ...

    @overload
    def step(
        self,
        reward: float,
        next_state: np.ndarray | None,
        terminal: Literal[True],
        action: int | None = None,
    ) -> None: ...

    def step(
        self,
        reward: float,
        next_state: np.ndarray | None,
        terminal: bool = False,
        action: int | None = None,
    ) -> int | None:
        """Learn from one transition and choose the next action.

        Args:
            reward: reward received for the last action.
            next_state: the state reached (ignored when ``terminal``; may be ``None`` then).
            terminal: the episode ended in a true terminal state (its value is 0).
            action: take this next action instead of choosing one (no random draw), to replay
                recorded transitions; ignored when ``terminal``.

        Returns:
            The next action, or ``None`` after a terminal transition.

        Raises:
            RuntimeError: called before :meth:`begin_episode` or after a terminal step.
            ValueError: a non-finite reward, or no ``next_state`` for a non-terminal step.
        """
        if self._features is None:
            raise RuntimeError("step() needs an episode: call begin_episode() first")
        if not np.isfinite(reward):
            raise ValueError(f"reward: must be finite, got {reward}")
        flat_w = self._flat_weights
        delta = reward - flat_w[self._action * self.coder.table_size + self._features].sum()
        if terminal:
            active = self._active
            flat_w[active] += (self._step * delta) * self._trace[active]
            self._trace[active] = 0.0
            self._active = np.empty(0, dtype=np.int64)
            self._features = None
            return None
        if next_state is None:
            raise ValueError("next_state: a non-terminal step needs the state reached")
        features = self.coder.indices(next_state)
        q_next = self._q(features)
        if action is None:
            action = epsilon_greedy(q_next, self.config.epsilon, self.rng)
        action = self._check_action(action)
        delta += self.config.gamma * q_next[action]
        active = self._active
        trace = self._trace
        flat_w[active] += (self._step * delta) * trace[active]
        # Decay, then drop what fell below the cutoff (exactly zero from then on).
        decayed = trace[active] * self._decay
        keep = decayed >= self.config.trace_cutoff
        trace[active] = np.where(keep, decayed, 0.0)
        self._active = active[keep]
        self._visit(features, action)
        return action

    def _visit(self, features: np.ndarray, action: int) -> None:
        """Replacing traces for (s, a): set to 1, other actions at F(s) to 0."""
        trace = self._trace
        if self.config.clear_other_action_traces and self.n_actions > 1:
            others = np.delete(self._action_offset[:, 0], action)
            # Entries zeroed here stay in the index list until the next decay drops them.
            trace[(others[:, None] + features[None, :]).reshape(-1)] = 0.0
        chosen = self._action_offset[action, 0] + features
        new = chosen[trace[chosen] == 0.0]  # not yet in the active list (trace 0 ⇔ not listed)
        trace[chosen] = 1.0
        if new.size:
            self._active = np.concatenate((self._active, np.unique(new)))
        self._features = features
        self._action = action
