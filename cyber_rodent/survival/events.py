"""What a control step of the survival world reports: captures, recharge ends, deaths, matings."""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class RechargeEnd(IntEnum):
    """Why a recharge ended (``StepEvents.recharge_end_reason``)."""

    NONE = 0
    DECISION = 1  #: the recharge controller said stop
    MAX_STEPS = 2  #: ``max_recharge_steps`` consecutive steps reached
    FULL = 3  #: energy reached ``max_energy``


class StepEvents:
    """What happened in one control step, per robot, in preallocated arrays.

    The lean path reuses one instance for every step (no per-step allocation): its arrays are
    overwritten by the next step, so call :meth:`copy` to keep them. ``any`` is False on the
    vast majority of steps, which lets a hot loop skip event handling with one test.

    Attributes:
        docked: (n,) bool, the robot docked onto a pack this step (it recharges from the next).
        dock_pack: (n,) int, index of the pack docked onto, -1 where ``docked`` is False.
        captured: (n,) bool, the robot's active agent captured a battery this step, by
            ``SurvivalConfig.capture_rule``: ``docked`` ("docking"), or the docking's first
            recharge step ("recharge").
        recharge_ended: (n,) bool, the robot's recharge ended this step.
        recharge_end_reason: (n,) int, a :class:`RechargeEnd` value (``NONE`` elsewhere).
        died: (n,) bool, the robot's energy reached 0 this step.
        mate_partner: (n,) int, the robot it exchanged genomes with this step, else -1.
        any: True if any of the above happened.
    """

    __slots__ = (
        "docked",
        "dock_pack",
        "captured",
        "recharge_ended",
        "recharge_end_reason",
        "died",
        "mate_partner",
        "any",
    )
    #: The per-robot arrays (every slot but ``any``).
    ARRAYS = __slots__[:-1]

    def __init__(self, n_robots: int):
        self.docked = np.zeros(n_robots, dtype=bool)
        self.dock_pack = np.full(n_robots, -1, dtype=np.int64)
        self.captured = np.zeros(n_robots, dtype=bool)
        self.recharge_ended = np.zeros(n_robots, dtype=bool)
        self.recharge_end_reason = np.zeros(n_robots, dtype=np.int64)
        self.died = np.zeros(n_robots, dtype=bool)
        self.mate_partner = np.full(n_robots, -1, dtype=np.int64)
        self.any = False

    def clear(self) -> None:
        if self.any:
            self.docked[:] = False
            self.dock_pack[:] = -1
            self.captured[:] = False
            self.recharge_ended[:] = False
            self.recharge_end_reason[:] = RechargeEnd.NONE
            self.died[:] = False
            self.mate_partner[:] = -1
            self.any = False

    def copy(self) -> StepEvents:
        other = StepEvents(len(self.docked))
        for name in self.ARRAYS:
            np.copyto(getattr(other, name), getattr(self, name))
        other.any = self.any
        return other

    def record_dock(self, robot: int, pack: int) -> None:
        """``robot`` captured ``pack``."""
        self.docked[robot] = True
        self.dock_pack[robot] = pack
        self.any = True

    def record_recharge_end(self, robot: int, reason: RechargeEnd) -> None:
        """``robot``'s recharge ended for ``reason``."""
        self.recharge_ended[robot] = True
        self.recharge_end_reason[robot] = reason
        self.any = True

    def dockings(self) -> list[tuple[int, int]]:
        """(robot, pack) for each capture this step."""
        return [(int(i), int(self.dock_pack[i])) for i in np.flatnonzero(self.docked)]

    def recharge_ends(self) -> list[tuple[int, RechargeEnd]]:
        """(robot, reason) for each recharge that ended this step."""
        return [
            (int(i), RechargeEnd(int(self.recharge_end_reason[i])))
            for i in np.flatnonzero(self.recharge_ended)
        ]

    def deaths(self) -> list[int]:
        """Robots whose energy reached 0 this step."""
        return [int(i) for i in np.flatnonzero(self.died)]

    def matings(self) -> list[tuple[int, int]]:
        """(robot_a, robot_b), a < b, for each IR exchange this step."""
        return [
            (int(i), int(self.mate_partner[i]))
            for i in np.flatnonzero(self.mate_partner >= 0)
            if i < self.mate_partner[i]
        ]

    def __repr__(self) -> str:
        return (
            f"StepEvents(dockings={self.dockings()}, recharge_ends={self.recharge_ends()}, "
            f"deaths={self.deaths()}, matings={self.matings()})"
        )
