"""The watchdog: robots that are tipped over or stuck, found every control step, and the
experimenter's rescue (docs/design.md §9.35).

A robot is

- **tipped** while its uprightness (the chassis' z-axis · the world's z) is below
  ``survival.tip_uprightness`` (default 0.5: tilted past 60°);
- **stuck** once it has commanded motion (driving: the mean of its two wheel commands, or
  turning: half their difference, at least :data:`MOVING_COMMAND` in size) for
  ``survival.stuck_steps`` control steps in a row without getting ``survival.stuck_distance``
  from where that run of steps began or turning ``survival.stuck_turn`` from the heading it
  had there, while neither docked nor in its reflex, and while its robot runs an agent (an
  idle robot commands nothing). It stays stuck until it gets that far, turns that much or
  stops commanding motion. A robot held while it tries to turn on the spot is as stuck as one
  held while it drives: Fig. 6's EE seed 19 of the published model lost 700,000 control steps
  to two robots that each turned in place against the other.

The watchdog only observes: it reads poses, commands and flags and changes nothing, so a run
with it is the run without it. The **rescue** (``survival.rescue``, off by default: the paper's
robots were never helped) does what an experimenter would: after ``survival.rescue_after_steps``
control steps tipped or stuck, the robot is set upright at rest at the nearest free spot
(:func:`free_spot`), facing the way it faced; its energy and its agent are unchanged. The
spot's search draws nothing at random, so a rescued run stays a pure function of its seed.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.survival.config import SurvivalConfig
from cyber_rodent.survival.watchdog_kernels import (
    RESCUE_DUE,
    STUCK_ENDED,
    STUCK_STARTED,
    TIP_ENDED,
    TIP_STARTED,
    WatchInputs,
    WatchRules,
    WatchState,
    watch,
    watch_reference,
)
from cyber_rodent.world import World

#: m/s: the drive (mean wheel command) or turn (half their difference) command from which a
#: robot is taken to be trying to move.
MOVING_COMMAND = 0.05


class Trouble(enum.IntEnum):
    """What the watchdog found (the ``value`` of a rescue event)."""

    TIPPED = 1
    STUCK = 2


@dataclass
class WatchdogEvents:
    """What changed in one step, robot indices (rare; the lists are usually empty).

    Attributes:
        tip_started, stuck_started: robots that became tipped / stuck this step.
        tip_ended, stuck_ended: ``(robot, steps it lasted)`` of troubles that ended.
        rescued: ``(robot, Trouble)`` of robots the rescue moved this step.
    """

    tip_started: list[int] = field(default_factory=list)
    tip_ended: list[tuple[int, int]] = field(default_factory=list)
    stuck_started: list[int] = field(default_factory=list)
    stuck_ended: list[tuple[int, int]] = field(default_factory=list)
    rescued: list[tuple[int, Trouble]] = field(default_factory=list)

    @property
    def any(self) -> bool:
        return bool(self.tip_started or self.tip_ended or self.stuck_started
                    or self.stuck_ended or self.rescued)  # fmt: skip


class Watchdog:
    """Finds tipped and stuck robots of one world, step by step (see the module docstring).

    The per-step rule is :func:`cyber_rodent.survival.watchdog_kernels.watch` (compiled, or its
    numpy reference), bound once to the buffers it reads; events and rescues are handled in
    Python on the rare steps with a change.

    Args:
        world: the physical world.
        wheels: (n, 2) m/s, the buffer that holds each step's wheel commands.
        docked: (n,) bool, the survival world's docked flags.
        reflex_steps: (n,) int, the survival world's reflex steps still to run.
        active: (n,) bool, robots that run an agent (None: all, always).
        rules: the survival rules whose watchdog fields it applies (``tip_uprightness``,
            ``stuck_steps``, ``stuck_distance``, ``stuck_turn``, ``stuck_progress``, ``rescue``,
            ``rescue_after_steps``; ``control_dt``, the step the commanded travel is taken
            over); default: the paper's.
        backend: ``"numba"`` or ``"numpy"``.

    Attributes:
        state: the counters (:class:`~cyber_rodent.survival.watchdog_kernels.WatchState`).
    """

    def __init__(
        self,
        world: World,
        wheels: np.ndarray,
        docked: np.ndarray,
        reflex_steps: np.ndarray,
        active: np.ndarray | None = None,
        *,
        rules: SurvivalConfig | None = None,
        backend: Backend = DEFAULT_BACKEND,
    ) -> None:
        self.world = world
        n = world.config.n_robots
        r = rules or SurvivalConfig()
        self.rules = WatchRules(
            float(r.tip_uprightness), int(r.stuck_steps), float(r.stuck_distance) ** 2,
            math.cos(float(r.stuck_turn)), MOVING_COMMAND,
            int(r.rescue_after_steps) if r.rescue else 0, float(r.stuck_progress),
            float(r.control_dt), float(world.robot.half_wheel_base),
        )  # fmt: skip
        self.state = WatchState(
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64),
            np.zeros(n, dtype=np.int64), np.zeros((n, 2)), np.zeros((n, 2)),
            np.zeros((n, 2)), np.zeros((n, 2)),
            np.zeros((n, 2), dtype=np.int64), np.zeros(n, dtype=np.int64),
        )  # fmt: skip
        self.state.last[...] = world.data.xpos[world.chassis_body, :2]
        self.state.last_heading[...] = world.data.xmat[world.chassis_body][:, [0, 3]]
        if active is None:
            active = np.ones(n, dtype=bool)
        inputs = WatchInputs(
            world.data.xmat, world.data.xpos, np.asarray(world.chassis_body, dtype=np.int64),
            wheels, docked, reflex_steps, active,
        )  # fmt: skip
        kernel = pick(check_backend(backend), watch, watch_reference)
        self._watch = bind(kernel, self.rules, inputs, self.state)

    def observe(self) -> WatchdogEvents | None:
        """One control step, after the world's step: None if nothing changed, else what did
        (rescuing the robots that are due, if the rescue is on)."""
        if not self._watch():
            return None
        state, events = self.state, WatchdogEvents()
        change = state.change
        for robot in np.flatnonzero(change).tolist():
            bits = int(change[robot])
            if bits & TIP_ENDED:
                events.tip_ended.append((robot, int(state.ended[robot, 0])))
            if bits & STUCK_ENDED:
                events.stuck_ended.append((robot, int(state.ended[robot, 1])))
            if bits & TIP_STARTED:
                events.tip_started.append(robot)
            if bits & STUCK_STARTED:
                events.stuck_started.append(robot)
            if bits & RESCUE_DUE:
                self._rescue(robot, events)
        return events

    def _rescue(self, robot: int, events: WatchdogEvents) -> None:
        state, world = self.state, self.world
        trouble = Trouble.TIPPED if state.tipped_steps[robot] >= self.rules.rescue_after else (
            Trouble.STUCK)  # fmt: skip
        yaw = float(world.poses()[robot, 2])
        spot = free_spot(world, robot)
        world.set_robot_pose(robot, float(spot[0]), float(spot[1]), yaw)
        mujoco.mj_forward(world.model, world.data)
        if state.tipped_steps[robot]:
            events.tip_ended.append((robot, int(state.tipped_steps[robot])))
        if state.stuck_steps[robot]:
            events.stuck_ended.append((robot, int(state.stuck_steps[robot])))
        state.tipped_steps[robot] = state.stuck_steps[robot] = state.trying[robot] = 0
        state.anchor[robot] = state.last[robot] = spot
        heading = world.data.xmat[world.chassis_body[robot]][[0, 3]]
        state.anchor_heading[robot] = state.last_heading[robot] = heading
        events.rescued.append((robot, trouble))

    # --- checkpoint state ------------------------------------------------------------------
    _SAVED = (
        "tipped_steps", "stuck_steps", "trying", "anchor", "anchor_heading", "last",
        "last_heading",
    )  # fmt: skip

    def state_dict(self) -> dict[str, np.ndarray]:
        """The watchdog's counters (what a checkpoint stores)."""
        return {name: getattr(self.state, name).copy() for name in self._SAVED}

    def load_state(self, saved: dict[str, np.ndarray]) -> None:
        """Restore a :meth:`state_dict` in place.

        Raises:
            ValueError: an array of another shape.
        """
        world = self.world
        now = {
            "last": world.data.xpos[world.chassis_body, :2],
            "last_heading": world.data.xmat[world.chassis_body][:, [0, 3]],
        }
        for name in self._SAVED:
            if name not in saved:  # written before the rule read it: its count restarts there
                getattr(self.state, name)[...] = now.get(name, 0.0)
                continue
            target, value = getattr(self.state, name), np.asarray(saved[name])
            if value.shape != target.shape:
                raise ValueError(f"watchdog {name}: shape {value.shape}, expected {target.shape}")
            target[...] = value


def free_spot(world: World, robot: int, step: float = 0.05, rings: int = 60) -> np.ndarray:
    """The free spot nearest to ``robot``'s position where it can stand upright: inside its
    arena's walls, a robot's clearance from every other robot and pack. Searched on rings of
    ``step`` m around the robot (16 directions per ring, from its heading anticlockwise), the
    robot's own spot first; nothing is drawn at random.

    Raises:
        RuntimeError: no free spot within ``rings`` rings.
    """
    poses = world.poses()
    here = poses[robot, :2]
    others = np.delete(poses[:, :2], robot, axis=0)
    packs = world.pack_positions()
    centre, half = arena_bounds(world, robot)
    radius = world.robot.body_radius
    limit = half - radius
    robot_gap, pack_gap = 2 * radius, radius + C.PACK_RADIUS
    for ring in range(rings + 1):
        directions = 1 if ring == 0 else 16
        for k in range(directions):
            angle = poses[robot, 2] + 2 * math.pi * k / directions
            spot = here + ring * step * np.array([math.cos(angle), math.sin(angle)])
            if np.any(np.abs(spot - centre) > limit):
                continue
            if len(others) and np.min(np.hypot(*(others - spot).T)) < robot_gap:
                continue
            if len(packs) and np.min(np.hypot(*(packs - spot).T)) < pack_gap:
                continue
            return spot
    raise RuntimeError(f"no free spot for robot {robot} within {rings * step:.2f} m")


def arena_bounds(world: World, robot: int) -> tuple[np.ndarray, float]:
    """The centre (x, y) of ``robot``'s walled field and its half side, m."""
    half = world.config.field_size / 2.0
    return np.asarray(world.arena_centres[int(world.robot_arena[robot])], dtype=float), half


__all__ = ["MOVING_COMMAND", "Trouble", "Watchdog", "WatchdogEvents", "arena_bounds", "free_spot"]
