"""``Survival``: the paper's multi-robot survival setting as a dm-control task."""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np
from dm_control.mjcf import Physics
from dm_env import specs

from cyber_rodent.tasks.base import SWITCH_ON, CyberRodentTask


class Survival(CyberRodentTask):
    """Four robots and five packs (the paper's simulation); every robot is controlled.

    Each robot must keep its virtual energy above 0 by docking onto packs, and reproduces by
    IR exchanges with robots that also signal Mate. The task is the interface for users and
    for multi-agent learners; the evolution runner steps the same
    :class:`~cyber_rodent.survival.SurvivalWorld` on its lean path instead.

    Actions (``k`` = ``n_robots``): ``wheels`` (k, 2) m/s, ``led`` (k,), plus

    * ``mate`` (k,) in [0, 1]: above 0.5 the robot's agent runs Mate (willing to exchange);
    * ``recharge`` (k,) in [0, 1]: while docked, above 0.5 continues recharging, otherwise
      recharging stops this step (the evolved recharge controller's decision).

    Reward, per robot and step: ``dock_reward`` for each capture of a pack plus
    ``mate_reward`` for each successful IR exchange, the two survival tasks the paper scores
    (captured batteries and matings); 0 otherwise. Dying costs no reward directly: a dead
    robot earns nothing more.

    Episode: ``episode_steps`` control steps (default 400, one agent lifetime of the paper),
    cut with discount 1; it ends early with discount 0 when every robot is dead. A dead robot
    stands still with its LED dark (no agent replacement here; that is evolution's job).

    Args:
        rng: the task's generator.
        dock_reward: reward for a capture.
        mate_reward: reward for an IR exchange.
        **options: see :class:`~cyber_rodent.tasks.base.CyberRodentTask` (defaults here:
            4 robots, 5 packs, 400 steps).
    """

    name = "survival"
    n_controlled = None

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        dock_reward: float = 1.0,
        mate_reward: float = 1.0,
        **options: Any,
    ):
        options.setdefault("episode_steps", 400)
        for key, value in (("dock_reward", dock_reward), ("mate_reward", mate_reward)):
            if not np.isfinite(value):
                raise ValueError(f"{key} must be a finite number, got {value!r}")
        self.dock_reward = float(dock_reward)
        self.mate_reward = float(mate_reward)
        super().__init__(rng, **options)

    def _make_action_spec(self) -> OrderedDict[str, specs.BoundedArray]:
        spec = super()._make_action_spec()
        spec["mate"] = specs.BoundedArray((self.k,), np.float64, 0.0, 1.0, name="mate")
        spec["recharge"] = specs.BoundedArray((self.k,), np.float64, 0.0, 1.0, name="recharge")
        return spec

    def _set_decisions(self, values: dict[str, np.ndarray]) -> None:
        np.greater(values["mate"], SWITCH_ON, out=self._mate)
        np.greater(values["recharge"], SWITCH_ON, out=self._recharge)

    def get_reward(self, physics: Physics | None = None) -> np.ndarray:
        ev = self.last_events
        reward = np.zeros(self.k)
        if ev.any:
            reward += self.dock_reward * ev.docked
            reward += self.mate_reward * (ev.mate_partner >= 0)
        return reward

    def get_termination(self, physics: Physics | None = None) -> float | None:
        """Discount 0 once every robot is dead."""
        return 0.0 if not self.survival.alive.any() else None
