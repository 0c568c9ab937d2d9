"""``Search``: the training setting of the Search behaviour (wander, avoid obstacles)."""

from __future__ import annotations

from typing import Any

import numpy as np
from dm_control.mjcf import Physics

from cyber_rodent.tasks.base import CyberRodentTask
from cyber_rodent.tasks.rewards import search_reward


class Search(CyberRodentTask):
    """One robot learns to move around the field without bumping into things.

    Search is the paper's always-available exploration behaviour: obstacle avoidance from the
    proximity sensors. Obstacles are the walls, the packs and the other robots, which stand
    still (parked, LEDs off) so that the learner sees static obstacles of every kind.

    Actions: ``wheels`` (1, 2) m/s and ``led`` (1,). The robot never signals Mate, and if it
    happens to dock onto a pack it stops recharging at once (and makes the reflex turn).

    Reward, per step: forward progress minus a collision penalty,
    ``clip(d / (reference_speed * control_dt), -1, 1) - collision_penalty * collided``, where
    ``d`` is the displacement of the robot's centre along its heading at the start of the step
    and ``collided`` is 1 when its body touches a wall, a pack or a robot at the end of the
    step. Driving straight at ``reference_speed`` in free space earns 1 per step; spinning in
    place earns 0; pushing against a wall earns at most ``-collision_penalty``. The rule is the
    Search behaviour's training reward (:func:`~cyber_rodent.tasks.rewards.search_reward`), whose
    episodes use a penalty of 3.

    Episode: ``episode_steps`` (default 100), cut with discount 1; ends with discount 0 if the
    robot's energy runs out.

    Args:
        rng: the task's generator.
        reference_speed: forward speed (m/s) that earns the full progress reward.
        collision_penalty: reward subtracted at each step in contact.
        **options: see :class:`~cyber_rodent.tasks.base.CyberRodentTask` (defaults here:
            4 robots, 5 packs, 100 steps).
    """

    name = "search"
    n_controlled = 1

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        reference_speed: float = 0.5,
        collision_penalty: float = 1.0,
        **options: Any,
    ):
        if not (np.isfinite(reference_speed) and reference_speed > 0):
            raise ValueError(f"reference_speed must be > 0 m/s, got {reference_speed!r}")
        if not (np.isfinite(collision_penalty) and collision_penalty >= 0):
            raise ValueError(f"collision_penalty must be >= 0, got {collision_penalty!r}")
        self.reference_speed = float(reference_speed)
        self.collision_penalty = float(collision_penalty)
        options.setdefault("episode_steps", 100)
        super().__init__(rng, **options)
        self._start_pose = np.zeros(3)
        self._collided = np.zeros(self.world.config.n_robots, dtype=bool)
        self._progress = 0.0

    def _set_decisions(self, values: dict[str, np.ndarray]) -> None:
        self._mate[:] = False
        self._recharge[:] = False

    def before_step(self, action: Any, physics: Physics | None = None) -> None:
        super().before_step(action, physics)
        self._start_pose[:] = self.world.poses()[0]

    def after_step(self, physics: Physics | None = None) -> None:
        super().after_step(physics)
        x, y, _ = self.world.poses()[0]
        x0, y0, yaw0 = self._start_pose
        self._progress = (x - x0) * np.cos(yaw0) + (y - y0) * np.sin(yaw0)
        self.survival.collisions(out=self._collided)

    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        reference_step = self.reference_speed * self.survival.config.control_dt
        reward = search_reward(
            float(self._progress), bool(self._collided[0]), reference_step, self.collision_penalty
        )
        return np.array([reward])
