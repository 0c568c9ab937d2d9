"""Energy, docking, recharging and the rotation reflex: the Python side of the battery rules.

The per-step arithmetic (recharge gain, stopping rules, decay, deaths) is in
:mod:`cyber_rodent.survival.kernels`; this module holds what stays in Python because it is rare
or touches MuJoCo (docs/design.md §5):

* **Captures.** A teeth/electrode contact (the kernels' contact scan) is a capture only if the
  pack lies ahead of the robot within ``dock_bearing_tolerance_deg`` (:meth:`Docking.pack_ahead`).
* **The docking hold.** While recharging, the robot is held in place by a weld of its chassis to
  the world, an equality constraint of the world model (``world.dock_hold_name``), switched on
  at the capture pose (:meth:`Docking.dock`) and off at the release (:meth:`Docking.release`).
* **The reflex.** A release after recharging starts a rotation of random direction and length,
  drawn from the world's generator, which turns the teeth away from the pack.
* **Pack reactivation** (``WorldConfig.pack_reactivation_steps`` N > 0). A docking makes its
  pack inactive (dark, refusing new dockings) for the rest of the step and the N steps after
  it; :meth:`Docking.count_down` brings it back (docs/design.md §9.26).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cyber_rodent.backend import Backend, bind, pick
from cyber_rodent.commands import motor_scale
from cyber_rodent.survival import kernels
from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.events import StepEvents
from cyber_rodent.survival.kernels import (
    ContactScan,
    DockingTables,
    PackAvailability,
    StepFlags,
    SurvivalState,
)
from cyber_rodent.world import World, dock_hold_name

# Weld equality data layout (MuJoCo 3.x ``eq_data`` row): anchor (3), relative pose of body2 in
# body1's frame: position (3) then quaternion (4), torque scale (1).
_WELD_RELPOS = slice(3, 6)
_WELD_RELQUAT = slice(6, 10)
#: Contact pairs the scan buffers hold at first; they grow with the contact list.
_INITIAL_CONTACTS = 64


def recharge_gain(config: SurvivalConfig) -> float:
    """Net energy change of a recharge step (``decay_while_recharging`` also pays the decay)."""
    decay = config.energy_decay if config.decay_while_recharging else 0.0
    return config.recharge_rate - decay


def check_energy(energy: float, config: SurvivalConfig) -> float:
    """``energy`` as a float if it is a loadable energy, in [0, max_energy]; else ValueError."""
    e = float(energy)
    if not 0.0 <= e <= config.max_energy:
        raise ValueError(f"energy must be in [0, {config.max_energy}], got {energy!r}")
    return e


def check_recharge_steps(steps: int, config: SurvivalConfig) -> int:
    """``steps`` if it is a consecutive-recharge count a docked robot can have; else ValueError."""
    if not 0 <= int(steps) < config.max_recharge_steps:
        raise ValueError(
            f"recharge steps must be in [0, {config.max_recharge_steps}), got {steps!r}"
        )
    return int(steps)


class Docking:
    """Captures, the docking holds and the reflex of every robot of a world.

    Args:
        world: the physical world (its model has a docking-hold weld per robot).
        config: the survival rules.
        state: the survival world's per-robot state (written in place).
        dock_pack: (n,) the survival world's docked-to pack of each robot (written in place).
        flags: the flags of the step in progress (the scan reads ``in_reflex``).
        events: the survival world's step events (captures are recorded there).
        backend: which implementation of the contact scan runs.

    Attributes:
        tables: which geoms are teeth and electrodes, and whose.
        pack_xy: (n_packs, 2) pack positions, read at reset and by :meth:`refresh_pack_positions`.
        reactivation_steps: ``WorldConfig.pack_reactivation_steps`` (0: packs never go
            inactive).
        packs: the packs' reactivation countdowns and colours (:class:`PackAvailability`).
        inactive_packs: how many packs are inactive now (:meth:`count_down` runs only while
            some are).
    """

    def __init__(
        self,
        world: World,
        config: SurvivalConfig,
        state: SurvivalState,
        dock_pack: np.ndarray,
        flags: StepFlags,
        events: StepEvents,
        backend: Backend,
    ):
        self.world = world
        self.config = config
        #: m/s, the reflex's rim speed on this world's robot (``commands.motor_scale``).
        self.reflex_speed = config.reflex_wheel_speed * motor_scale(world.robot)
        self.state = state
        self.dock_pack = dock_pack
        self.flags = flags
        self.events = events
        m = world.model
        n_robots, n_packs = world.config.n_robots, world.config.n_packs
        hold = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, dock_hold_name(i))
            for i in range(n_robots)
        ]
        if min(hold) < 0:
            raise RuntimeError("the world model has no docking-hold welds (world.build_mjcf)")
        self.hold_eq = np.asarray(hold, dtype=np.int64)
        for i, e in enumerate(self.hold_eq):
            if m.eq_type[e] != mujoco.mjtEq.mjEQ_WELD or m.eq_obj1id[e] != world.chassis_body[i]:
                raise RuntimeError(f"{dock_hold_name(i)} is not a weld of robot {i}'s chassis")
        teeth_owner = np.full(m.ngeom, -1, dtype=np.int64)
        teeth_owner[world.teeth_geom] = np.arange(n_robots)
        electrode_owner = np.full(m.ngeom, -1, dtype=np.int64)
        electrode_owner[world.electrode_geom] = np.arange(n_packs)
        dock_code = np.zeros(m.ngeom, dtype=np.int8)
        dock_code[world.teeth_geom] = 1
        dock_code[world.electrode_geom] = 2
        self.tables = DockingTables(dock_code, teeth_owner, electrode_owner, world.pack_active)
        self.pack_xy = np.zeros((n_packs, 2))
        self.reactivation_steps = int(world.config.pack_reactivation_steps)
        self.packs = PackAvailability(
            countdown=np.zeros(n_packs, dtype=np.int64),
            active=world.pack_active,
            geom_rgba=m.geom_rgba,
            pack_geom=np.asarray(world.pack_geom, dtype=np.int64),
            pack_rgba=world.pack_rgba,
        )
        self.inactive_packs = 0
        self._count_down = bind(
            pick(backend, kernels.count_down_packs, kernels.count_down_packs_reference),
            self.packs,
        )
        self._cos_dock = math.cos(math.radians(config.dock_bearing_tolerance_deg))
        self._scan_kernel = pick(
            backend, kernels.teeth_on_electrodes, kernels.teeth_on_electrodes_reference
        )
        self._bind_scan(_INITIAL_CONTACTS)

    def _bind_scan(self, capacity: int) -> None:
        self._contacts = ContactScan(
            np.zeros((capacity, 2), dtype=np.int32),
            np.zeros(1, dtype=np.int64),
            np.zeros((capacity, 2), dtype=np.int64),
        )
        self._scan = bind(self._scan_kernel, self._contacts, self.tables, self.state, self.flags)

    def refresh_pack_positions(self) -> None:
        """Re-read pack positions after the world placed or moved packs."""
        self.pack_xy[:] = self.world.pack_positions()

    def reset_packs(self) -> None:
        """Every pack active (``World.reset`` restored their colours): no countdown runs."""
        self.packs.countdown[:] = 0
        self.inactive_packs = 0

    def load_pack_countdown(self, countdown: np.ndarray) -> None:
        """Take the packs' countdowns of a saved state: packs counting down are inactive
        (dark), the others active in their colour."""
        np.copyto(self.packs.countdown, countdown)
        active = self.packs.countdown == 0
        for j in np.flatnonzero(active != self.world.pack_active).tolist():
            self.world.set_pack_active(j, bool(active[j]))
        self.inactive_packs = int(np.count_nonzero(~active))

    def count_down(self) -> None:
        """End of a step, after its dockings: the inactive packs' countdowns (see
        :class:`PackAvailability`); those that run out are active again."""
        self.inactive_packs = self._count_down()

    def detect(self) -> None:
        """Dock every eligible robot whose teeth touch an electrode with the pack ahead."""
        geom = self.world.data.contact.geom
        n = len(geom)
        contacts = self._contacts
        if n > len(contacts.geom):
            self._bind_scan(2 * n)
            contacts = self._contacts
        contacts.geom[:n] = geom
        contacts.ncon[0] = n
        k = self._scan()
        if k:
            docked, active = self.state.docked, self.world.pack_active
            for i, j in contacts.pairs[:k].tolist():
                # A docking earlier in this loop may have made pack j inactive.
                if not docked[i] and active[j] and self.pack_ahead(i, j):
                    self.dock(i, j)

    def pack_ahead(self, i: int, j: int) -> bool:
        """Is pack ``j`` within the docking tolerance of robot ``i``'s heading?"""
        d = self.world.data
        b = self.world.chassis_body[i]
        xmat = d.xmat[b]
        rel_x = self.pack_xy[j, 0] - d.xpos[b, 0]
        rel_y = self.pack_xy[j, 1] - d.xpos[b, 1]
        forward = rel_x * xmat[0] + rel_y * xmat[3]
        dist = math.hypot(rel_x, rel_y)
        return bool(dist > 0.0 and forward >= self._cos_dock * dist)

    def dock(self, i: int, j: int) -> None:
        """Robot ``i`` captures pack ``j``: weld it where it stands, start recharging; with a
        reactivation time the pack goes inactive for the rest of this step and the next
        ``reactivation_steps`` steps."""
        m, d = self.world.model, self.world.data
        b = self.world.chassis_body[i]
        e = self.hold_eq[i]
        # Weld at the current pose: relpose = the world frame seen from the chassis frame.
        quat = d.xquat[b]
        conj = np.array([quat[0], -quat[1], -quat[2], -quat[3]])
        relpos = np.empty(3)
        mujoco.mju_rotVecQuat(relpos, -d.xpos[b], conj)
        m.eq_data[e, _WELD_RELPOS] = relpos
        m.eq_data[e, _WELD_RELQUAT] = conj
        d.eq_active[e] = 1
        state = self.state
        state.docked[i] = True
        self.dock_pack[i] = j
        state.recharge_steps[i] = 0
        self.events.record_dock(i, j)
        if self.reactivation_steps:
            if not self.packs.countdown[j]:
                self.inactive_packs += 1
            self.packs.countdown[j] = self.reactivation_steps + 1
            self.world.set_pack_active(j, False)

    def release(self, i: int, reflex_rng: np.random.Generator | None) -> None:
        """Undock robot ``i``; with a generator, start its rotation reflex (drawn from it)."""
        self.world.data.eq_active[self.hold_eq[i]] = 0
        state = self.state
        state.docked[i] = False
        self.dock_pack[i] = -1
        state.recharge_steps[i] = 0
        if reflex_rng is not None:
            self.start_reflex(i, reflex_rng)

    def start_reflex(self, i: int, rng: np.random.Generator) -> None:
        """Start robot ``i``'s rotation reflex: a random direction and length drawn from
        ``rng``, during which the world ignores its wheel commands (no-op if the reflex is
        switched off, ``reflex_max_steps = 0``)."""
        cfg = self.config
        if cfg.reflex_max_steps <= 0:
            return
        state = self.state
        state.reflex_steps_left[i] = rng.integers(cfg.reflex_min_steps, cfg.reflex_max_steps + 1)
        direction = 1.0 if rng.random() < 0.5 else -1.0  # +1 = counter-clockwise
        state.reflex_wheels[i] = (-direction * self.reflex_speed, direction * self.reflex_speed)


__all__ = ["Docking", "check_energy", "check_recharge_steps", "recharge_gain"]
