"""``cyber-rodent view``: watch a run, a checkpoint or a task live in MuJoCo's viewer.

What it shows, chosen by exactly one of:

* ``RUN_DIR``: a run directory's newest checkpoint, continued with the behaviour policies the
  run recorded, as ``cyber-rodent resume`` and ``render`` load it. The steps happen in memory
  only; nothing is written to the directory.
* ``--checkpoint FILE``: that checkpoint (with the policies of its run directory if it lies in
  one, else the shipped trained behaviours).
* ``--task NAME``: a dm-control task (:func:`cyber_rodent.tasks.load` with ``--seed``), its
  controlled robots driven by the shipped learned behaviours: in ``forage``, ``mate`` and
  ``search`` they run that behaviour (both robots in ``mate``); in ``survival``, and in any
  other registered task (:func:`check_task`: the names come from the task registry, so a task
  a program registered opens too), each robot picks one by a fixed rule,
  :func:`survival_choice`, since no evolved controller comes with a task. A finished episode
  starts the next one.

The simulation advances in whole control steps (``survival.control_dt`` of simulated time each,
0.2 s by default), paced to the wall clock times ``--speed`` (:class:`Pacer`; after a stall,
when the machine or the window held the loop up, it carries on from there rather than
fast-forwarding to make up the lost time). The window shows a mirror of the live world, its own
copy of the model and data updated after every control step; between steps the mirror moves the
bodies along the way from the previous step's poses to the new ones, so that robots glide
instead of jumping five times a second. The mirror also keeps the viewer's panels and mouse from
changing the simulation: a run continues exactly as ``resume`` would.

Each robot carries a label (``CR1 Forage 123``: robot, active behaviour, energy) and, under its
text, an energy bar in its behaviour's colour (the colours of ``cyber-rodent render``), laid out
in window pixels so that neither covers the other at any zoom or camera angle, nor another
robot's (:func:`decorate`). The top-left panel shows the source, the simulated time and the
speed; the top-right one lists the robots (behaviour, energy and, in a run, the active agent and
its generation); the bottom-left one the keys.

Keys, besides the viewer's own (left drag turns, right drag pans, scroll zooms, Tab and
Shift+Tab show the left and right panels, F1 help, Esc free camera):

=========  ====================================================
Space      pause / resume
→ (right)  pause and advance one control step
``-``      half speed (down to 0.01x)
``=``      double speed (up to 100x)
=========  ====================================================

The window needs an X display (``DISPLAY``; ``xvfb-run`` gives a virtual one). ``--screenshot``
reads the window back from the X server (:mod:`evolution.lab.window_capture`).
"""

from __future__ import annotations

import argparse
import copy
import math
import queue
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np

from cyber_rodent.constants import FIELD_SIZE
from cyber_rodent.tasks.spec import task_names
from evolution.checkpoint import CheckpointError, read_header
from evolution.lab.api import CHECKPOINT_DIR, RUN_FILE, policies_by_name
from evolution.lab.experiment import policies_for_identity, read_run_record
from evolution.lab.video import BEHAVIOUR_STYLE
from evolution.lab.window_capture import CaptureError, capture_own_window, display_problem
from evolution.runner import EvolutionRunner, latest_checkpoint, policy_identity

if TYPE_CHECKING:
    from behaviours import BehaviourInputs, BehaviourPolicies
    from cyber_rodent.survival import SurvivalWorld
    from cyber_rodent.world import World
    from evolution.runner import EvolutionRunner

EXIT_USAGE = 2
EXIT_FAILED = 1
MIN_SPEED = 0.01
MAX_SPEED = 100.0
#: GLFW key codes (what MuJoCo's viewer hands to the key callback).
KEY_SPACE, KEY_RIGHT, KEY_MINUS, KEY_EQUAL = 32, 262, 45, 61
KEY_KP_SUBTRACT, KEY_KP_ADD = 333, 334
#: Behaviour index of a docked robot (recharging, no behaviour), as in ``evolution.lab.video``.
RECHARGING = -1
#: Survival task rule: a robot below this share of ``max_energy`` is hungry.
HUNGRY = 0.5
FRAME_PERIOD = 1.0 / 60.0
#: Wall time per frame that may go to control steps; beyond it the viewer runs slower than
#: ``--speed`` rather than stall.
STEP_BUDGET = 0.75 * FRAME_PERIOD
#: The most wall time one frame counts towards the simulation. A longer gap between frames is a
#: stall (the process was held up, the window dragged, a slow step): the clock is re-anchored
#: and the time lost is not caught up. Frames slower than this (under 10 per second) run the
#: simulation slower than ``--speed``.
MAX_FRAME_GAP = 0.1
LAUNCH_TIMEOUT = 60.0
#: Wall time given to the viewer's thread to draw the last state before a screenshot.
SETTLE = 0.4
PARKED_STYLE = ("Parked", (150, 150, 150))
DEAD_STYLE = ("Dead", (120, 40, 40))


class ViewerError(ValueError):
    """Bad input: printed as one line, exit status 2."""


class ViewerFailed(RuntimeError):
    """The viewer could not run (no window, no screenshot): one line, exit status 1."""


def __getattr__(name: str) -> str:
    if name == "TASK_HELP_NAMES":  # the registered tasks' names, as ``--help`` lists them
        return ", ".join(task_names())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def check_task(name: object) -> str:
    """``--task``'s value as a registered task's name (lower case): a built-in task or one a
    program registered (:func:`cyber_rodent.tasks.register`).

    Raises:
        ViewerError: no task of that name (the message lists the registered ones).
    """
    task = str(name).lower()
    if task not in task_names():
        raise ViewerError(f"--task must be one of {', '.join(task_names())}; got {name!r}")
    return task


# --- the camera -----------------------------------------------------------------------------------
class CameraView(NamedTuple):
    """A MuJoCo free camera: where it looks, from how far and from which direction (degrees)."""

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float

    def project(self, points: np.ndarray, width: int, height: int, fovy: float) -> np.ndarray:
        """Window pixels (x right, y down) of world ``points`` (n, 3) in a ``width`` x
        ``height`` scene viewport with vertical field of view ``fovy`` (degrees): MuJoCo's free
        camera geometry (``mjv_updateCamera``). For placing checks on a screenshot."""
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        up = np.array([-math.sin(el) * math.cos(az), -math.sin(el) * math.sin(az), math.cos(el)])
        right = np.cross(forward, up)
        eye = np.asarray(self.lookat) - self.distance * forward
        rel = np.asarray(points, dtype=np.float64).reshape(-1, 3) - eye
        depth = rel @ forward
        focal = 0.5 * height / math.tan(math.radians(fovy) / 2)
        x = 0.5 * width + focal * (rel @ right) / depth
        y = 0.5 * height - focal * (rel @ up) / depth
        return np.column_stack([x, y])


#: The opening view: the whole field from the south, 60 degrees down.
OVERVIEW = CameraView(lookat=(0.0, 0.0, 0.0), distance=3.6, azimuth=90.0, elevation=-60.0)


def overview(world: World) -> CameraView:
    """The opening view of ``world``: :data:`OVERVIEW` for the paper's 2.3 m field, farther back
    in proportion for a larger field or several arenas (``WorldConfig.extent``), so that all of
    it is in view."""
    scale = max(1.0, world.config.extent / FIELD_SIZE)
    return OVERVIEW._replace(distance=OVERVIEW.distance * scale)


# --- what each robot shows ------------------------------------------------------------------------
class RobotStatus(NamedTuple):
    """One robot's label and panel line."""

    name: str
    behaviour: str
    colour: tuple[int, int, int]
    energy: float
    detail: str = ""


def _behaviour_style(index: int) -> tuple[str, tuple[int, int, int]]:

    return BEHAVIOUR_STYLE[index]


def _robot_name(i: int) -> str:
    """0-based, as in videos, snapshots and ``chase:N``."""
    return f"CR{i}"


class LiveSource(Protocol):
    """What the viewer steps and shows."""

    world: World
    survival: SurvivalWorld

    def step(self) -> bool:
        """One control step; True when the scene jumped (a new episode): shown without
        gliding."""
        ...

    def robots(self) -> list[RobotStatus]: ...

    def rows(self) -> list[tuple[str, str]]:
        """Panel lines (name, value) about the source."""
        ...

    def close(self) -> None: ...


class RunSource:
    """A run continued from a checkpoint (in memory; the run directory is never written)."""

    def __init__(self, runner: EvolutionRunner, label: str) -> None:
        self.runner = runner
        self.world = runner.world
        self.survival = runner.survival
        self.label = label

    def step(self) -> bool:
        self.runner.step()
        return False

    def robots(self) -> list[RobotStatus]:
        runner = self.runner
        behaviour = runner.controller.behaviour
        scheduler = runner.scheduler
        statuses = []
        for i in range(self.world.config.n_robots):
            shown = RECHARGING if runner.survival.docked[i] else int(behaviour[i])
            name, colour = _behaviour_style(shown)
            slot = int(scheduler.active_slot[i])
            generation = int(scheduler.slot_generation[i, slot])
            statuses.append(
                RobotStatus(
                    _robot_name(i), name, colour, float(runner.survival.energy[i]),
                    f"agent {slot}, gen {generation}",
                )  # fmt: skip
            )
        return statuses

    def rows(self) -> list[tuple[str, str]]:
        runner = self.runner
        return [
            ("source", self.label),
            (
                "run",
                f"{runner.config.method.upper()} seed {runner.seed}, "
                f"{runner.completed_generations} generations done",
            ),
        ]

    def close(self) -> None:
        self.runner.close()


def survival_choice(
    inputs: BehaviourInputs, energy: np.ndarray, docked: np.ndarray, max_energy: float
) -> np.ndarray:
    """The behaviour each robot runs in the ``survival`` task (the viewer's fixed rule).

    A task comes without an evolved controller, so the viewer arbitrates by energy and by what
    each robot sees: a robot that is not hungry (energy at least ``HUNGRY`` of ``max_energy``)
    and sees another robot runs Mate (LED on, willing to exchange genomes); otherwise one that
    sees a pack runs Forage; otherwise Search. A docked robot recharges until full (the world
    ends a recharge after ``max_recharge_steps`` in any case).

    Returns:
        (n,) behaviour indices (``MATE``, ``FORAGE``, ``SEARCH``), ``RECHARGING`` where docked.
    """
    from behaviours.inputs import FORAGE, MATE, SEARCH

    hungry = np.asarray(energy) < HUNGRY * max_energy
    choice = np.full(hungry.shape, SEARCH, dtype=np.int64)
    choice[inputs.forage_available] = FORAGE
    choice[inputs.mate_available & ~hungry] = MATE
    choice[np.asarray(docked, dtype=bool)] = RECHARGING
    return choice


class TaskSource:
    """A dm-control task whose controlled robots run the learned behaviours."""

    def __init__(self, name: str, seed: int, policies: BehaviourPolicies) -> None:
        from behaviours.definitions import spec as behaviour_spec
        from behaviours.inputs import BEHAVIOUR_NAMES, MATE, SEARCH, behaviour_inputs
        from cyber_rodent import tasks
        from cyber_rodent.commands import command_speeds

        self._inputs = behaviour_inputs
        self._mate, self._search = MATE, SEARCH
        self.name, self.seed, self.policies = name, seed, policies
        self.env = tasks.load(name, seed=seed)
        self.env.reset()
        self.task = self.env.task
        self.world = self.task.world
        self._speeds = command_speeds(self.world.robot)
        self.survival = self.task.survival
        # A behaviour's own task (its training episode) runs that behaviour alone.
        self.fixed: int | None = (
            behaviour_spec(name).index if name in BEHAVIOUR_NAMES else None
        )
        self.choice = np.full(self.world.config.n_robots, SEARCH, dtype=np.int64)
        self.episode, self.episode_step, self.episode_return = 1, 0, 0.0
        self.last_episode = ""
        self._choose(self._read_inputs())

    def _read_inputs(self) -> BehaviourInputs:
        world = self.world
        return self._inputs(
            self.task.frame, world.range_readings(), world.range_max,
            proximity=world.robot.proximity,
        )  # fmt: skip

    def _choose(self, inputs: BehaviourInputs) -> None:
        k = self.task.k
        if self.fixed is None:
            survival = self.survival
            self.choice[:] = survival_choice(
                inputs, survival.energy, survival.docked, survival.config.max_energy
            )
        else:
            self.choice[:k] = self.fixed

    def step(self) -> bool:
        inputs = self._read_inputs()
        self._choose(inputs)
        k = self.task.k
        commands = self.policies.commands(
            np.where(self.choice >= 0, self.choice, self._search), inputs
        )
        led = (self.choice[:k] == self._mate).astype(np.float64)
        action: dict[str, np.ndarray] = {"wheels": self._speeds[commands[:k]], "led": led}
        open_switches = self.env.action_spec()
        if "mate" in open_switches:  # the mate signal follows Mate
            action["mate"] = led.copy()
        if "recharge" in open_switches:  # recharge until full
            survival = self.survival
            action["recharge"] = (survival.energy[:k] < survival.config.max_energy).astype(
                np.float64
            )
        timestep = self.env.step(action)
        self.episode_step += 1
        self.episode_return += float(np.sum(timestep.reward))
        if not timestep.last():
            return False
        self.last_episode = (
            f"episode {self.episode}: {self.episode_step} steps, return {self.episode_return:g}"
        )
        self.env.reset()
        self.episode += 1
        self.episode_step, self.episode_return = 0, 0.0
        return True

    def robots(self) -> list[RobotStatus]:
        k = self.task.k
        statuses = []
        for i in range(self.world.config.n_robots):
            if not self.survival.alive[i]:
                name, colour = DEAD_STYLE
            elif i >= k:
                name, colour = PARKED_STYLE
            else:
                shown = RECHARGING if self.survival.docked[i] else int(self.choice[i])
                name, colour = _behaviour_style(shown)
            statuses.append(
                RobotStatus(_robot_name(i), name, colour, float(self.survival.energy[i]))
            )
        return statuses

    def rows(self) -> list[tuple[str, str]]:
        rows = [
            ("source", f"task {self.name} (seed {self.seed})"),
            ("episode", f"{self.episode}, step {self.episode_step}/{self.task.episode_steps}"),
        ]
        if self.last_episode:
            rows.append(("last", self.last_episode))
        return rows

    def close(self) -> None:
        self.env.close()


# --- the window's copy of the world ---------------------------------------------------------------
class Mirror:
    """The world as the window shows it: a copy of the live model and data.

    After each control step :meth:`follow` takes the live state; :meth:`show` then places the
    bodies a fraction of the way from the previous step's poses to the new ones (MuJoCo's
    ``mj_differentiatePos``/``mj_integratePos``, so free joints turn along the shortest arc).
    The model fields the world changes while it runs (LED colours, pack positions) are copied
    at every step.
    """

    def __init__(self, world: World) -> None:
        import mujoco

        self._mujoco = mujoco
        self.live = world
        self.model = copy.copy(world.model)
        self.data = mujoco.MjData(self.model)
        self._start = world.data.qpos.copy()
        self._end = world.data.qpos.copy()
        self._velocity = np.zeros(self.model.nv)
        self._times = (world.time, world.time)
        self.follow(jumped=True)
        self.show(1.0)

    def follow(self, jumped: bool) -> None:
        """Take the live state after a control step (``jumped``: show it without gliding)."""
        live = self.live
        self._start[:] = live.data.qpos if jumped else self._end
        self._end[:] = live.data.qpos
        self._times = (live.time if jumped else self._times[1], live.time)
        self.model.geom_rgba[:] = live.model.geom_rgba
        self.model.body_pos[:] = live.model.body_pos
        self._mujoco.mj_differentiatePos(self.model, self._velocity, 1.0, self._start, self._end)

    def show(self, fraction: float) -> None:
        """Place the bodies ``fraction`` (0 to 1) of the way through the last control step."""
        data = self.data
        data.qpos[:] = self._start
        self._mujoco.mj_integratePos(self.model, data.qpos, self._velocity, fraction)
        t0, t1 = self._times
        data.time = t0 + fraction * (t1 - t0)
        self._mujoco.mj_forward(self.model, data)


# --- keys -----------------------------------------------------------------------------------------
class Controls:
    """Pause, single steps and speed: set by keys on the viewer's thread, read by the loop."""

    def __init__(self, speed: float) -> None:
        self._lock = threading.Lock()
        self.paused = False
        self.speed = speed
        self._steps = 0

    def on_key(self, key: int) -> None:
        """The viewer's key callback (runs on its thread: no viewer calls here)."""
        with self._lock:
            if key == KEY_SPACE:
                self.paused = not self.paused
            elif key == KEY_RIGHT:
                self.paused = True
                self._steps += 1
            elif key in (KEY_MINUS, KEY_KP_SUBTRACT):
                self.speed = max(self.speed / 2, MIN_SPEED)
            elif key in (KEY_EQUAL, KEY_KP_ADD):
                self.speed = min(self.speed * 2, MAX_SPEED)

    def take_step(self) -> bool:
        """True once per requested single step."""
        with self._lock:
            if self._steps:
                self._steps -= 1
                return True
            return False


# --- drawing --------------------------------------------------------------------------------------
#: m above the chassis centre: the label's anchor, where its text starts (left end, baseline).
LABEL_HEIGHT = 0.36
#: The energy bar, in window pixels: it lies under its label's text, left-aligned with it, at
#: this gap below the text's baseline (room for descenders), and faces the camera. Sized in
#: pixels like the text, it keeps clear of the label at any zoom and camera angle.
BAR_GAP_PX = 6.0
BAR_LENGTH_PX = 64.0
BAR_THICKNESS_PX = 5.0
#: Scene viewport height assumed when the window does not report one (it is closing).
DEFAULT_VIEWPORT_HEIGHT = 600
#: MuJoCo's label font at 100 % (the viewer's scale without display scaling): about this many
#: pixels per character, and the text's top this far above its anchor. For keeping the labels
#: of robots that stand close on the screen apart.
LABEL_CHAR_PX = 8.5
LABEL_TOP_PX = 14.0
LABEL_SPACING_PX = 3.0
#: Labels are lifted apart for colonies up to this size. In a larger one, seen whole, robots
#: stand a few pixels apart and lifting would stack their labels into towers taller than the
#: window (and cost time growing with the cube of the count): they stay on their robots.
MAX_LIFTED_LABELS = 16


class ScreenFrame(NamedTuple):
    """The camera as the window draws it: world directions of the screen's right and up, the
    viewing direction, and how many metres one pixel spans at a given depth."""

    eye: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    right: np.ndarray
    metres_per_px: float  # at depth 1 m (perspective) or anywhere (orthographic)
    orthographic: bool

    def pixel(self, point: np.ndarray) -> float:
        """Metres per window pixel at ``point``."""
        if self.orthographic:
            return self.metres_per_px
        return self.metres_per_px * max(float((point - self.eye) @ self.forward), 1e-6)

    def to_screen(self, point: np.ndarray) -> tuple[float, float]:
        """Window pixels of ``point`` from the view's centre (x right, y up)."""
        rel, px = point - self.eye, self.pixel(point)
        return float(rel @ self.right) / px, float(rel @ self.up) / px


def label_lifts(anchors: np.ndarray, texts: Sequence[str]) -> np.ndarray:
    """Pixels to raise each label (and its bar) so that no two robots' label-and-bar boxes
    overlap on the screen.

    Args:
        anchors: (n, 2) the labels' anchors in window pixels (x right, y up).
        texts: the labels.

    Returns:
        (n,) lifts, >= 0. Labels lowest on the screen stay; each higher one that would touch a
        label already placed goes up just clear of it, straight above its robot. All 0 for
        more than :data:`MAX_LIFTED_LABELS` robots.
    """
    anchors = np.asarray(anchors, dtype=np.float64).reshape(-1, 2)
    if len(anchors) > MAX_LIFTED_LABELS:
        return np.zeros(len(anchors))
    below = BAR_GAP_PX + BAR_THICKNESS_PX + 1.0
    boxes: list[tuple[float, float, float, float]] = []  # (x0, y0, x1, y1), y up
    lifts = np.zeros(len(anchors))
    for k in np.argsort(anchors[:, 1], kind="stable"):
        x, y = anchors[k]
        x1 = x + max(LABEL_CHAR_PX * len(texts[k]), BAR_LENGTH_PX)
        lift = 0.0
        moved = True
        while moved:
            moved = False
            for bx0, by0, bx1, by1 in boxes:
                y0, y1 = y + lift - below, y + lift + LABEL_TOP_PX
                gap = LABEL_SPACING_PX
                if x < bx1 + gap and bx0 < x1 + gap and y0 < by1 + gap and by0 < y1 + gap:
                    lift = by1 + gap + below - y
                    moved = True
        lifts[k] = lift
        boxes.append((x, y + lift - below, x1, y + lift + LABEL_TOP_PX))
    return lifts


def screen_frame(
    model: Any, data: Any, camera: Any, viewport_height: int, scratch: Any
) -> ScreenFrame:
    """The :class:`ScreenFrame` of ``camera`` (an ``MjvCamera``) on ``model`` and ``data`` in
    a viewport ``viewport_height`` pixels tall (``scratch``: an ``MjvScene`` to compute in)."""
    import mujoco

    mujoco.mjv_updateCamera(model, data, camera, scratch)
    gl = scratch.camera[0]
    forward = np.array(gl.forward, dtype=np.float64)
    up = np.array(gl.up, dtype=np.float64)
    span = float(gl.frustum_top - gl.frustum_bottom) / max(int(viewport_height), 1)
    orthographic = bool(gl.orthographic)
    return ScreenFrame(
        eye=np.array(gl.pos, dtype=np.float64), forward=forward, up=up,
        right=np.cross(forward, up),
        metres_per_px=span if orthographic else span / max(float(gl.frustum_near), 1e-9),
        orthographic=orthographic,
    )  # fmt: skip


def decorate(
    scene: Any,
    centres: np.ndarray,
    robots: Sequence[RobotStatus],
    max_energy: float,
    screen: ScreenFrame,
) -> None:
    """Fill the viewer's user scene: per robot a label above it and its energy bar under the
    label's text, laid out in window pixels on ``screen`` so that neither covers the other,
    nor another robot's (:func:`label_lifts`)."""
    import mujoco

    scene.ngeom = 0
    # Bar boxes: x along the screen's right, y along its up, z towards the camera.
    facing = np.column_stack([screen.right, screen.up, -screen.forward]).ravel()
    identity = np.eye(3).ravel()
    texts = [f"{s.name} {s.behaviour} {s.energy:.0f}"[:99] for s in robots]
    anchors = np.asarray(centres, dtype=np.float64).reshape(-1, 3) + [0.0, 0.0, LABEL_HEIGHT]
    lifts = label_lifts(np.array([screen.to_screen(a) for a in anchors]).reshape(-1, 2), texts)
    for anchor, lift, status, text in zip(anchors, lifts, robots, texts, strict=True):
        share = float(np.clip(status.energy / max_energy, 0.0, 1.0)) if max_energy > 0 else 0.0
        colour = np.array([*(c / 255 for c in status.colour), 1.0], dtype=np.float32)
        anchor = anchor + screen.up * lift * screen.pixel(anchor)
        px = screen.pixel(anchor)
        half_length, half_thick = 0.5 * BAR_LENGTH_PX * px, 0.5 * BAR_THICKNESS_PX * px
        bar = anchor + screen.right * half_length - screen.up * (BAR_GAP_PX * px + half_thick)
        shapes = (
            (mujoco.mjtGeom.mjGEOM_LABEL, np.zeros(3), anchor, identity,
             np.ones(4, dtype=np.float32)),
            # A dark frame one pixel wider than the bar all round, then the bar over it.
            (mujoco.mjtGeom.mjGEOM_BOX, np.array([half_length + px, half_thick + px, px]),
             bar, facing, np.array([0.1, 0.1, 0.1, 0.85], dtype=np.float32)),
            (mujoco.mjtGeom.mjGEOM_BOX, np.array([half_length * share, half_thick, 2 * px]),
             bar + screen.right * half_length * (share - 1.0), facing, colour),
        )  # fmt: skip
        for kind, size, pos, mat, rgba in shapes:
            if scene.ngeom >= scene.maxgeom:
                return
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(geom, kind, size, pos, mat, rgba)
            if kind == mujoco.mjtGeom.mjGEOM_LABEL:
                geom.label = text
            scene.ngeom += 1


def _columns(rows: Sequence[tuple[str, str]]) -> tuple[str, str]:
    return "\n".join(k for k, _ in rows), "\n".join(v for _, v in rows)


#: Most robots the robot panel lists, one line each (a large colony's rest in one last line).
MAX_PANEL_ROBOTS = 10


def panel_texts(
    source_rows: Sequence[tuple[str, str]],
    robots: Sequence[RobotStatus],
    sim_time: float,
    controls: Controls,
) -> tuple[tuple[str, str], tuple[str, str]]:
    """The two panels, each two columns: top left the source, time and speed; top right one
    line per robot (behaviour, energy, and its agent in a run), the first
    :data:`MAX_PANEL_ROBOTS` of a large colony and a line counting the rest."""
    speed = f"{controls.speed:g}x" + ("   PAUSED (Space resumes)" if controls.paused else "")
    about = [*source_rows, ("time", f"{sim_time:.1f} s"), ("speed", speed)]
    listed = robots[:MAX_PANEL_ROBOTS]
    lines = [(r.name, f"{r.behaviour:<9s}{r.energy:4.0f}  {r.detail}".rstrip()) for r in listed]
    if len(robots) > len(listed):
        lines.append(("...", f"and {len(robots) - len(listed)} more"))
    return _columns(about), _columns(lines)


KEY_HELP = (
    "Space\nRight\n-  =\nTab",
    "pause / resume\npause, one step\nhalf / double speed\npanels",
)


# --- the loop -------------------------------------------------------------------------------------
class Pacer:
    """When control steps are due: the wall clock times the speed, without catching up stalls.

    ``progress`` is how far the window is through the last control step (1: the newest state in
    full). Each frame adds the wall time since the previous one, at most ``MAX_FRAME_GAP``,
    times ``speed / dt``; a whole step is due each time it reaches 1.
    """

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.progress = 1.0

    def due(self, elapsed: float, speed: float) -> int:
        """Steps due after ``elapsed`` wall seconds at ``speed``."""
        self.progress += min(max(elapsed, 0.0), MAX_FRAME_GAP) * speed / self.dt
        return int(self.progress)

    def taken(self, steps: int) -> float:
        """``steps`` of those due were taken; what was not (too slow) is dropped. Returns the
        fraction of the last step to show."""
        self.progress = min(self.progress - steps, 1.0)
        return self.progress

    def single_step(self) -> float:
        """A step taken by key: shown in full at once."""
        self.progress = 1.0
        return self.progress


@dataclass
class Session:
    """A running viewer: the source, its mirror, the window and the keys (``clock`` and
    ``sleep``: the wall clock the loop paces itself by)."""

    source: LiveSource
    mirror: Mirror
    handle: Any
    controls: Controls
    threads: list[threading.Thread]
    clock: Callable[[], float] = time.monotonic
    sleep: Callable[[float], None] = time.sleep
    _texts: tuple[tuple[str, str], tuple[str, str]] | None = None
    _scratch: Any = None

    def advance(self) -> None:
        """One control step of the source, taken into the mirror."""
        self.mirror.follow(jumped=self.source.step())

    def screen(self) -> ScreenFrame:
        """The window's camera now (call with the handle's lock held)."""
        import mujoco

        if self._scratch is None:
            self._scratch = mujoco.MjvScene(self.mirror.model, maxgeom=1)
        viewport = self.handle.viewport
        height = DEFAULT_VIEWPORT_HEIGHT if viewport is None else viewport.height
        return screen_frame(
            self.mirror.model, self.mirror.data, self.handle.cam, height, self._scratch
        )

    def present(self, fraction: float) -> None:
        """Show the mirror ``fraction`` through the last step, with labels and the panel."""
        import mujoco

        self.mirror.show(fraction)
        robots = self.source.robots()
        world = self.source.world
        centres = self.mirror.data.xpos[world.chassis_body]
        handle = self.handle
        max_energy = self.source.survival.config.max_energy
        with handle.lock():
            decorate(handle.user_scn, centres, robots, max_energy, self.screen())
        about, lines = panel_texts(self.source.rows(), robots, world.time, self.controls)
        if (about, lines) != self._texts:
            grid = mujoco.mjtGridPos
            handle.set_texts(
                [(None, grid.mjGRID_TOPLEFT, *about), (None, grid.mjGRID_TOPRIGHT, *lines),
                 (None, grid.mjGRID_BOTTOMLEFT, *KEY_HELP)]
            )  # fmt: skip
            self._texts = (about, lines)
        handle.sync()

    def watch(self, seconds: float | None) -> bool:
        """Step in real time times the speed until the window closes or ``seconds`` pass;
        True if the time ran out with the window still open."""
        pacer = Pacer(self.source.survival.config.control_dt)
        progress = pacer.progress
        clock = self.clock
        start = last = clock()
        while self.handle.is_running():
            now = clock()
            if seconds is not None and now - start >= seconds:
                return True
            elapsed, last = now - last, now
            if self.controls.take_step():
                self.advance()
                progress = pacer.single_step()
            elif not self.controls.paused:
                due, taken = pacer.due(elapsed, self.controls.speed), 0
                while taken < due and clock() < now + STEP_BUDGET:
                    self.advance()
                    taken += 1
                progress = pacer.taken(taken)
            self.present(progress)
            self.sleep(max(0.0, now + FRAME_PERIOD - clock()))
        return False

    def close(self) -> None:
        self.handle.close()
        for thread in self.threads:
            thread.join(timeout=10.0)
        self.source.close()


def open_window(mirror: Mirror, controls: Controls) -> tuple[Any, list[threading.Thread]]:
    """MuJoCo's passive viewer on the mirror, looking at the whole field.

    ``launch_passive`` waits forever if its thread fails to make the window, so it runs on a
    helper thread and the failure is caught from the thread's exception.

    Raises:
        ViewerFailed: the window did not open.
    """
    import mujoco
    import mujoco.viewer

    before = set(threading.enumerate())
    failures: list[BaseException] = []
    hook = threading.excepthook

    def record(args: threading.ExceptHookArgs) -> None:
        failures.append(args.exc_value if args.exc_value is not None else RuntimeError())

    box: queue.Queue[Any] = queue.Queue()

    def launch() -> None:
        box.put(
            mujoco.viewer.launch_passive(
                mirror.model, mirror.data, key_callback=controls.on_key,
                show_left_ui=False, show_right_ui=False,
            )  # fmt: skip
        )

    launcher = threading.Thread(target=launch, name="viewer-launch", daemon=True)
    threading.excepthook = record
    try:
        launcher.start()
        deadline = time.monotonic() + LAUNCH_TIMEOUT
        while True:
            try:
                handle = box.get(timeout=0.1)
                break
            except queue.Empty:
                pass
            if failures:
                raise ViewerFailed(f"the viewer window did not open: {failures[0]}")
            if time.monotonic() > deadline:
                raise ViewerFailed(f"the viewer window did not open within {LAUNCH_TIMEOUT:g} s")
    finally:
        threading.excepthook = hook
    threads = [t for t in threading.enumerate() if t not in before and t is not launcher]
    with handle.lock():
        cam = handle.cam
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        view = overview(mirror.live)
        cam.lookat[:] = view.lookat
        cam.distance = view.distance
        cam.azimuth = view.azimuth
        cam.elevation = view.elevation
        handle.opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0  # 'Y' shows the IR rays
    return handle, threads


# --- command line ---------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``cyber-rodent view``."""
    parser.add_argument(
        "dir", nargs="?", default=None, metavar="RUN_DIR",
        help="a run directory: continue its newest checkpoint",
    )  # fmt: skip
    parser.add_argument("--checkpoint", default=None, metavar="FILE", help="a checkpoint file")
    parser.add_argument(
        "--task", default=None, metavar="NAME",
        help=f"a dm-control task driven by the learned behaviours: {', '.join(task_names())}",
    )  # fmt: skip
    parser.add_argument(
        "--seed", type=int, default=None, help="placement seed of --task (default 0)"
    )
    parser.add_argument(
        "--speed", type=float, default=1.0,
        help=f"simulated seconds per wall second (default 1; {MIN_SPEED:g} to {MAX_SPEED:g}; "
        "the - and = keys halve and double it)",
    )  # fmt: skip
    parser.add_argument(
        "--seconds", type=float, default=None, metavar="S",
        help="close the viewer after S wall seconds (default: when the window is closed)",
    )  # fmt: skip
    parser.add_argument(
        "--screenshot", default=None, metavar="PNG",
        help="with --seconds: save what the window shows at the end as PNG",
    )  # fmt: skip


@dataclass(frozen=True)
class Plan:
    """What ``run`` will show, resolved and checked before anything is created."""

    task: str | None
    seed: int
    checkpoint: Path | None
    label: str
    policies: BehaviourPolicies | None
    speed: float
    seconds: float | None
    screenshot: Path | None


def _check_options(args: argparse.Namespace) -> None:
    given = [args.dir is not None, args.checkpoint is not None, args.task is not None]
    if sum(given) != 1:
        raise ViewerError(
            "give one of RUN_DIR, --checkpoint FILE or --task NAME "
            f"(got {sum(given)}); e.g. cyber-rodent view --task forage"
        )
    if args.seed is not None:
        if args.task is None:
            raise ViewerError("--seed applies to --task only (a run continues with its own seed)")
        if args.seed < 0:
            raise ViewerError(f"--seed must be an integer >= 0, got {args.seed}")
    speed = args.speed
    if not (math.isfinite(speed) and MIN_SPEED <= speed <= MAX_SPEED):
        raise ViewerError(f"--speed must be in [{MIN_SPEED:g}, {MAX_SPEED:g}], got {speed:g}")
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise ViewerError(f"--seconds must be a number > 0, got {args.seconds:g}")
    if args.screenshot is not None:
        if args.seconds is None:
            raise ViewerError("--screenshot needs --seconds S (it is taken after S seconds)")
        if Path(args.screenshot).suffix.lower() != ".png":
            raise ViewerError(f"--screenshot must name a .png file, got {args.screenshot}")
        from cyber_rodent.render import check_writable_output

        try:
            check_writable_output(args.screenshot)
        except ValueError as err:
            raise ViewerError(str(err).replace("--out", "--screenshot", 1)) from None


def _check_display() -> None:
    """Fail early, in one line, where no window can open (X11 platforms)."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return

    problem = display_problem()
    if problem is not None:
        raise ViewerError(
            f"{problem}: the viewer opens a window on an X display; set DISPLAY, or run it "
            "under a virtual one: xvfb-run -a cyber-rodent view ..."
        )


def _run_source(args: argparse.Namespace) -> tuple[Path, str, BehaviourPolicies]:
    """The checkpoint, a label and the run's behaviour policies, as ``render`` finds them."""

    if args.dir is not None:
        directory = Path(args.dir)
        if not directory.is_dir():
            raise ViewerError(f"RUN_DIR {directory}: no such directory")
        identity = read_run_record(directory)["policies"]
        checkpoint = latest_checkpoint(directory / CHECKPOINT_DIR)
        if checkpoint is None:
            raise ViewerError(
                f"RUN_DIR {directory} has no checkpoint yet (a run writes one per generation)"
            )
        label = f"run {directory}"
    else:
        checkpoint = Path(args.checkpoint)
        if not checkpoint.is_file():
            raise ViewerError(f"--checkpoint {checkpoint}: no such file")
        read_header(checkpoint)
        run_dir = checkpoint.parent.parent
        identity = (
            read_run_record(run_dir)["policies"]
            if (run_dir / RUN_FILE).exists()
            else policy_identity(policies_by_name("trained"))
        )
        label = f"checkpoint {checkpoint.name}"
    return checkpoint, label, policies_for_identity(identity)


def plan(args: argparse.Namespace) -> Plan:
    """Check every option and find the source; nothing is created.

    Raises:
        ViewerError: bad input (the message names the option and what is allowed).
    """
    _check_options(args)
    # dm-control, imported from here on, initialises GLFW when MUJOCO_GL=glfw and warns where
    # there is no display; that case is reported below, in one line.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", module="glfw")
        chosen = _plan_source(args)
    _check_display()
    return chosen


def _plan_source(args: argparse.Namespace) -> Plan:
    checkpoint: Path | None = None
    policies: BehaviourPolicies | None = None
    task: str | None = None
    if args.task is not None:
        task = check_task(args.task)
        from behaviours import BehaviourPolicies

        try:
            policies = BehaviourPolicies.load_default()
        except FileNotFoundError as err:
            raise ViewerError(f"--task needs the shipped trained behaviours: {err}") from None
        label = f"task {task}"
    else:

        try:
            checkpoint, label, policies = _run_source(args)
        except CheckpointError as err:
            raise ViewerError(f"--checkpoint: {err}") from None
    return Plan(
        task=task,
        seed=0 if args.seed is None else int(args.seed),
        checkpoint=checkpoint,
        label=label,
        policies=policies,
        speed=float(args.speed),
        seconds=args.seconds,
        screenshot=None if args.screenshot is None else Path(args.screenshot),
    )


def _make_source(chosen: Plan) -> LiveSource:
    if chosen.task is not None:
        assert chosen.policies is not None
        return TaskSource(chosen.task, chosen.seed, chosen.policies)

    assert chosen.checkpoint is not None
    runner = EvolutionRunner.from_checkpoint(chosen.checkpoint, chosen.policies)
    return RunSource(runner, chosen.label)


def _fail(message: str, status: int) -> int:
    print(f"cyber-rodent view: error: {message}", file=sys.stderr)
    return status


def run(args: argparse.Namespace) -> int:
    """``cyber-rodent view``: 0 when done, 2 for bad input, 1 if the viewer could not run."""
    try:
        chosen = plan(args)
    except ValueError as err:  # ViewerError and the loaders' ValueErrors (run.json, policies)
        return _fail(str(err), EXIT_USAGE)
    try:
        import mujoco.viewer  # noqa: F401  # loads GLFW: fails here if it cannot
    except (ImportError, RuntimeError) as err:
        return _fail(f"MuJoCo's viewer is not available: {err}", EXIT_FAILED)
    try:
        source = _make_source(chosen)
    except ValueError as err:  # a checkpoint this version cannot continue (CheckpointError)
        return _fail(str(err), EXIT_USAGE)
    controls = Controls(chosen.speed)
    try:
        mirror = Mirror(source.world)
        handle, threads = open_window(mirror, controls)
    except ViewerFailed as err:
        source.close()
        return _fail(str(err), EXIT_FAILED)
    session = Session(source, mirror, handle, controls, threads)
    try:
        session.present(1.0)
        finished = session.watch(chosen.seconds)
        if chosen.screenshot is not None:
            if not finished:
                return _fail("the window was closed before the screenshot", EXIT_FAILED)
            _save_screenshot(session, chosen.screenshot)
            print(f"wrote {chosen.screenshot}")
    except ViewerFailed as err:
        return _fail(str(err), EXIT_FAILED)
    except KeyboardInterrupt:
        print("cyber-rodent view: interrupted", file=sys.stderr)
        return 130
    finally:
        session.close()
    return 0


def _save_screenshot(session: Session, path: Path) -> None:
    """What the window shows now, as PNG (read back from the X server)."""
    from cyber_rodent.render import write_png

    time.sleep(SETTLE)  # the viewer's thread draws the last synced state
    try:
        image = capture_own_window()
    except CaptureError as err:
        raise ViewerFailed(f"--screenshot: {err}") from None
    write_png(image, path)


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``python -m evolution.lab.viewer`` (the same options as ``cyber-rodent
    view``)."""
    parser = argparse.ArgumentParser(
        prog="cyber-rodent view",
        description="Watch a run, a checkpoint or a task live in MuJoCo's viewer.",
    )
    add_arguments(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
