"""``Mate``: the training setting of the Mate behaviour (reach the IR exchange position)."""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.mjcf import Physics

from cyber_rodent.tasks.base import CyberRodentTask
from cyber_rodent.vision import FACE, LED, VisionFrame


class Mate(CyberRodentTask):
    """Two robots, both running Mate, learn to meet nose to nose for an IR exchange.

    **Partner choice.** The partner is not a fixed script: the task takes one action *per
    robot* (``wheels`` (2, 2), ``led`` (2,)) and returns one observation and one reward per
    robot, so a learner trains Mate against a partner that also runs Mate, typically the same
    policy acting on each robot's own observation (self-play; each robot's transitions are
    experience for the shared action values). To train against a different partner, compute
    robot 1's action with it. We chose this over a partner-policy callable because it keeps
    the task a plain ``dm_env`` environment (no hidden policy inside it), and both robots'
    experience is available to the learner.

    Both robots always signal Mate (they run Mate); their LEDs start on (docs/design.md §5: the LED
    is on when Mate wins over Forage), and the ``led`` action sets them from then on. In the
    paper Mate uses bearing and distance of the nearest green LED, or of the red face if no
    LED is seen, and is available only with another robot in view: episodes start (by
    default) from a placement in which each robot sees the other's LED or face.

    Reward, per robot: 1 for both at the step their IR ports face each other within the
    mating angle and distance (``SurvivalConfig.mate_angle_deg``, ``mate_distance``), which
    ends the episode (discount 0); 0 otherwise.

    Episode: ``episode_steps`` (default 100), cut with discount 1; ends with discount 0 if a
    robot's energy runs out.

    Args:
        rng: the task's generator.
        start_in_view: re-draw the initial placement until the two robots see each other.
        **options: see :class:`~cyber_rodent.tasks.base.CyberRodentTask` (defaults here:
            2 robots, 0 packs, 100 steps).
    """

    name = "mate"
    n_controlled = 2

    def __init__(self, rng: np.random.Generator, *, start_in_view: bool = True, **options: Any):
        options.setdefault("n_robots", 2)
        options.setdefault("n_packs", 0)
        options.setdefault("episode_steps", 100)
        self.start_in_view = bool(start_in_view)
        super().__init__(rng, **options)

    def _start_state(self) -> None:
        on = np.zeros(self.world.config.n_robots, dtype=bool)
        on[:2] = True
        self.world.set_led(on)

    def _start_episode(self) -> None:
        self._start_state()
        if self.start_in_view:

            def see_each_other(frame: VisionFrame) -> bool:
                sees = frame.visible[:2, LED] | frame.visible[:2, FACE]
                return bool(sees.all())

            self._redraw_until(see_each_other, "the two robots in view of each other")

    def _set_decisions(self, values: dict[str, np.ndarray]) -> None:
        self._mate[:] = False
        self._mate[:2] = True
        self._recharge[:] = False

    def _mated(self) -> bool:
        return bool(self.last_events.mate_partner[0] == 1)

    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        return np.full(2, 1.0 if self._mated() else 0.0)

    def get_termination(self, physics: Physics | None = None) -> float | None:
        if self._mated() or not self.survival.alive[:2].all():
            return 0.0
        return None
