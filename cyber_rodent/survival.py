"""The survival world: virtual energy, docking and recharging, the LED, and IR mating.

This is the paper's survival setting (Elfwing et al., section 3.2 and Table 1; docs/design.md §5) as
mechanics of the simulated world, on top of :class:`cyber_rodent.world.World`:

* **Energy.** Each robot carries the virtual battery of its active agent: it starts at 100,
  is capped at 200 and drains 1 per control step; a step spent recharging adds 5 instead. We
  read "gains 5 per step" (docs/design.md §5) as the net change of a recharge step, because the
  paper's numbers fit that reading: 40 steps x 5 = 200, the maximum energy, exactly
  (``decay_while_recharging=True`` gives the other reading, +5 - 1). Energy 0 is death, which
  the world reports once; a dead robot stands still with its LED off until the caller loads
  the next agent's energy (:meth:`SurvivalWorld.set_energy`).
* **Docking.** A capture happens when MuJoCo reports a contact between a robot's charging
  teeth and a pack's electrode ring *and* the pack lies ahead of the robot within
  ``dock_bearing_tolerance_deg``. Brushing a pack with the side or back is not a capture (no
  teeth contact), and neither is catching the electrode ring with a corner of the teeth on an
  off-centre approach: that contact has the pack 16-24° off the heading (measured in
  ``tests/test_survival_physics.py``) and is refused until the robot, still pushing, pivots
  its teeth onto the pack.
  While recharging the robot is held in place by a weld of its chassis to the world, an
  equality constraint of the world model (``world.dock_hold_name``); its wheels are stopped.
  Packs are static and never used up.
* **Recharging.** Every step the caller's recharge decision (the evolved recharge controller)
  says continue or stop. Recharging ends on "stop", after ``max_recharge_steps`` (40)
  consecutive steps, or at full energy. Then the weld is released and the robot performs a
  short rotation reflex of random direction and length (seeded), which turns its teeth away
  from the pack so that it does not simply dock again (the paper's "random rotating motion").
* **LED.** Green on or dark, per robot, set by the caller every step; other robots see it
  through vision.
* **IR mating.** An exchange succeeds when both robots signal Mate and each one's IR port
  faces the other's within ``mate_angle_deg`` (±15°) at a port-to-port distance of at most
  ``mate_distance`` (0.35 m), for ``mate_consecutive_steps`` consecutive control steps. The
  world reports the pair; what is exchanged is the caller's business.

The class is the *lean path* that the evolution runner steps 1.2 million times per run: it
computes no observations (no vision, no copies of sensor data), keeps its state in
preallocated numpy arrays and reports events in a reused :class:`StepEvents`. The dm-control
tasks (:mod:`cyber_rodent.tasks`) drive the same object through :meth:`SurvivalWorld.begin_step`
and :meth:`SurvivalWorld.end_step`, with dm-control stepping the physics in between.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent import survival_kernel
from cyber_rodent.world import LED_OFF_RGBA, LED_ON_RGBA, World, WorldConfig, dock_hold_name

# Weld equality data layout (MuJoCo 3.x ``eq_data`` row): anchor (3), relative pose of body2 in
# body1's frame: position (3) then quaternion (4), torque scale (1).
_WELD_RELPOS = slice(3, 6)
_DSBL_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
_WELD_RELQUAT = slice(6, 10)


class RechargeEnd(IntEnum):
    """Why a recharge ended (``StepEvents.recharge_end_reason``)."""

    NONE = 0
    DECISION = 1  #: the recharge controller said stop
    MAX_STEPS = 2  #: ``max_recharge_steps`` consecutive steps reached
    FULL = 3  #: energy reached ``max_energy``


@dataclass(frozen=True)
class SurvivalConfig:
    """Every rule of the survival world, with the paper's defaults (Table 1, docs/design.md §5).

    Attributes:
        initial_energy: energy of a newborn agent (paper: 100).
        max_energy: energy cap (paper: 200).
        energy_decay: energy lost per control step when not recharging (paper: 1).
        recharge_rate: energy gained per recharge step (paper: 5).
        decay_while_recharging: also drain ``energy_decay`` on recharge steps (net +4 instead of
            +5). Off by default: 40 steps x 5 = 200 = ``max_energy`` is the paper's arithmetic.
        max_recharge_steps: consecutive recharge steps after which recharging ends (paper: 40).
        control_dt: seconds of simulated time per control step (docs/design.md §5: 0.1 s); must be a
            whole number of physics timesteps.
        reflex_min_steps: shortest post-recharge rotation reflex, control steps.
        reflex_max_steps: longest reflex; the length is drawn uniformly in [min, max]. At the
            default spin speed a step turns 0.375 rad, so 4..8 steps turn 86°..172°.
        reflex_wheel_speed: wheel rim speed of the reflex spin, m/s.
        dock_bearing_tolerance_deg: a teeth/electrode contact is a capture only if the pack's
            centre lies within this angle of the robot's heading. With 6 cm wide teeth and a
            9 cm electrode ring, 15° admits contacts with the pack's axis up to about 4.7 cm
            off the robot's centre line, and refuses the glancing contacts of a teeth corner
            further out (16-29°).
        mate_angle_deg: each IR port must face the other port within this angle (paper: about
            ±15°; docs/design.md §5).
        mate_distance: largest IR port-to-port distance for an exchange, m (docs/design.md
            §5: 0.35).
        mate_consecutive_steps: control steps the mating condition must hold (docs/design.md
            §5: 1).
    """

    initial_energy: float = 100.0
    max_energy: float = 200.0
    energy_decay: float = 1.0
    recharge_rate: float = 5.0
    decay_while_recharging: bool = False
    max_recharge_steps: int = 40
    control_dt: float = 0.1
    reflex_min_steps: int = 4
    reflex_max_steps: int = 8
    reflex_wheel_speed: float = 0.3
    dock_bearing_tolerance_deg: float = 15.0
    mate_angle_deg: float = 15.0
    mate_distance: float = 0.35
    mate_consecutive_steps: int = 1

    def __post_init__(self) -> None:
        def number(name: str, lo: float, hi: float, lo_open: bool = False) -> None:
            v = getattr(self, name)
            ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            ok = ok and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                left = "(" if lo_open else "["
                raise ValueError(f"{name} must be a number in {left}{lo}, {hi}], got {v!r}")

        def integer(name: str, lo: int, hi: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or not lo <= v <= hi:
                raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")

        number("initial_energy", 0.0, 1e9, lo_open=True)
        number("max_energy", 0.0, 1e9, lo_open=True)
        if self.max_energy < self.initial_energy:
            raise ValueError(
                f"max_energy must be >= initial_energy ({self.initial_energy}), "
                f"got {self.max_energy!r}"
            )
        number("energy_decay", 0.0, self.max_energy)
        number("recharge_rate", 0.0, self.max_energy)
        if not isinstance(self.decay_while_recharging, bool):
            raise ValueError(
                f"decay_while_recharging must be a bool, got {self.decay_while_recharging!r}"
            )
        integer("max_recharge_steps", 1, 1_000_000)
        number("control_dt", 0.0, 10.0, lo_open=True)
        integer("reflex_min_steps", 0, 1000)
        integer("reflex_max_steps", self.reflex_min_steps, 1000)
        number("reflex_wheel_speed", 0.0, C.TOP_SPEED, lo_open=True)
        number("dock_bearing_tolerance_deg", 0.0, 90.0, lo_open=True)
        number("mate_angle_deg", 0.0, 90.0, lo_open=True)
        number("mate_distance", 0.0, C.FIELD_SIZE * math.sqrt(2), lo_open=True)
        integer("mate_consecutive_steps", 1, 1_000_000)


class StepEvents:
    """What happened in one control step, per robot, in preallocated arrays.

    The lean path reuses one instance for every step (no per-step allocation): its arrays are
    overwritten by the next step, so call :meth:`copy` to keep them. ``any`` is False on the
    vast majority of steps, which lets a hot loop skip event handling with one test.

    Attributes:
        docked: (n,) bool, the robot captured a pack this step (it recharges from the next).
        dock_pack: (n,) int, index of the captured pack, -1 where ``docked`` is False.
        recharge_ended: (n,) bool, the robot's recharge ended this step.
        recharge_end_reason: (n,) int, a :class:`RechargeEnd` value (``NONE`` elsewhere).
        died: (n,) bool, the robot's energy reached 0 this step.
        mate_partner: (n,) int, the robot it exchanged genomes with this step, else -1.
        any: True if any of the above happened.
    """

    __slots__ = (
        "docked",
        "dock_pack",
        "recharge_ended",
        "recharge_end_reason",
        "died",
        "mate_partner",
        "any",
    )

    def __init__(self, n_robots: int):
        self.docked = np.zeros(n_robots, dtype=bool)
        self.dock_pack = np.full(n_robots, -1, dtype=np.int64)
        self.recharge_ended = np.zeros(n_robots, dtype=bool)
        self.recharge_end_reason = np.zeros(n_robots, dtype=np.int64)
        self.died = np.zeros(n_robots, dtype=bool)
        self.mate_partner = np.full(n_robots, -1, dtype=np.int64)
        self.any = False

    def clear(self) -> None:
        if self.any:
            self.docked[:] = False
            self.dock_pack[:] = -1
            self.recharge_ended[:] = False
            self.recharge_end_reason[:] = RechargeEnd.NONE
            self.died[:] = False
            self.mate_partner[:] = -1
            self.any = False

    def copy(self) -> StepEvents:
        other = StepEvents(len(self.docked))
        for name in self.__slots__[:-1]:
            np.copyto(getattr(other, name), getattr(self, name))
        other.any = self.any
        return other

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


def _substeps(control_dt: float, timestep: float) -> int:
    n = round(control_dt / timestep)
    if n < 1 or abs(n * timestep - control_dt) > 1e-9 * max(1.0, control_dt):
        raise ValueError(
            f"control_dt must be a positive whole multiple of the physics timestep "
            f"({timestep} s), got {control_dt!r}"
        )
    return int(n)


class SurvivalWorld:
    """A :class:`World` with the survival mechanics; the lean stepping path.

    Per-robot state lives in public numpy arrays (read them freely; write energy and recharge
    counters through :meth:`set_energy` and :meth:`set_recharge_steps`, which validate), so a
    time-sharing scheduler can swap the active agent's energy in and out of a robot.

    Args:
        world: the physical world, or a :class:`WorldConfig` to build one (default: 4 robots,
            5 packs).
        config: the survival rules.
        rng: generator for the placement and the reflexes; :meth:`reset` takes a new one.

    Attributes:
        energy: (n,) float, virtual energy of each robot's active agent.
        recharge_steps: (n,) int, consecutive steps recharged in the current docking (0 when
            not docked).
        docked: (n,) bool, the robot is docked and recharging (held by its weld).
        dock_pack: (n,) int, the pack it is docked to, else -1.
        reflex_steps_left: (n,) int, steps of the post-recharge rotation reflex still to run.
        alive: (n,) bool, energy above 0.
        rng: the generator of the reflexes (and of the placement at :meth:`reset`).
        step_count: control steps since the last reset.
        events: the :class:`StepEvents` of the last step (reused, see there).
    """

    def __init__(
        self,
        world: World | WorldConfig | None = None,
        config: SurvivalConfig | None = None,
        rng: np.random.Generator | None = None,
    ):
        if world is None or isinstance(world, WorldConfig):
            world = World(world)
        self.world = world
        self.config = config if config is not None else SurvivalConfig()
        self.n_robots = world.config.n_robots
        self.n_packs = world.config.n_packs
        m = world.model
        self.n_substeps = _substeps(self.config.control_dt, float(m.opt.timestep))
        self._index()
        n = self.n_robots
        self.energy = np.zeros(n)
        self.recharge_steps = np.zeros(n, dtype=np.int64)
        self.docked = np.zeros(n, dtype=bool)
        self.dock_pack = np.full(n, -1, dtype=np.int64)
        self.reflex_steps_left = np.zeros(n, dtype=np.int64)
        self.alive = np.ones(n, dtype=bool)
        self.step_count = 0
        self.events = StepEvents(n)
        # Scratch state of the step in progress (begin_step -> end_step).
        self._reflex_wheels = np.zeros((n, 2))
        self._wheels = np.zeros((n, 2))
        self._recharging = np.zeros(n, dtype=bool)
        self._in_reflex = np.zeros(n, dtype=bool)
        self._mate_signal = np.zeros(n, dtype=bool)
        self._led = np.zeros(n, dtype=bool)
        self._mate_streak = np.zeros((n, n), dtype=np.int64)
        self._streak_active = False
        self._scratch = np.zeros(n, dtype=bool)
        self._stop_reason = np.zeros(n, dtype=np.int64)
        self._died = np.zeros(n, dtype=bool)
        self._n_recharging = self._n_reflex = 0
        self._wheel_shape = (n, 2)
        self._flag_shape = (n,)
        self._mid_step = False
        self._cos_dock = math.cos(math.radians(self.config.dock_bearing_tolerance_deg))
        self._cos_mate = math.cos(math.radians(self.config.mate_angle_deg))
        self.reset(rng if rng is not None else np.random.default_rng(0))

    # --- set-up (off the hot path) -----------------------------------------------------------
    def _index(self) -> None:
        w, m = self.world, self.world.model
        hold = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, dock_hold_name(i))
            for i in range(self.n_robots)
        ]
        if min(hold) < 0:
            raise RuntimeError("the world model has no docking-hold welds (world.build_mjcf)")
        self._hold_eq = np.asarray(hold, dtype=np.int64)
        for i, e in enumerate(self._hold_eq):
            if m.eq_type[e] != mujoco.mjtEq.mjEQ_WELD or m.eq_obj1id[e] != w.chassis_body[i]:
                raise RuntimeError(f"{dock_hold_name(i)} is not a weld of robot {i}'s chassis")
        self._teeth_owner = np.full(m.ngeom, -1, dtype=np.int64)
        self._teeth_owner[w.teeth_geom] = np.arange(self.n_robots)
        self._electrode_owner = np.full(m.ngeom, -1, dtype=np.int64)
        self._electrode_owner[w.electrode_geom] = np.arange(self.n_packs)
        self._teeth_owner_list = self._teeth_owner.tolist()
        self._electrode_owner_list = self._electrode_owner.tolist()
        self._dock_code = np.zeros(m.ngeom, dtype=np.int8)  # teeth 1, electrode 2
        self._dock_code[w.teeth_geom] = 1
        self._dock_code[w.electrode_geom] = 2
        self._dock_pairs = np.zeros((64, 2), dtype=np.int64)  # the kernel's output, grown
        self._floor_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.FLOOR_GEOM)
        # The wheel motors' ctrl as an (n, 2) view (one slice: left/right per robot).
        motors = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, C.robot_prefix(i) + name)
            for i in range(self.n_robots)
            for name in (C.LEFT_MOTOR, C.RIGHT_MOTOR)
        ]
        if motors != list(range(motors[0], motors[0] + len(motors))):
            raise RuntimeError("wheel motors are not contiguous in the compiled model")
        self._ctrl = w.data.ctrl[motors[0] : motors[0] + len(motors)].reshape(self.n_robots, 2)
        self._inv_wheel_radius = 1.0 / w.wheel_radius
        self._geom_rgba = m.geom_rgba
        self._led_geom = w.led_geom.tolist()
        self._led_geom_array = np.asarray(w.led_geom, dtype=np.int64)
        self._ir_sites = w.ir_port_site
        self._pack_xy = np.zeros((self.n_packs, 2))

    def reset(self, rng: np.random.Generator) -> None:
        """New random placement (``World.reset``) and newborn energy for every robot.

        ``rng`` is kept for the reflexes, so a run is a pure function of its generator.
        """
        self.rng = rng
        self.world.reset(rng)  # mj_resetData also switches every docking weld off
        self._pack_xy[:] = self.world.pack_positions()
        self.energy[:] = self.config.initial_energy
        self.recharge_steps[:] = 0
        self.docked[:] = False
        self.dock_pack[:] = -1
        self.reflex_steps_left[:] = 0
        self.alive[:] = True
        self._mate_streak[:] = 0
        self._streak_active = False
        self.step_count = 0
        self.events.any = True
        self.events.clear()
        self._mid_step = False

    def refresh_pack_positions(self) -> None:
        """Re-read pack positions after moving packs with ``World.set_pack_position``."""
        self._pack_xy[:] = self.world.pack_positions()

    # --- agent state (time sharing) ----------------------------------------------------------
    def set_energy(self, robot: int, energy: float) -> None:
        """Load an agent's energy into ``robot``; energy > 0 also revives a dead robot.

        Raises:
            ValueError: if ``energy`` is not in [0, max_energy].
        """
        e = float(energy)
        if not 0.0 <= e <= self.config.max_energy:
            raise ValueError(f"energy must be in [0, {self.config.max_energy}], got {energy!r}")
        self.energy[robot] = e
        self.alive[robot] = e > 0.0

    def set_recharge_steps(self, robot: int, steps: int) -> None:
        """Set the consecutive-recharge counter of a docked robot (agent switch while docked).

        Raises:
            ValueError: if ``steps`` is not in [0, max_recharge_steps).
        """
        if not 0 <= int(steps) < self.config.max_recharge_steps:
            raise ValueError(
                f"recharge steps must be in [0, {self.config.max_recharge_steps}), got {steps!r}"
            )
        self.recharge_steps[robot] = int(steps)

    def end_recharge(self, robot: int, reflex: bool = True) -> None:
        """Undock ``robot`` at the caller's request (no event), optionally with the reflex."""
        if self.docked[robot]:
            self._release(robot, reflex)

    # --- stepping ----------------------------------------------------------------------------
    def step(
        self,
        wheels: np.ndarray,
        led: np.ndarray,
        mate: np.ndarray,
        recharge_continue: np.ndarray,
    ) -> StepEvents:
        """One control step: commands, ``n_substeps`` physics steps, then the mechanics.

        Args:
            wheels: (n, 2) left/right wheel rim speeds in m/s, within ±``TOP_SPEED``. Ignored
                for robots that are docked, in their reflex, or dead.
            led: (n,) bool, green LED on.
            mate: (n,) bool, the robot's active agent runs Mate (signals willingness to mate).
            recharge_continue: (n,) bool, the recharge decision of docked robots (True =
                keep recharging); ignored for the others.

        Returns:
            The step's events (a reused object, see :class:`StepEvents`).

        Raises:
            ValueError: on NaN, infinite or out-of-range wheel speeds or wrong shapes.
        """
        self.begin_step(wheels, led, mate, recharge_continue)
        self.advance_physics()
        return self.end_step()

    def advance_physics(self) -> None:
        """The control step's ``n_substeps`` physics steps, with sensors evaluated only once.

        The world's sensors are its 32 rangefinders (rays), read once per control step, after
        the physics; evaluated in every substep they were 30 % of ``mj_step``'s cost. They do
        not act on the dynamics, so the first ``n_substeps - 1`` steps run with MuJoCo's
        sensor stage disabled and the last one with it enabled (as configured): the trajectory
        and ``sensordata`` are bit-identical to ``mj_step(nstep=n_substeps)``
        (``tests/test_survival_sensor_deferral.py`` checks both).
        """
        m, d, n_sub = self.world.model, self.world.data, self.n_substeps
        if n_sub > 1:
            opt = m.opt
            flags = opt.disableflags
            opt.disableflags = flags | _DSBL_SENSOR
            try:
                mujoco.mj_step(m, d, nstep=n_sub - 1)
            finally:
                opt.disableflags = flags
            mujoco.mj_step(m, d)
        else:
            mujoco.mj_step(m, d, nstep=n_sub)

    def begin_step(
        self,
        wheels: np.ndarray,
        led: np.ndarray,
        mate: np.ndarray,
        recharge_continue: np.ndarray,
    ) -> None:
        """First half of :meth:`step`: apply decisions and commands (physics not stepped)."""
        if type(wheels) is not np.ndarray or wheels.dtype != np.float64:
            wheels = np.asarray(wheels, dtype=np.float64)
        if wheels.shape != self._wheel_shape:
            raise ValueError(f"wheels must have shape {self._wheel_shape}, got {wheels.shape}")
        led = self._flags("led", led)
        mate = self._flags("mate", mate)
        recharge_continue = self._flags("recharge_continue", recharge_continue)
        # Recharge decisions of docked robots: "stop" ends the recharge now, before this step.
        # An invalid command must change nothing: the numpy path, and a step that undocks
        # robots, validate first; otherwise the kernel validates before it writes anything.
        stop = self.docked & ~recharge_continue
        checked = bool(stop.any()) or not survival_kernel.AVAILABLE
        if checked:
            self._check_wheels(wheels)
            self.events.clear()
            for i in np.flatnonzero(stop).tolist():
                self._release(i, reflex=True)
                self._record_end(i, RechargeEnd.DECISION)
        if not survival_kernel.AVAILABLE:
            self._begin_numpy(wheels, led, mate)
        else:
            valid, self._n_recharging, self._n_reflex = survival_kernel.begin(
                wheels, led, mate, self.docked, self.alive, self.reflex_steps_left,
                self._reflex_wheels, self._inv_wheel_radius, C.TOP_SPEED, self.world.led_on,
                self._geom_rgba, self._led_geom_array, LED_ON_RGBA, LED_OFF_RGBA, self._ctrl,
                self._recharging, self._in_reflex, self._mate_signal,
            )  # fmt: skip
            if not valid:  # nothing was written; raise the error that names the problem
                self._check_wheels(wheels)
            if not checked:
                self.events.clear()
        self._mid_step = True

    def _check_wheels(self, wheels: np.ndarray) -> None:
        """Raise the error that names the problem if a wheel speed is NaN or out of range."""
        if not (-C.TOP_SPEED <= wheels.min() and wheels.max() <= C.TOP_SPEED):  # NaN fails too
            if not np.isfinite(wheels).all():
                raise ValueError("wheels must be finite wheel speeds in m/s (got NaN or inf)")
            raise ValueError(
                f"wheels must be in [-{C.TOP_SPEED}, {C.TOP_SPEED}] m/s (the motor limit), "
                f"got values from {wheels.min():.4g} to {wheels.max():.4g}"
            )

    def _begin_numpy(self, wheels: np.ndarray, led: np.ndarray, mate: np.ndarray) -> None:
        """:meth:`begin_step` after the recharge decisions, in numpy: the reference of
        ``survival_kernel.begin``."""
        # A handful of numpy calls on (n,) arrays. Rare states (docked, reflex, dead) are
        # counted with count_nonzero (cheap) and handled only when present.
        count = np.count_nonzero
        np.copyto(self._recharging, self.docked)
        np.greater(self.reflex_steps_left, 0, out=self._in_reflex)
        self._n_recharging = count(self._recharging)
        self._n_reflex = count(self._in_reflex)
        n_dead = self.n_robots - count(self.alive)

        # Motor commands: docked and dead robots stand still, reflexes override the caller.
        if self._n_recharging or self._n_reflex or n_dead:
            np.copyto(self._wheels, wheels)
            self._wheels[self._recharging] = 0.0
            self._wheels[~self.alive] = 0.0
            self._wheels[self._in_reflex] = self._reflex_wheels[self._in_reflex]
            wheels = self._wheels
        np.multiply(wheels, self._inv_wheel_radius, out=self._ctrl)

        if n_dead:
            np.logical_and(led, self.alive, out=self._led)
            led = self._led
        if count(np.not_equal(led, self.world.led_on, out=self._scratch)):
            # What World.set_led does, for the changed LEDs only (a quarter of its cost).
            for i in np.flatnonzero(self._scratch).tolist():
                on = bool(led[i])
                self.world.led_on[i] = on
                self._geom_rgba[self._led_geom[i]] = LED_ON_RGBA if on else LED_OFF_RGBA
        # Only free, living robots take part in a mating handshake.
        np.logical_and(mate, self.alive, out=self._mate_signal)
        if self._n_recharging or self._n_reflex:
            self._mate_signal &= ~self._recharging
            self._mate_signal &= ~self._in_reflex

    def end_step(self) -> StepEvents:
        """Second half of :meth:`step`, after the physics has advanced: energy and events."""
        if not self._mid_step:
            raise RuntimeError("end_step() called without begin_step()")
        self._mid_step = False
        cfg = self.config
        ev = self.events
        count = np.count_nonzero
        if survival_kernel.AVAILABLE:
            gain = cfg.recharge_rate - (cfg.energy_decay if cfg.decay_while_recharging else 0.0)
            n_stops, n_died = survival_kernel.end(
                self._in_reflex, self.reflex_steps_left, self._recharging, self.energy,
                self.recharge_steps, self.alive, gain, cfg.max_energy, cfg.max_recharge_steps,
                cfg.energy_decay, int(RechargeEnd.MAX_STEPS), int(RechargeEnd.FULL),
                self._stop_reason, self._died,
            )  # fmt: skip
            if n_stops:
                for i in np.flatnonzero(self._stop_reason).tolist():
                    self._release(i, reflex=True)
                    self._record_end(i, RechargeEnd(int(self._stop_reason[i])))
            if n_died:
                ev.died |= self._died
                ev.any = True
            self._after_energy()
            return ev
        if self._n_reflex:
            np.subtract(self.reflex_steps_left, self._in_reflex, out=self.reflex_steps_left)

        # Energy of recharging robots, then the recharge stopping rules.
        rech = self._recharging
        if self._n_recharging:
            gain = cfg.recharge_rate - (cfg.energy_decay if cfg.decay_while_recharging else 0.0)
            self.energy[rech] = np.minimum(self.energy[rech] + gain, cfg.max_energy)
            self.recharge_steps[rech] += 1
            for i in np.flatnonzero(rech).tolist():
                if self.recharge_steps[i] >= cfg.max_recharge_steps:
                    reason = RechargeEnd.MAX_STEPS
                elif self.energy[i] >= cfg.max_energy:
                    reason = RechargeEnd.FULL
                else:
                    continue
                self._release(i, reflex=True)
                self._record_end(i, reason)

        # Everyone else pays the step; energy 0 is death.
        if self._n_recharging or count(self.alive) < self.n_robots:
            free = self.alive & ~rech
            self.energy[free] -= cfg.energy_decay
            died = free & (self.energy <= 0.0)
        else:
            self.energy -= cfg.energy_decay
            died = self.energy <= 0.0
        if count(died):
            self.energy[died] = 0.0
            self.alive[died] = False
            ev.died |= died
            ev.any = True
        self._after_energy()
        return ev

    def _after_energy(self) -> None:
        """The end of :meth:`end_step`: captures, mating, the step count."""
        if self.n_packs and self.world.data.ncon:
            self._detect_docking()
        if np.count_nonzero(self._mate_signal) >= 2:
            self._detect_mating()
        elif self._streak_active:
            self._mate_streak[:] = 0
            self._streak_active = False
        self.step_count += 1

    def _flags(self, name: str, value: np.ndarray) -> np.ndarray:
        if type(value) is np.ndarray and value.dtype == bool and value.shape == self._flag_shape:
            return value
        arr = np.asarray(value)
        if arr.shape != self._flag_shape:
            raise ValueError(f"{name} must have shape {self._flag_shape}, got {arr.shape}")
        if arr.dtype != bool:
            if arr.dtype.kind == "f" and not np.isfinite(arr).all():
                raise ValueError(f"{name} must be booleans (got NaN or inf)")
            arr = arr.astype(bool)
        return arr

    # --- docking -----------------------------------------------------------------------------
    def _detect_docking(self) -> None:
        # One lookup finds teeth/electrode contacts among all contacts: teeth geoms have bit 1,
        # electrodes bit 2, so a pair ORs to 3 exactly when it is teeth on electrode.
        geom = self.world.data.contact.geom
        if survival_kernel.AVAILABLE:
            pairs = self._dock_pairs
            if len(pairs) < len(geom):
                pairs = self._dock_pairs = np.zeros((2 * len(geom), 2), dtype=np.int64)
            k = survival_kernel.teeth_on_electrodes(
                geom, self._dock_code, self._teeth_owner, self._electrode_owner, self.alive,
                self.docked, self._in_reflex, self.reflex_steps_left, pairs,
            )  # fmt: skip
            for i, j in pairs[:k].tolist():
                if not self.docked[i] and self._pack_ahead(i, j):
                    self._dock(i, j)
            return
        code = self._dock_code[geom]
        pair = np.bitwise_or(code[:, 0], code[:, 1])
        hits = np.flatnonzero(pair == 3)
        if not len(hits):
            return
        teeth_owner, electrode_owner = self._teeth_owner_list, self._electrode_owner_list
        for g1, g2 in geom[hits].tolist():
            i = teeth_owner[g1]
            if i >= 0:
                j = electrode_owner[g2]
            else:
                i, j = teeth_owner[g2], electrode_owner[g1]
            free = self.alive[i] and not self.docked[i] and not self._in_reflex[i]
            if free and self.reflex_steps_left[i] == 0 and self._pack_ahead(i, j):
                self._dock(i, j)

    def _pack_ahead(self, i: int, j: int) -> bool:
        """Is pack ``j`` within the docking tolerance of robot ``i``'s heading?"""
        d = self.world.data
        b = self.world.chassis_body[i]
        xmat = d.xmat[b]
        rel_x = self._pack_xy[j, 0] - d.xpos[b, 0]
        rel_y = self._pack_xy[j, 1] - d.xpos[b, 1]
        forward = rel_x * xmat[0] + rel_y * xmat[3]
        dist = math.hypot(rel_x, rel_y)
        return dist > 0.0 and forward >= self._cos_dock * dist

    def _dock(self, i: int, j: int) -> None:
        m, d = self.world.model, self.world.data
        b = self.world.chassis_body[i]
        e = self._hold_eq[i]
        # Weld at the current pose: relpose = the world frame seen from the chassis frame.
        quat = d.xquat[b]
        conj = np.array([quat[0], -quat[1], -quat[2], -quat[3]])
        relpos = np.empty(3)
        mujoco.mju_rotVecQuat(relpos, -d.xpos[b], conj)
        m.eq_data[e, _WELD_RELPOS] = relpos
        m.eq_data[e, _WELD_RELQUAT] = conj
        d.eq_active[e] = 1
        self.docked[i] = True
        self.dock_pack[i] = j
        self.recharge_steps[i] = 0
        self.events.docked[i] = True
        self.events.dock_pack[i] = j
        self.events.any = True

    def _release(self, i: int, reflex: bool) -> None:
        self.world.data.eq_active[self._hold_eq[i]] = 0
        self.docked[i] = False
        self.dock_pack[i] = -1
        self.recharge_steps[i] = 0
        if reflex and self.config.reflex_max_steps > 0:
            cfg = self.config
            self.reflex_steps_left[i] = self.rng.integers(
                cfg.reflex_min_steps, cfg.reflex_max_steps + 1
            )
            direction = 1.0 if self.rng.random() < 0.5 else -1.0  # +1 = counter-clockwise
            self._reflex_wheels[i] = (
                -direction * cfg.reflex_wheel_speed,
                direction * cfg.reflex_wheel_speed,
            )

    def _record_end(self, i: int, reason: RechargeEnd) -> None:
        self.events.recharge_ended[i] = True
        self.events.recharge_end_reason[i] = reason
        self.events.any = True

    # --- mating ------------------------------------------------------------------------------
    def ir_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """Pairwise IR-port geometry: (distance m, angle deg), both (n, n).

        ``angle[i, j]`` is the angle between robot ``i``'s IR port direction and the line from
        its port to robot ``j``'s port; the diagonal is undefined (distance 0, angle 0).
        """
        dist, cos = self._ir_pairs()
        with np.errstate(invalid="ignore"):
            angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        np.fill_diagonal(angle, 0.0)
        return dist, angle

    def _ir_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        d = self.world.data
        sites = self.world.ir_port_site
        pos = d.site_xpos[sites]
        axis = d.site_xmat[sites][:, 2::3]  # the site's z axis: where the port points
        diff = pos[None, :, :] - pos[:, None, :]  # diff[i, j] = p_j - p_i
        dist = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        proj = np.einsum("ik,ijk->ij", axis, diff)
        np.fill_diagonal(dist, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.where(dist > 0.0, proj / np.where(dist > 0.0, dist, 1.0), 1.0)
        return dist, cos

    def _detect_mating(self) -> None:
        # Plain Python over the signalling pairs: with a few robots this is several times
        # cheaper than the (n, n) numpy version (ir_geometry), and it runs every step.
        cfg = self.config
        sig = self._mate_signal & self.alive & ~self.docked
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
        streak = self._mate_streak
        previous = {(a, b): int(streak[a, b]) for _, a, b in facing}
        if self._streak_active:
            streak[:] = 0
        for (a, b), k in previous.items():
            streak[a, b] = streak[b, a] = k + 1
        self._streak_active = bool(facing)
        ready = sorted(p for p in facing if streak[p[1], p[2]] >= cfg.mate_consecutive_steps)
        # A robot exchanges with one partner per step: nearest pairs first (deterministic).
        ev = self.events
        for _, a, b in ready:
            if ev.mate_partner[a] < 0 and ev.mate_partner[b] < 0:
                ev.mate_partner[a] = b
                ev.mate_partner[b] = a
                streak[a, b] = streak[b, a] = 0
                ev.any = True

    # --- contacts ------------------------------------------------------------------------------
    def collisions(self, out: np.ndarray | None = None) -> np.ndarray:
        """(n,) bool: the robot's body touches a wall, a pack or another robot right now.

        Floor contacts (wheels, casters) do not count; a docked robot's teeth on its pack do.
        """
        if out is None:
            out = np.zeros(self.n_robots, dtype=bool)
        else:
            out[:] = False
        d = self.world.data
        if d.ncon == 0:
            return out
        geom = d.contact.geom
        owner = self.world.geom_robot[geom]
        floor = geom == self._floor_geom
        for side, other in ((0, 1), (1, 0)):
            mask = (owner[:, side] >= 0) & ~floor[:, other] & (owner[:, other] != owner[:, side])
            out[owner[mask, side]] = True
        return out
