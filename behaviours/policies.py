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

from behaviours.definitions import load_values
from behaviours.greedy_policy import GreedyPolicy
from behaviours.inputs import BEHAVIOUR_NAMES, N_BEHAVIOURS, BehaviourInputs
from behaviours.kernels import (
    BAD_BEHAVIOUR,
    BAD_STATE,
    GreedyTables,
    greedy_commands,
    greedy_commands_reference,
)
from behaviours.reactive import reactive_forage, reactive_mate, reactive_search
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, check_backend, pick


class CommandPolicy(Protocol):
    """Anything that maps a batch of one behaviour's inputs to wheel-command indices."""

    def act(self, states: np.ndarray) -> np.ndarray:
        """(batch,) command indices for (batch, 2) inputs in [0, 1]."""
        ...


def stack_tables(policies: tuple[GreedyPolicy, ...]) -> GreedyTables:
    """The greedy policies' coders and action values stacked for :func:`greedy_commands`.

    Per robot the kernel computes the same tile coordinates with its behaviour's coder
    parameters, reads the same precomputed hash lookup, gathers the same weight rows and sums
    them over the tilings in the same order as :meth:`GreedyPolicy.act`, then takes the same
    ``argmax``, so its choices equal each policy's own, bit for bit.

    Raises:
        ValueError: the coders differ in shape or hash on the fly (no precomputed lookup).
    """
    coders = [p.coder for p in policies]
    dims = {c.config.n_dims for c in coders}
    tilings = {c.config.n_tilings for c in coders}
    if len(dims) != 1 or len(tilings) != 1 or any(c.lookup is None for c in coders):
        raise ValueError("coders differ in shape or hash on the fly: no stacked tables")
    lookups = [c.lookup for c in coders]
    assert all(lookup is not None for lookup in lookups)
    lookup_base = np.cumsum([0] + [lk.size for lk in lookups[:-1] if lk is not None])
    table_base = np.cumsum([0] + [p.table.shape[0] for p in policies[:-1]])
    return GreedyTables(
        scale=np.stack([c.scale for c in coders]).astype(np.float64),
        offsets=np.stack([c.offsets for c in coders]).astype(np.int64),
        coordinate_count=np.ascontiguousarray(
            np.stack([c.coordinate_count for c in coders]), np.int64
        ),
        strides=np.ascontiguousarray(np.stack([c.strides for c in coders]), np.int64),
        # Per behaviour and tiling: where its lookup block starts in the concatenated lookup.
        base=np.stack([c.tiling_base + lookup_base[i] for i, c in enumerate(coders)]).astype(
            np.int64
        ),
        # Lookup entries already shifted to the behaviour's rows of the stacked weight table.
        lookup=np.concatenate(
            [lk + table_base[i] for i, lk in enumerate(lookups) if lk is not None]
        ).astype(np.int64),
        table=np.concatenate([p.table for p in policies]),
    )


def raise_for_status(status: int) -> None:
    """Raise the error that a :func:`greedy_commands` status code names (none for OK)."""
    if status == BAD_STATE:
        raise ValueError("states: every behaviour input must be in [0, 1] (no NaN)")
    if status == BAD_BEHAVIOUR:
        raise ValueError(
            f"behaviour: indices must be in [0, {N_BEHAVIOURS}) (mate, forage, search)"
        )


class BehaviourPolicies:
    """The Mate, Forage and Search policies, evaluated for all robots at once.

    Args:
        mate: the Mate policy.
        forage: the Forage policy.
        search: the Search policy.
        kind: a label for reports (``"learned"``, ``"reactive"``, ...).
        backend: ``"numba"`` or ``"numpy"``: which implementation of the stacked greedy
            policies :meth:`commands` runs.
    """

    def __init__(
        self,
        mate: CommandPolicy,
        forage: CommandPolicy,
        search: CommandPolicy,
        kind: str = "custom",
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        self.policies: tuple[CommandPolicy, ...] = (mate, forage, search)
        self.kind = kind
        self.backend = check_backend(backend)
        #: The stacked tables of three tile-coded greedy policies (None for other policies,
        #: which run one by one in Python).
        self.tables: GreedyTables | None = None
        greedy = tuple(p for p in self.policies if isinstance(p, GreedyPolicy))
        if len(greedy) == N_BEHAVIOURS:
            try:
                self.tables = stack_tables(greedy)
            except ValueError:
                self.tables = None
        self._greedy = pick(self.backend, greedy_commands, greedy_commands_reference)

    @classmethod
    def load_default(cls, backend: Backend = DEFAULT_BACKEND) -> BehaviourPolicies:
        """Greedy policies of the shipped trained action values.

        Raises:
            FileNotFoundError, CorruptActionValuesError, IncompatibleActionValuesError: see
                :func:`behaviours.definitions.load_values`.
        """
        return cls.from_directory(None, backend)

    @classmethod
    def from_directory(
        cls, directory: str | os.PathLike[str] | None, backend: Backend = DEFAULT_BACKEND
    ) -> BehaviourPolicies:
        """Greedy policies of ``<directory>/{mate,forage,search}.npz`` (None: the shipped ones)."""
        mate, forage, search = (GreedyPolicy(load_values(n, directory)) for n in BEHAVIOUR_NAMES)
        return cls(mate, forage, search, kind="learned", backend=backend)

    @classmethod
    def reactive(cls) -> BehaviourPolicies:
        """The hand-written reactive baseline (needs no trained values; runs in Python)."""
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
        if n and (behaviour.min() < 0 or behaviour.max() >= N_BEHAVIOURS):
            raise ValueError(
                f"behaviour: indices must be in [0, {N_BEHAVIOURS}) (mate, forage, search), got "
                f"{behaviour.min()} to {behaviour.max()}"
            )
        if out is None:
            out = np.empty(n, dtype=np.int64)
        if self.tables is not None:
            status = self._greedy(behaviour.astype(np.int64, copy=False), inputs, self.tables, out)
            raise_for_status(status)
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
