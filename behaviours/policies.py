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
from behaviours.reactive import reactive_forage, reactive_mate, reactive_search


class CommandPolicy(Protocol):
    """Anything that maps a batch of one behaviour's inputs to wheel-command indices."""

    def act(self, states: np.ndarray) -> np.ndarray:
        """(batch,) command indices for (batch, 2) inputs in [0, 1]."""
        ...


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
        if n and (behaviour.min() < 0 or behaviour.max() >= N_BEHAVIOURS):
            raise ValueError(
                f"behaviour: indices must be in [0, {N_BEHAVIOURS}) (mate, forage, search), got "
                f"{behaviour.min()} to {behaviour.max()}"
            )
        if out is None:
            out = np.empty(n, dtype=np.int64)
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
