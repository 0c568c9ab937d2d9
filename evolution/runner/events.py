"""The event log of an evolution run: dockings, recharge ends, matings, deaths and births.

One row per event, in a compact int64 table (``step, robot, kind, slot, generation, value``), so a
paper-scale run (tens of thousands of events) costs a few megabytes and converts to a pandas
``DataFrame`` or a CSV file in one call. The runner appends only on the rare steps that have an
event, so the log costs nothing on ordinary steps.

Columns:

- ``step``: the world control step (1-based: the step's number once it has been taken).
- ``robot``: the physical robot.
- ``kind``: an :class:`EventKind`.
- ``slot``, ``generation``: the virtual agent concerned (its time-sharing slot and the
  generation that slot was at). For world events that is the agent that was active during the
  step; for a birth it is the new agent.
- ``value``: kind-specific: the pack (``DOCK``), the :class:`cyber_rodent.survival.RechargeEnd`
  reason (``RECHARGE_END``; :data:`RECHARGE_END_SWITCHED` = 0 when the runner ended the recharge
  because the agent was switched out), the partner robot (``MATE``), the agent's age
  (``DEATH``), the :class:`evolution.agent.Origin` of the new agent (``BIRTH``; ``OFFSPRING`` =
  an EE offspring, ``SELECTED`` = a CE offspring, ``RECEIVED`` = mEDEA's), the sender
  (``RECEIVE``), 0 (``LISTEN``, ``TIPPED``, ``STUCK``), the control steps the trouble lasted
  (``TIPPED_END``, ``STUCK_END``), what the rescue ended (``RESCUE``: 1 tipped, 2 stuck).
"""

from __future__ import annotations

import enum
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from evolution.agent import Origin

if TYPE_CHECKING:  # pandas is imported only when a table is asked for
    import pandas as pd

COLUMNS = ("step", "robot", "kind", "slot", "generation", "value")
#: ``value`` of a ``RECHARGE_END`` caused by an agent switch (``RechargeEnd.NONE`` in the world).
RECHARGE_END_SWITCHED = 0


class EventKind(enum.IntEnum):
    """What happened (the ``kind`` column)."""

    DOCK = 0  #: the robot captured a battery pack (value: the pack)
    RECHARGE_END = 1  #: the robot's recharge ended (value: the RechargeEnd reason)
    MATE = 2  #: a successful IR exchange (value: the partner robot)
    DEATH = 3  #: the active agent's energy reached 0 (value: its age)
    BIRTH = 4  #: a new agent took over a slot (value: its Origin)
    RECEIVE = 5  #: mEDEA: the robot first received a genome from a sender (value: the sender)
    LISTEN = 6  #: mEDEA: the robot fell silent, listening, having received none (value: 0)
    TIPPED = 7  #: the watchdog: the robot tipped past survival.tip_uprightness (value: 0)
    TIPPED_END = 8  #: it is upright again (value: the control steps it was tipped)
    STUCK = 9  #: the watchdog: the robot got stuck (value: 0)
    STUCK_END = 10  #: it moves again (value: the control steps it was stuck)
    RESCUE = 11  #: survival.rescue set the robot upright at a free spot (value: 1 tipped, 2 stuck)


class EventLog:
    """A growable int64 table of events (see the module docstring for the columns).

    Args:
        capacity: initial number of rows; the table doubles when full.
    """

    def __init__(self, capacity: int = 1024) -> None:
        self._rows = np.zeros((max(int(capacity), 1), len(COLUMNS)), dtype=np.int64)
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def append(
        self, step: int, robot: int, kind: int, slot: int, generation: int, value: int
    ) -> None:
        """Add one event."""
        if self._n == len(self._rows):
            self._grow()
        self._rows[self._n] = (step, robot, kind, slot, generation, value)
        self._n += 1

    def _grow(self) -> None:
        bigger = np.zeros((2 * len(self._rows), len(COLUMNS)), dtype=np.int64)
        bigger[: self._n] = self._rows[: self._n]
        self._rows = bigger

    @property
    def array(self) -> np.ndarray:
        """(n_events, 6) read-only view of the rows, in the order they happened."""
        view = self._rows[: self._n]
        view.flags.writeable = False
        return view

    def counts(self) -> dict[str, int]:
        """Number of events of each kind, by lower-case kind name."""
        kinds = np.bincount(self._rows[: self._n, 2], minlength=len(EventKind))
        return {kind.name.lower(): int(kinds[kind]) for kind in EventKind}

    def offspring(self) -> int:
        """Births of offspring: EE offspring made at a full lifetime, CE selected children, or
        mEDEA's received genomes."""
        rows = self._rows[: self._n]
        births = rows[rows[:, 2] == EventKind.BIRTH]
        made = (Origin.OFFSPRING, Origin.SELECTED, Origin.RECEIVED)
        return int(np.isin(births[:, 5], made).sum())

    def watchdog(self, generation_steps: list[int]) -> list[dict[str, int]]:
        """Per closed generation (the steps after the previous one closed, up to its own), what
        the watchdog saw: tips and jams that began, robot-steps spent tipped and stuck (of the
        troubles that ended in it, or that go on past its end), rescues, and the robots
        concerned (a bit mask is impractical past 63 robots, so their count)."""
        rows = self._rows[: self._n]
        kinds = rows[:, 2]
        table = []
        start = 0
        for generation, end in enumerate(generation_steps):
            inside = (rows[:, 0] > start) & (rows[:, 0] <= end)
            row = {"generation": generation}
            for name, kind in (("tips", EventKind.TIPPED), ("jams", EventKind.STUCK),
                               ("rescues", EventKind.RESCUE)):  # fmt: skip
                row[name] = int(np.count_nonzero(inside & (kinds == kind)))
            for name, kind in (("tipped_steps", EventKind.TIPPED_END),
                               ("stuck_steps", EventKind.STUCK_END)):  # fmt: skip
                row[name] = int(rows[inside & (kinds == kind), 5].sum())
            troubled = inside & np.isin(kinds, (EventKind.TIPPED, EventKind.STUCK))
            row["robots"] = int(len(np.unique(rows[troubled, 1])))
            table.append(row)
            start = end
        return table

    def to_frame(self) -> pd.DataFrame:
        """The log as a ``DataFrame`` with a ``kind`` column of names (``"dock"``, ...)."""
        import pandas as pd

        frame = pd.DataFrame(self._rows[: self._n].copy(), columns=list(COLUMNS))
        names = np.array([k.name.lower() for k in EventKind])
        frame["kind"] = pd.Categorical(names[frame["kind"].to_numpy()], categories=list(names))
        return frame

    def write_csv(self, path: str | os.PathLike[str]) -> None:
        """Write the log as CSV (kinds as names)."""
        self.to_frame().to_csv(path, index=False)

    def state(self) -> dict[str, Any]:
        """The log as plain state: its (n_events, 6) int64 rows (docs/design.md §10)."""
        return {"rows": self._rows[: self._n].copy()}

    def load_state(self, state: dict[str, Any]) -> None:
        """Replace the log's rows with a :meth:`state`'s.

        Raises:
            ValueError: the rows are not an (n, 6) int64 array.
        """
        rows = state["rows"]
        if not (
            isinstance(rows, np.ndarray)
            and rows.dtype == np.int64
            and rows.ndim == 2
            and rows.shape[1] == len(COLUMNS)
        ):
            raise ValueError(f"event log rows must be an (n, {len(COLUMNS)}) int64 array")
        self._n = len(rows)
        self._rows = np.zeros((max(2 * self._n, 1024), len(COLUMNS)), dtype=np.int64)
        self._rows[: self._n] = rows
