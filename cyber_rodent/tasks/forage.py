"""``Forage``: the training setting of the Forage behaviour (approach and capture a pack)."""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.mjcf import Physics

from cyber_rodent.tasks.base import CyberRodentTask
from cyber_rodent.vision import BATTERY


class Forage(CyberRodentTask):
    """One robot learns to approach the nearest battery pack and dock onto it.

    In the paper Forage uses the bearing and distance of the nearest pack and is available
    only with a pack in view, so an episode starts (by default) from a placement in which the
    robot sees a pack.

    Actions: ``wheels`` (1, 2) m/s and ``led`` (1,); the LED plays no role here.

    Reward: 1 at the step the robot captures a pack (teeth on the electrodes, aligned), which
    ends the episode (discount 0); 0 on every other step. Discounting makes faster captures
    worth more.

    Episode: ``episode_steps`` (default 100) control steps, cut with discount 1; it also ends
    with discount 0 if the robot's energy runs out (only possible with ``episode_steps`` >
    ``initial_energy``).

    Args:
        rng: the task's generator.
        start_in_view: re-draw the initial placement until the robot sees a pack.
        **options: see :class:`~cyber_rodent.tasks.base.CyberRodentTask` (defaults here:
            1 robot, 5 packs, 100 steps).
    """

    name = "forage"
    n_controlled = 1

    def __init__(self, rng: np.random.Generator, *, start_in_view: bool = True, **options: Any):
        options.setdefault("n_robots", 1)
        options.setdefault("episode_steps", 100)
        self.start_in_view = bool(start_in_view)
        super().__init__(rng, **options)
        if self.start_in_view and self.world.config.n_packs == 0:
            raise ValueError("n_packs must be >= 1 for Forage with start_in_view=True")

    def _start_episode(self) -> None:
        if self.start_in_view:
            self._redraw_until(lambda f: f.visible[0, BATTERY], "a pack in view")

    def _set_decisions(self, values: dict[str, np.ndarray]) -> None:
        self._mate[:] = False
        self._recharge[:] = True  # a capture ends the episode anyway

    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        return np.array([1.0 if self.last_events.docked[0] else 0.0])

    def get_termination(self, physics: Physics | None = None) -> float | None:
        if self.last_events.docked[0] or not self.survival.alive[0]:
            return 0.0
        return None
