"""All three behaviours for all robots at once: what the evolution runner calls every step.

Each robot's active agent picks a behaviour (Mate, Forage or Search); :meth:`BehaviourPolicies.
commands` turns those choices and the robots' :class:`~behaviours.inputs.BehaviourInputs` into
discrete wheel commands (indices into :data:`cyber_rodent.commands.WHEEL_COMMANDS`) in one
vectorised call: per behaviour, one batched greedy-policy evaluation over the robots that run it.

Two sets ship with the package:

* :meth:`BehaviourPolicies.load_default`: greedy policies of the trained action values
  (``behaviours/data/*.npz``), the paper's learned behaviours.
* :meth:`BehaviourPolicies.reactive`: the hand-written baseline (:mod:`behaviours.reactive`),
  usable without any trained values.
"""

from __future__ import annotations

import os
from typing import Protocol

import numpy as np

from behaviours import greedy_kernel
from behaviours.definitions import load_values
from behaviours.greedy_policy import GreedyPolicy
from behaviours.inputs import BEHAVIOUR_NAMES, N_BEHAVIOURS, BehaviourInputs
from behaviours.reactive import reactive_forage, reactive_mate, reactive_search


class CommandPolicy(Protocol):
    """Anything that maps a batch of one behaviour's inputs to wheel-command indices."""

    def act(self, states: np.ndarray) -> np.ndarray:
        """(batch,) command indices for (batch, 2) inputs in [0, 1]."""
        ...


class _FusedGreedy:
    """The three greedy policies evaluated for all robots in one pass (the hot path).

    Equivalent, bit for bit, to calling each :class:`GreedyPolicy` on its robots: per robot it
    computes the same tile coordinates with its behaviour's coder parameters, reads the same
    precomputed hash lookup, gathers the same weight rows and sums them over the tilings in the
    same order, then takes the same ``argmax``. Doing it as one batch saves the per-behaviour
    fixed costs (three coder calls of ~10 µs each) in a loop run 1.2 million times per run.
    """

    def __init__(self, policies: tuple[GreedyPolicy, ...]) -> None:
        coders = [p.coder for p in policies]
        dims = {c.config.n_dims for c in coders}
        tilings = {c.config.n_tilings for c in coders}
        if len(dims) != 1 or len(tilings) != 1 or any(c._lookup is None for c in coders):
            raise ValueError("coders differ in shape or hash on the fly: no fused path")
        self.n_tilings = tilings.pop()
        self.scale = np.stack([c.scale for c in coders])  # (B, dims)
        self.offsets = np.stack([c.offsets for c in coders])  # (B, T, dims)
        self.count = np.stack([c.coordinate_count for c in coders])[:, None, :]  # (B, 1, dims)
        self.strides = np.stack([c._strides for c in coders])[:, None, :]  # (B, 1, dims)
        lookup_base = np.cumsum([0] + [c._lookup.size for c in coders[:-1]])
        # Per behaviour and tiling: where its lookup block starts in the concatenated lookup.
        self.base = np.stack(
            [c._tiling_base + lookup_base[i] for i, c in enumerate(coders)]
        )  # (B, T)
        table_base = np.cumsum([0] + [p._table.shape[0] for p in policies[:-1]])
        # Lookup entries already shifted to the behaviour's rows of the stacked weight table.
        self.lookup = np.concatenate([c._lookup + table_base[i] for i, c in enumerate(coders)])
        self.table = np.concatenate([p._table for p in policies])  # (sum tables, n_actions)
        self._count2 = np.ascontiguousarray(self.count[:, 0, :], dtype=np.int64)  # (B, dims)
        self._strides2 = np.ascontiguousarray(self.strides[:, 0, :], dtype=np.int64)

    def act_compiled(self, behaviour: np.ndarray, inputs: BehaviourInputs, out: np.ndarray) -> int:
        """:meth:`act` for every robot in one compiled call (:mod:`behaviours.greedy_kernel`);
        returns its status code."""
        return greedy_kernel.act(
            behaviour, inputs.mate, inputs.forage, inputs.search, self.scale, self.offsets,
            self._count2, self._strides2, self.base, self.lookup, self.table, out,
        )  # fmt: skip

    def act(self, behaviour: np.ndarray, states: np.ndarray) -> np.ndarray:
        if states.size and not (states.min() >= 0.0 and states.max() <= 1.0):
            raise ValueError("states: every behaviour input must be in [0, 1] (no NaN)")
        q = np.floor(states * self.scale[behaviour]).astype(np.int64)  # (n, dims)
        coords = (q[:, None, :] + self.offsets[behaviour]) // self.n_tilings
        coords %= self.count[behaviour]
        flat = (coords * self.strides[behaviour]).sum(axis=-1) + self.base[behaviour]
        return np.argmax(self.table[self.lookup[flat]].sum(axis=-2), axis=-1)


class BehaviourPolicies:
    """The Mate, Forage and Search policies, evaluated for all robots at once.

    Args:
        mate: the Mate policy.
        forage: the Forage policy.
        search: the Search policy.
        kind: a label for reports (``"learned"``, ``"reactive"``, ...).
    """

    def __init__(
        self,
        mate: CommandPolicy,
        forage: CommandPolicy,
        search: CommandPolicy,
        kind: str = "custom",
    ) -> None:
        self.policies: tuple[CommandPolicy, ...] = (mate, forage, search)
        self.kind = kind
        self._fused: _FusedGreedy | None = None
        if all(isinstance(p, GreedyPolicy) for p in self.policies):
            try:
                self._fused = _FusedGreedy(self.policies)
            except ValueError:
                self._fused = None
        self._rows = np.arange(0)
        #: The fused greedy policies run compiled (:mod:`behaviours.greedy_kernel`).
        self._compiled = self._fused is not None and greedy_kernel.AVAILABLE

    def kernel_arguments(self) -> tuple:
        """The table arguments of ``greedy_kernel.act`` (between the inputs and the output),
        for callers that run it inside their own compiled code; () when these policies do not
        run compiled (not all greedy, or no numba)."""
        f = self._fused
        if not self._compiled or f is None:
            return ()
        return (f.scale, f.offsets, f._count2, f._strides2, f.base, f.lookup, f.table)

    @classmethod
    def load_default(cls) -> BehaviourPolicies:
        """Greedy policies of the shipped trained action values.

        Raises:
            FileNotFoundError, CorruptActionValuesError, IncompatibleActionValuesError: see
                :func:`behaviours.definitions.load_values`.
        """
        return cls.from_directory(None)

    @classmethod
    def from_directory(cls, directory: str | os.PathLike | None) -> BehaviourPolicies:
        """Greedy policies of ``<directory>/{mate,forage,search}.npz`` (None: the shipped ones)."""
        policies = [GreedyPolicy(load_values(name, directory)) for name in BEHAVIOUR_NAMES]
        return cls(*policies, kind="learned")

    @classmethod
    def reactive(cls) -> BehaviourPolicies:
        """The hand-written reactive baseline (needs no trained values)."""
        return cls(reactive_mate(), reactive_forage(), reactive_search(), kind="reactive")

    def commands(
        self, behaviour: np.ndarray, inputs: BehaviourInputs, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Each robot's wheel command for its chosen behaviour.

        Args:
            behaviour: (n,) behaviour index per robot (``MATE``, ``FORAGE`` or ``SEARCH``).
            inputs: the robots' behaviour inputs (``behaviour_inputs``).
            out: optional (n,) int64 buffer for the result.

        Returns:
            (n,) int64 indices into ``WHEEL_COMMANDS``.

        Raises:
            ValueError: wrong shape or a behaviour index outside [0, 3).
        """
        behaviour = np.asarray(behaviour)
        n = inputs.n_robots
        if behaviour.shape != (n,):
            raise ValueError(f"behaviour: expected shape ({n},), got {behaviour.shape}")
        if self._compiled and out is not None and out.dtype == np.int64:
            status = self._fused.act_compiled(behaviour, inputs, out)
            if status == greedy_kernel.OK:
                return out
            if status == greedy_kernel.BAD_STATE:
                raise ValueError("states: every behaviour input must be in [0, 1] (no NaN)")
            # BAD_BEHAVIOUR: the message below names the indices.
        if n and (behaviour.min() < 0 or behaviour.max() >= N_BEHAVIOURS):
            raise ValueError(
                f"behaviour: indices must be in [0, {N_BEHAVIOURS}) (mate, forage, search), got "
                f"{behaviour.min()} to {behaviour.max()}"
            )
        if out is None:
            out = np.empty(n, dtype=np.int64)
        if self._fused is not None:
            if self._rows.size != n:
                self._rows = np.arange(n)
            # Each robot's own behaviour's input row: stack (3, n, 2), pick [behaviour, robot].
            states = np.stack((inputs.mate, inputs.forage, inputs.search))[behaviour, self._rows]
            out[:] = self._fused.act(behaviour, states)
            return out
        for b in range(N_BEHAVIOURS):
            rows = np.flatnonzero(behaviour == b)
            if rows.size == n:
                out[:] = self.policies[b].act(inputs.of(b))
                break
            if rows.size:
                out[rows] = self.policies[b].act(inputs.of(b)[rows])
        return out

    def act(self, behaviour: int, states: np.ndarray) -> np.ndarray:
        """Commands (batch,) of one behaviour for (batch, 2) inputs."""
        return np.asarray(self.policies[behaviour].act(states), dtype=np.int64).reshape(-1)
