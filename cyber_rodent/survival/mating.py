"""IR mating: the geometry of the robots' IR ports and exchanges after consecutive steps.

An exchange succeeds when both robots signal Mate and each one's IR port faces the other's
within ``mate_angle_deg`` (±15°) at a port-to-port distance of at most ``mate_distance``
(0.35 m), for ``mate_consecutive_steps`` consecutive control steps (docs/design.md §5). The
world reports the pair; what is exchanged is the caller's business.
"""

from __future__ import annotations

import math

import numpy as np

from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.events import StepEvents
from cyber_rodent.world import World


class Mating:
    """Mating detection of a world's robots, with the pairs' consecutive-step streaks.

    Args:
        world: the physical world (its robots' IR port sites).
        config: the survival rules.

    Attributes:
        streak: (n, n) int, consecutive steps each pair has held the mating condition
            (symmetric; reset when the pair exchanges or stops holding it).
        streak_active: some pair has a streak (so :attr:`streak` is not all zeros).
    """

    def __init__(self, world: World, config: SurvivalConfig):
        self.world = world
        self.config = config
        n = world.config.n_robots
        self.streak = np.zeros((n, n), dtype=np.int64)
        self.streak_active = False
        self._ir_sites = world.ir_port_site
        self._cos_mate = math.cos(math.radians(config.mate_angle_deg))

    def reset(self) -> None:
        """Forget every streak."""
        self.streak[:] = 0
        self.streak_active = False

    def after_step(
        self, signal: np.ndarray, alive: np.ndarray, docked: np.ndarray, events: StepEvents
    ) -> None:
        """Record this step's exchanges in ``events``; ``signal`` marks who signals Mate."""
        if np.count_nonzero(signal) >= 2:
            self.detect(signal, alive, docked, events)
        elif self.streak_active:
            self.reset()

    def detect(
        self, signal: np.ndarray, alive: np.ndarray, docked: np.ndarray, events: StepEvents
    ) -> None:
        """Advance the streaks of the signalling, free, living robots and record exchanges."""
        # Plain Python over the signalling pairs: with a few robots this is several times
        # cheaper than the (n, n) numpy version (ir_geometry), and it runs every step.
        cfg = self.config
        sig = signal & alive & ~docked
        who = np.flatnonzero(sig).tolist()
        pos = self.world.data.site_xpos[self._ir_sites].tolist()
        reach2 = cfg.mate_distance**2
        close = []
        for a_k, a in enumerate(who):
            pa = pos[a]
            for b in who[a_k + 1 :]:
                pb = pos[b]
                dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
                d2 = dx * dx + dy * dy + dz * dz
                if 0.0 < d2 <= reach2:
                    close.append((a, b, d2, dx, dy, dz))
        facing = []
        if close:
            axes = self.world.data.site_xmat[self._ir_sites].tolist()  # row-major 3x3
            limit = self._cos_mate
            for a, b, d2, dx, dy, dz in close:
                za, zb = axes[a], axes[b]  # each port's z axis: (m[2], m[5], m[8])
                dist = math.sqrt(d2)
                if (za[2] * dx + za[5] * dy + za[8] * dz) >= limit * dist and (
                    -(zb[2] * dx + zb[5] * dy + zb[8] * dz) >= limit * dist
                ):
                    facing.append((d2, a, b))
        # Consecutive-step streaks: pairs that hold the condition count up, all others reset.
        streak = self.streak
        previous = {(a, b): int(streak[a, b]) for _, a, b in facing}
        if self.streak_active:
            streak[:] = 0
        for (a, b), k in previous.items():
            streak[a, b] = streak[b, a] = k + 1
        self.streak_active = bool(facing)
        ready = sorted(p for p in facing if streak[p[1], p[2]] >= cfg.mate_consecutive_steps)
        # A robot exchanges with one partner per step: nearest pairs first (deterministic).
        for _, a, b in ready:
            if events.mate_partner[a] < 0 and events.mate_partner[b] < 0:
                events.mate_partner[a] = b
                events.mate_partner[b] = a
                streak[a, b] = streak[b, a] = 0
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
