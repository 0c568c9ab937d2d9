"""IR mating: the geometry of the robots' IR ports and exchanges after consecutive steps.

An exchange succeeds when both robots signal Mate and each one's IR port faces the other's
within ``mate_angle_deg`` (±15°) at a port-to-port distance of at most ``mate_distance``
(0.35 m), for ``mate_consecutive_steps`` consecutive control steps (docs/design.md §5). No IR
link crosses a wall: in a world of several arenas (``WorldConfig.arenas``) only robots of one
arena pair. The world reports the pair; what is exchanged is the caller's business.
"""

from __future__ import annotations

import math

import numpy as np

from cyber_rodent.backend import Backend, bind, pick
from cyber_rodent.survival import kernels
from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.events import StepEvents
from cyber_rodent.survival.kernels import IrPorts, MatingRules
from cyber_rodent.world import World


class Mating:
    """Mating detection of a world's robots, with the pairs' consecutive-step streaks.

    Args:
        world: the physical world (its robots' IR port sites).
        config: the survival rules.
        signal, alive, docked: (n,) the survival world's flags, read after every step.
        partner: (n,) the step events' mate partners, written for exchanges.
        backend: ``"numba"`` (:func:`~cyber_rodent.survival.kernels.mate`) or ``"numpy"``
            (its reference).

    Attributes:
        streak: (n, n) int, consecutive steps each pair has held the mating condition
            (symmetric; reset when the pair exchanges or stops holding it).
    """

    def __init__(
        self,
        world: World,
        config: SurvivalConfig,
        signal: np.ndarray,
        alive: np.ndarray,
        docked: np.ndarray,
        partner: np.ndarray,
        backend: Backend,
    ):
        self.world = world
        self.config = config
        n = world.config.n_robots
        self.streak = np.zeros((n, n), dtype=np.int64)
        self._ir_sites = world.ir_port_site
        d = world.data
        self.ports = IrPorts(
            site=np.asarray(world.ir_port_site, dtype=np.int64),
            site_xpos=d.site_xpos,
            site_xmat=d.site_xmat,
            streak=self.streak,
            streak_active=np.zeros(1, dtype=np.bool_),
            pairs=np.zeros((n * n, 3)),
            arena=np.asarray(world.robot_arena, dtype=np.int64),
        )
        self.rules = MatingRules(
            reach2=float(config.mate_distance) ** 2,
            cos_angle=math.cos(math.radians(config.mate_angle_deg)),
            consecutive_steps=int(config.mate_consecutive_steps),
        )
        kernel = pick(backend, kernels.mate, kernels.mate_reference)
        self._mate = bind(kernel, signal, alive, docked, self.ports, self.rules, partner)

    @property
    def streak_active(self) -> bool:
        """Some pair has a streak (so :attr:`streak` is not all zeros)."""
        return bool(self.ports.streak_active[0])

    @streak_active.setter
    def streak_active(self, active: bool) -> None:
        self.ports.streak_active[0] = active

    def reset(self) -> None:
        """Forget every streak."""
        self.streak[:] = 0
        self.streak_active = False

    def after_step(self, events: StepEvents) -> None:
        """Record this step's exchanges in ``events`` (:func:`~cyber_rodent.survival.kernels.mate`
        on the flags and partners given at construction)."""
        if self._mate():
            events.any = True

    def ir_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """Pairwise IR-port geometry: (distance m, angle deg), both (n, n).

        ``angle[i, j]`` is the angle between robot ``i``'s IR port direction and the line from
        its port to robot ``j``'s port; the diagonal is undefined (distance 0, angle 0).
        """
        d = self.world.data
        sites = self._ir_sites
        pos = d.site_xpos[sites]
        axis = d.site_xmat[sites][:, 2::3]  # the site's z axis: where the port points
        diff = pos[None, :, :] - pos[:, None, :]  # diff[i, j] = p_j - p_i
        dist = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        proj = np.einsum("ik,ijk->ij", axis, diff)
        np.fill_diagonal(dist, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.where(dist > 0.0, proj / np.where(dist > 0.0, dist, 1.0), 1.0)
            angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        np.fill_diagonal(angle, 0.0)
        return dist, angle


__all__ = ["Mating"]
