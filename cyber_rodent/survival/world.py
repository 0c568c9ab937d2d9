"""The survival world: a :class:`~cyber_rodent.world.World` with the survival mechanics.

:class:`SurvivalWorld` composes the package's concerns into the lean stepping path that the
evolution runner steps 1.2 million times per run: it computes no observations (no vision, no
copies of sensor data), keeps its state in preallocated numpy arrays and reports events in a
reused :class:`~cyber_rodent.survival.events.StepEvents`. One control step is

1. :meth:`SurvivalWorld.begin_step`: the recharge decisions (a "stop" undocks now), then
   :func:`~cyber_rodent.survival.kernels.begin` (motor commands, LEDs, mating signals);
2. :meth:`SurvivalWorld.advance_physics`: ``n_substeps`` MuJoCo steps;
3. :meth:`SurvivalWorld.end_step`: :func:`~cyber_rodent.survival.kernels.end` (energy,
   recharge stopping rules, deaths), the releases it asks for
   (:class:`~cyber_rodent.survival.energy.Docking`), captures, the inactive packs'
   countdowns (:func:`~cyber_rodent.survival.kernels.count_down_packs`, only while a pack is
   inactive) and mating (:class:`~cyber_rodent.survival.mating.Mating`).

The dm-control tasks (:mod:`cyber_rodent.tasks`) drive the same object through
:meth:`SurvivalWorld.begin_step` and :meth:`SurvivalWorld.end_step`, with dm-control stepping the
physics in between.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from typing import Any

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.backend import Backend, bind, check_backend, pick
from cyber_rodent.survival import kernels
from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.energy import (
    Docking,
    check_energy,
    check_recharge_steps,
    recharge_gain,
)
from cyber_rodent.survival.events import RechargeEnd, StepEvents
from cyber_rodent.survival.kernels import (
    Actuation,
    EnergyOutcome,
    StepCommands,
    StepFlags,
    SurvivalRules,
    SurvivalState,
)
from cyber_rodent.survival.mating import Mating
from cyber_rodent.vision import kernels as vision_kernels
from cyber_rodent.vision.geometric import culled_rangefinders
from cyber_rodent.world import LED_OFF_RGBA, LED_ON_RGBA, World, WorldConfig

_DSBL_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
#: The per-robot arrays of :meth:`SurvivalWorld.state` (all attributes of the world).
_STATE_ARRAYS = (*SurvivalState._fields, "dock_pack")


def _substeps(control_dt: float, timestep: float) -> int:
    n = round(control_dt / timestep)
    if n < 1 or abs(n * timestep - control_dt) > 1e-9 * max(1.0, control_dt):
        raise ValueError(
            f"control_dt must be a positive whole multiple of the physics timestep "
            f"({timestep} s), got {control_dt!r}"
        )
    return int(n)


def _check_wheels(wheels: np.ndarray, top: float) -> None:
    """Raise the error that names the problem if a wheel speed is NaN or outside the robot's
    top speed ``top`` (m/s)."""
    if not (-top <= wheels.min() and wheels.max() <= top):  # NaN fails too
        if not np.isfinite(wheels).all():
            raise ValueError("wheels must be finite wheel speeds in m/s (got NaN or inf)")
        raise ValueError(
            f"wheels must be in [-{top:g}, {top:g}] m/s (the motor limit), "
            f"got values from {wheels.min():.4g} to {wheels.max():.4g}"
        )


class SurvivalWorld:
    """A :class:`World` with the survival mechanics; the lean stepping path.

    Per-robot state lives in public numpy arrays (read them freely; write energy and recharge
    counters through :meth:`set_energy` and :meth:`set_recharge_steps`, which validate), so a
    time-sharing scheduler can swap the active agent's energy in and out of a robot. The arrays
    are never replaced, only written in place: other objects hold them.

    Args:
        world: the physical world, or a :class:`WorldConfig` to build one (default: 4 robots,
            5 packs).
        config: the survival rules.
        rng: generator for the placement and the reflexes; :meth:`reset` takes a new one.
        backend: ``"numba"`` runs the compiled per-step kernels, ``"numpy"`` their references
            (:mod:`cyber_rodent.survival.kernels`); both give bit-identical runs.

    Attributes:
        energy: (n,) float, virtual energy of each robot's active agent.
        recharge_steps: (n,) int, consecutive steps recharged in the current docking (0 when
            not docked).
        docked: (n,) bool, the robot is docked and recharging (held by its weld).
        dock_pack: (n,) int, the pack it is docked to, else -1.
        reflex_steps_left: (n,) int, steps of the post-recharge rotation reflex still to run.
        reflex_wheels: (n, 2) float, wheel speeds of the running reflex, m/s.
        alive: (n,) bool, energy above 0.
        pack_countdown: (n_packs,) int, control steps each pack stays inactive, the step in
            progress included (0: active; ``WorldConfig.pack_reactivation_steps``).
        rng: the generator of the reflexes (and of the placement at :meth:`reset`).
        step_count: control steps since the last reset.
        events: the :class:`StepEvents` of the last step (reused, see there).
        docking: captures, docking holds and reflexes (:class:`Docking`).
        mating: mating detection and its streaks (:class:`Mating`).
    """

    def __init__(
        self,
        world: World | WorldConfig | None = None,
        config: SurvivalConfig | None = None,
        rng: np.random.Generator | None = None,
        backend: Backend = "numba",
    ):
        self.backend = check_backend(backend)
        if world is None or isinstance(world, WorldConfig):
            world = World(world)
        self.world = world
        self.config = cfg = config if config is not None else SurvivalConfig()
        self.n_robots = n = world.config.n_robots
        self.n_packs = world.config.n_packs
        m = world.model
        self.n_substeps = _substeps(cfg.control_dt, float(m.opt.timestep))
        self.energy = np.zeros(n)
        self.recharge_steps = np.zeros(n, dtype=np.int64)
        self.docked = np.zeros(n, dtype=bool)
        self.dock_pack = np.full(n, -1, dtype=np.int64)
        self.reflex_steps_left = np.zeros(n, dtype=np.int64)
        self.reflex_wheels = np.zeros((n, 2))
        self.alive = np.ones(n, dtype=bool)
        self.step_count = 0
        self.events = StepEvents(n)
        #: ``capture_rule`` "recharge": a capture is a docking's first recharge step.
        self._capture_on_recharge = cfg.capture_rule == "recharge"
        #: ``mate_reflex``: both partners of an IR exchange turn away with the reflex.
        self._reflex_after_mating = cfg.mate_reflex
        self._state = SurvivalState(
            self.energy, self.recharge_steps, self.docked, self.alive, self.reflex_steps_left,
            self.reflex_wheels,
        )  # fmt: skip
        self._flags = StepFlags(
            np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        )
        self._outcome = EnergyOutcome(np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool))
        self._commands = StepCommands(
            np.zeros((n, 2)), np.zeros(n, dtype=bool), np.zeros(n, bool), np.zeros(n, bool)
        )
        self._actuation = Actuation(
            ctrl=self._wheel_controls(),
            led_on=world.led_on,
            geom_rgba=m.geom_rgba,
            led_geom=np.asarray(world.led_geom, dtype=np.int64),
            led_rgba=np.stack([LED_OFF_RGBA, LED_ON_RGBA]).astype(np.float64),
        )
        self._rules = SurvivalRules(
            inv_wheel_radius=1.0 / float(world.wheel_radius),
            top_speed=float(world.robot.top_speed),
            recharge_gain=float(recharge_gain(cfg)),
            max_energy=float(cfg.max_energy),
            max_recharge_steps=int(cfg.max_recharge_steps),
            energy_decay=float(cfg.energy_decay),
            mate_min_energy=float(cfg.mate_min_energy),
            max_steps_code=int(RechargeEnd.MAX_STEPS),
            full_code=int(RechargeEnd.FULL),
        )
        self.docking = Docking(
            world, cfg, self._state, self.dock_pack, self._flags, self.events, self.backend
        )
        self.pack_countdown = self.docking.packs.countdown
        self.mating = Mating(
            world, cfg, self._flags.mate_signal, self.alive, self.docked,
            self.events.mate_partner, self.backend,
        )  # fmt: skip
        self._floor_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.FLOOR_GEOM)
        self._begin_kernel = pick(self.backend, kernels.begin, kernels.begin_reference)
        end = pick(self.backend, kernels.end, kernels.end_reference)
        self._begin_own = self._begin = self._bind_begin(self._commands)
        #: The caller's command arrays that ``_begin`` reads directly (see :meth:`begin_step`).
        self._callers: tuple[np.ndarray, ...] = ()
        self._end = bind(end, self._state, self._rules, self._flags, self._outcome)
        #: In a world of many arenas, the rangefinders' rays through a grid of the geoms near
        #: them, after the physics (:meth:`advance_physics`); None: MuJoCo's sensor stage.
        self._ranges: Callable[[], None] | None = None
        finders = culled_rangefinders(world)
        if finders is not None:
            d = world.data
            poses = vision_kernels.MujocoPoses(
                d.site_xpos, d.site_xmat, d.geom_xpos, d.geom_xmat, m._address, d._address
            )
            ranges = pick(self.backend, vision_kernels.ranges, vision_kernels.ranges_reference)
            self._ranges = bind(ranges, poses, finders, d.sensordata)
        self._wheel_shape = (n, 2)
        self._flag_shape = (n,)
        self._mid_step = False
        self.reset(rng if rng is not None else np.random.default_rng(0))

    def _wheel_controls(self) -> np.ndarray:
        """The wheel motors' ctrl as an (n, 2) view of MjData.ctrl (left/right per robot)."""
        w, m = self.world, self.world.model
        motors = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, C.robot_prefix(i) + name)
            for i in range(self.n_robots)
            for name in (w.robot.parts.left_motor, w.robot.parts.right_motor)
        ]
        if motors != list(range(motors[0], motors[0] + len(motors))):
            raise RuntimeError("wheel motors are not contiguous in the compiled model")
        ctrl: np.ndarray = w.data.ctrl[motors[0] : motors[0] + len(motors)]
        return ctrl.reshape(self.n_robots, 2)

    # --- set-up (off the hot path) -----------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """New random placement (``World.reset``), every pack active, and newborn energy for
        every robot.

        ``rng`` is kept for the reflexes, so a run is a pure function of its generator.
        """
        self.rng = rng
        self.world.reset(rng)  # mj_resetData also switches every docking weld off
        self.docking.refresh_pack_positions()
        self.docking.reset_packs()
        self.energy[:] = self.config.initial_energy
        self.recharge_steps[:] = 0
        self.docked[:] = False
        self.dock_pack[:] = -1
        self.reflex_steps_left[:] = 0
        self.alive[:] = True
        self.mating.reset()
        self.step_count = 0
        self.events.any = True
        self.events.clear()
        self._mid_step = False

    def refresh_pack_positions(self) -> None:
        """Re-read pack positions after moving packs with ``World.set_pack_position``."""
        self.docking.refresh_pack_positions()

    # --- agent state (time sharing) ----------------------------------------------------------
    def set_energy(self, robot: int, energy: float) -> None:
        """Load an agent's energy into ``robot``; energy > 0 also revives a dead robot.

        Raises:
            ValueError: if ``energy`` is not in [0, max_energy].
        """
        e = check_energy(energy, self.config)
        self.energy[robot] = e
        self.alive[robot] = e > 0.0

    def set_recharge_steps(self, robot: int, steps: int) -> None:
        """Set the consecutive-recharge counter of a docked robot (agent switch while docked).

        Raises:
            ValueError: if ``steps`` is not in [0, max_recharge_steps).
        """
        self.recharge_steps[robot] = check_recharge_steps(steps, self.config)

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
        continue_recharge: np.ndarray,
    ) -> StepEvents:
        """One control step: commands, ``n_substeps`` physics steps, then the mechanics.

        Args:
            wheels: (n, 2) left/right wheel rim speeds in m/s, within the robot's top speed
                (``world.robot.top_speed``). Ignored for robots that are docked, in their
                reflex, or dead.
            led: (n,) bool, green LED on.
            mate: (n,) bool, the robot's active agent runs Mate (signals willingness to mate).
            continue_recharge: (n,) bool, the recharge decision of docked robots (True =
                keep recharging); ignored for the others.

        Returns:
            The step's events (a reused object, see :class:`StepEvents`).

        Raises:
            ValueError: on NaN, infinite or out-of-range wheel speeds or wrong shapes.
        """
        self.begin_step(wheels, led, mate, continue_recharge)
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

        In a world of many arenas (``WorldConfig.arenas``) every substep runs without the
        sensor stage, and the rangefinders are then read from the last substep's poses, as
        MuJoCo's sensor stage reads them, by ``cyber_rodent.vision.kernels.ranges``, whose rays
        test only the geoms near them: the same readings, bit for bit
        (``tests/test_arenas.py``), while MuJoCo's scan of every geom of the colony for each
        ray cost each robot more as the colony grew.
        """
        m, d, n_sub = self.world.model, self.world.data, self.n_substeps
        if self._ranges is not None:
            opt = m.opt
            flags = opt.disableflags
            opt.disableflags = flags | _DSBL_SENSOR
            try:
                mujoco.mj_step(m, d, nstep=n_sub)
            finally:
                opt.disableflags = flags
            self._ranges()
            return
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
        continue_recharge: np.ndarray,
    ) -> None:
        """First half of :meth:`step`: apply decisions and commands (physics not stepped).

        A caller that passes the same arrays every step (the evolution runner) has them read
        in place; other arguments are checked and copied into the world's own buffers.
        """
        callers = self._callers
        if not (
            callers
            and wheels is callers[0]
            and led is callers[1]
            and mate is callers[2]
            and continue_recharge is callers[3]
        ):
            self._take_commands(wheels, led, mate, continue_recharge)
        events = self.events
        status = self._begin()
        if status == kernels.RELEASE_FIRST:
            # "Stop" ends a docked robot's recharge now, before this step.
            events.clear()
            stop = self.docked & ~self._begin_commands.continue_recharge
            for i in np.flatnonzero(stop).tolist():
                self._release(i, reflex=True)
                events.record_recharge_end(i, RechargeEnd.DECISION)
            status = self._begin()
        else:
            if status == kernels.BEGIN_OK:
                events.clear()
        if status != kernels.BEGIN_OK:  # nothing was written; raise the error that names it
            _check_wheels(self._begin_commands.wheels, self._rules.top_speed)
        self._mid_step = True

    def _bind_begin(self, commands: StepCommands) -> Callable[[], int]:
        self._begin_commands = commands
        return bind(
            self._begin_kernel, commands, self._state, self._actuation, self._rules, self._flags
        )

    def _take_commands(
        self,
        wheels: np.ndarray,
        led: np.ndarray,
        mate: np.ndarray,
        continue_recharge: np.ndarray,
    ) -> None:
        """Check the commands; read them in place if they are the world's kind of arrays,
        else copy them into the world's own buffers."""
        raw = (wheels, led, mate, continue_recharge)
        if type(wheels) is not np.ndarray or wheels.dtype != np.float64:
            wheels = np.asarray(wheels, dtype=np.float64)
        if wheels.shape != self._wheel_shape:
            raise ValueError(f"wheels must have shape {self._wheel_shape}, got {wheels.shape}")
        led = self._as_flags("led", led)
        mate = self._as_flags("mate", mate)
        continue_recharge = self._as_flags("continue_recharge", continue_recharge)
        if all(a is b for a, b in zip(raw, (wheels, led, mate, continue_recharge), strict=True)):
            # Arrays of the right kind: bind the kernel to them (once per set of arrays).
            self._begin = self._bind_begin(StepCommands(wheels, led, mate, continue_recharge))
            self._callers = raw
            return
        commands = self._commands
        np.copyto(commands.wheels, wheels)
        np.copyto(commands.led, led)
        np.copyto(commands.mate, mate)
        np.copyto(commands.continue_recharge, continue_recharge)
        self._begin = self._begin_own
        self._begin_commands = commands
        self._callers = ()

    def end_step(self) -> StepEvents:
        """Second half of :meth:`step`, after the physics has advanced: energy and events."""
        if not self._mid_step:
            raise RuntimeError("end_step() called without begin_step()")
        self._mid_step = False
        events = self.events
        n_stops, n_died = self._end()
        if self._capture_on_recharge:
            self._capture_first_recharge()
        if n_stops:
            reasons = self._outcome.stop_reason
            for i in np.flatnonzero(reasons).tolist():
                self._release(i, reflex=True)
                events.record_recharge_end(i, RechargeEnd(int(reasons[i])))
        if n_died:
            events.died |= self._outcome.died
            events.any = True
        if self.n_packs and self.world.data.ncon:
            self.docking.detect()
            if events.any and not self._capture_on_recharge:
                np.copyto(events.captured, events.docked)  # "docking": the docking is the capture
        if self.docking.inactive_packs:  # after the dockings, which may have started some
            self.docking.count_down()
        self.mating.after_step(events)
        if self._reflex_after_mating and events.any:
            for i in np.flatnonzero(events.mate_partner >= 0).tolist():
                self.docking.start_reflex(i, self.rng)
        self.step_count += 1
        return events

    def _capture_first_recharge(self) -> None:
        """``capture_rule`` "recharge": mark the robots whose recharge step just taken is
        their docking's first (before a stopping rule's release zeroes the counter)."""
        events = self.events
        captured = events.captured
        np.equal(self.recharge_steps, 1, out=captured)
        np.logical_and(captured, self._flags.recharging, out=captured)
        if captured.any():
            events.any = True

    def _release(self, robot: int, reflex: bool) -> None:
        self.docking.release(robot, self.rng if reflex else None)

    def _as_flags(self, name: str, value: np.ndarray) -> np.ndarray:
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

    # --- mating and contacts -----------------------------------------------------------------
    def ir_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """Pairwise IR-port geometry: (distance m, angle deg), both (n, n) (:class:`Mating`)."""
        return self.mating.ir_geometry()

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

    # --- run state (checkpoints) -------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Every piece of mutable Python-side state a resumed run needs, as plain data.

        Numpy arrays (copies), Python scalars and nested dicts of those: the per-robot arrays,
        the step count, the reflex generator's state, the mating streaks, the last step's
        events, the flags of a step in progress, the pack positions the captures test against,
        the packs' reactivation countdowns and the world's LED state. MuJoCo's model and data
        are not included: the checkpoint saves them separately (docs/design.md §10).
        """
        events = self.events
        return {
            **{name: getattr(self, name).copy() for name in _STATE_ARRAYS},
            "step_count": self.step_count,
            "rng": copy.deepcopy(self.rng.bit_generator.state),
            "mate_streak": self.mating.streak.copy(),
            "mate_streak_active": self.mating.streak_active,
            "events": {
                **{name: getattr(events, name).copy() for name in StepEvents.ARRAYS},
                "any": events.any,
            },
            "mid_step": self._mid_step,
            **{name: getattr(self._flags, name).copy() for name in StepFlags._fields},
            "pack_xy": self.docking.pack_xy.copy(),
            "pack_countdown": self.pack_countdown.copy(),
            "led_on": self.world.led_on.copy(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Write a :meth:`state` back, arrays in place (other objects hold views of them).

        Nothing is written unless all of ``state`` fits this world. A state written before
        ``StepEvents.captured`` existed, when every docking was a capture, gets ``captured``
        equal to its ``docked``; one written before packs could go inactive
        (``pack_countdown``) has every pack active. A pack counting down is made inactive
        (dark), the others active.

        Raises:
            ValueError: a key is missing or unknown, an array's shape or dtype differs, a
                scalar has the wrong type, a pack's countdown is longer than this world's
                reactivation time, or the generator state is of another generator.
        """
        template = self.state()
        state = _with_pack_countdown(_with_captured(state), self.n_packs)
        _check_state(state, template, "")
        countdown, steps = state["pack_countdown"], self.docking.reactivation_steps
        longest = steps + 1 if steps else 0  # a docking sets N + 1; no countdown without N
        if self.n_packs and not (0 <= countdown.min() and countdown.max() <= longest):
            raise ValueError(
                f"survival state['pack_countdown'] must be in [0, {longest}] (this world's "
                f"pack_reactivation_steps is {steps}), got values from {countdown.min()} to "
                f"{countdown.max()}"
            )
        probe = type(self.rng.bit_generator)(0)
        try:
            probe.state = copy.deepcopy(state["rng"])
        except (ValueError, TypeError, KeyError) as error:
            raise ValueError(f"survival state['rng'] is not a generator state: {error}") from None
        targets: dict[str, np.ndarray] = {
            **{name: getattr(self, name) for name in _STATE_ARRAYS},
            "mate_streak": self.mating.streak,
            **{name: getattr(self._flags, name) for name in StepFlags._fields},
            "pack_xy": self.docking.pack_xy,
            "led_on": self.world.led_on,
        }
        for name, target in targets.items():
            np.copyto(target, state[name])
        self.docking.load_pack_countdown(state["pack_countdown"])
        for name in StepEvents.ARRAYS:
            np.copyto(getattr(self.events, name), state["events"][name])
        self.events.any = bool(state["events"]["any"])
        self.step_count = int(state["step_count"])
        self.mating.streak_active = bool(state["mate_streak_active"])
        self._mid_step = bool(state["mid_step"])
        self.rng.bit_generator.state = copy.deepcopy(state["rng"])


def _with_captured(state: Any) -> Any:
    """``state`` with ``events['captured']`` (= ``events['docked']``) if it predates it."""
    events = state.get("events") if isinstance(state, Mapping) else None
    if not isinstance(events, Mapping) or "captured" in events:
        return state
    docked = events.get("docked")
    if not isinstance(docked, np.ndarray):
        return state  # _check_state names what is wrong
    return {**state, "events": {**events, "captured": docked.copy()}}


def _with_pack_countdown(state: Any, n_packs: int) -> Any:
    """``state`` with ``pack_countdown`` (every pack active) if it predates it."""
    if not isinstance(state, Mapping) or "pack_countdown" in state:
        return state
    return {**state, "pack_countdown": np.zeros(n_packs, dtype=np.int64)}


def _check_state(state: Any, template: Mapping[str, Any], where: str) -> None:
    """Raise ValueError if ``state`` does not have ``template``'s keys, shapes and types."""
    if not isinstance(state, Mapping):
        raise ValueError(f"survival state{where} must be a mapping, got {type(state).__name__}")
    missing = [k for k in template if k not in state]
    unknown = [k for k in state if k not in template]
    if missing or unknown:
        raise ValueError(
            f"survival state{where} does not fit this world: missing keys {missing}, "
            f"unknown keys {unknown}"
        )
    for key, expected in template.items():
        value = state[key]
        name = f"survival state{where}[{key!r}]"
        if key == "rng":
            kind = expected["bit_generator"]
            if not isinstance(value, Mapping) or value.get("bit_generator") != kind:
                raise ValueError(f"{name} must be the state of a {kind} generator")
        elif isinstance(expected, Mapping):
            _check_state(value, expected, f"{where}[{key!r}]")
        elif isinstance(expected, np.ndarray):
            if not isinstance(value, np.ndarray):
                raise ValueError(f"{name} must be a numpy array, got {type(value).__name__}")
            if value.shape != expected.shape or value.dtype != expected.dtype:
                raise ValueError(
                    f"{name} must be a {expected.dtype} array of shape {expected.shape}, "
                    f"got {value.dtype} {value.shape}"
                )
        elif isinstance(expected, bool):
            if not isinstance(value, bool | np.bool_):
                raise ValueError(f"{name} must be true or false, got {value!r}")
        elif isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ValueError(f"{name} must be an integer, got {value!r}")
