"""One episode loop of a task, for every interface: reset, step, termination, observation.

A :class:`TaskEpisode` runs the task of a :class:`~cyber_rodent.tasks.spec.TaskSpec` on one
:class:`~cyber_rodent.survival.SurvivalWorld`. It is the task half of dm_control's
Task/Environment split, written once; each interface is a thin adapter that turns its own
action into the episode's commands and the step's result into its own return values:

=========================================  ===================================================
interface                                  adapter
=========================================  ===================================================
dm-control (``tasks.load``)                :class:`cyber_rodent.tasks.base.CyberRodentTask`
Gymnasium (``CyberRodent/<Task>-v0``)      :class:`cyber_rodent.gym_env.CyberRodentEnv`
PettingZoo (``colony_env.parallel_env``)   :class:`cyber_rodent.colony_env.ColonyEnv`
the behaviours' episodes (training, eval)  ``behaviours.episodes.BehaviourEpisode``
=========================================  ===================================================

What the episode owns, and the adapters never write again:

* **reset** (:meth:`TaskEpisode.reset`): a placement drawn from the generator, the LEDs of the
  spec, and the placement re-drawn until the spec's start condition holds in what the robots
  see (at most ``max_start_draws`` draws), the reward's start (target distance, first cell).
* **step** (:meth:`TaskEpisode.step`, or :meth:`begin` and :meth:`end` around the physics where
  the caller steps it, as dm-control does): the commands (:attr:`wheels`, :attr:`led`,
  :attr:`mate`, :attr:`recharge`: the spec's fixed switches, the actions' where the spec leaves
  them open) go to the world; then, in this order, the step's events, what the robots see,
  their contacts (if measured), the task's success, the termination (success, or a death that
  ends the task: :meth:`TaskSpec.dead`), the docking released at once where the spec says
  ``release_docking``, the reward's terms and their sum, and the truncation after
  ``episode_steps``. :class:`EpisodeStep` holds it all, and :meth:`EpisodeStep.info` names
  each term of the reward.
* **observation** (:meth:`TaskEpisode.observations`): every robot's entries of the one table,
  :mod:`cyber_rodent.observations`.

The step reads like MuJoCo Playground's ``step()``: the reward is a tuple of named terms, each a
small function of what the step did (:class:`~cyber_rodent.tasks.rewards.StepOutcome`) times
its scale (:class:`~cyber_rodent.tasks.rewards.RewardScales`), summed in order.

**``release_docking``** (Search: recharging is not its job) is decided here, for every
interface alike: at the end of a step in which a learner docked, the docking is released at
once, without the rotation reflex, after the step's events, success and contacts were taken
and before its reward, so the step still reports the docking and the next one starts free. The
dm-control tasks left the docking to the recharge decision until this loop was shared (a
Search robot stopped recharging on the next step, with the reflex); they now release it as the
Gymnasium environments and the behaviours' episodes always did.

What the adapters choose: how the robots see (``look``: the vision provider's ``observe``, or
the lazy nearest-target pass, :func:`~cyber_rodent.observations.nearest_frame`), which switches
their actions set, which reward kind and scales, how many robots are rewarded, and the rules
(:func:`task_rules`: the behaviour tasks' endless energy, except in dm-control, which runs the
rules it is given).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cyber_rodent.observations import robot_observations
from cyber_rodent.survival import StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.tasks.rewards import (
    EpisodeConfig,
    RewardScales,
    TaskRewards,
    episode_rules,
    total_reward,
)
from cyber_rodent.tasks.spec import SWITCHES, TaskSpec
from cyber_rodent.vision import VisionFrame

#: Placements drawn for a start condition before giving up (``EpisodeConfig.max_start_draws``).
START_DRAWS: int = EpisodeConfig().max_start_draws

Look = Callable[[], VisionFrame | None]


def task_rules(spec: TaskSpec, survival: SurvivalConfig | None) -> SurvivalConfig:
    """The rules an episode of ``spec`` runs under: ``survival`` (default: the paper's), with
    endless energy where the spec says ``endless_energy`` (:func:`~cyber_rodent.tasks.rewards.
    episode_rules`)."""
    if spec.endless_energy:
        return episode_rules(survival)
    return survival or SurvivalConfig()


@dataclass
class EpisodeStep:
    """What one step of a :class:`TaskEpisode` did.

    Attributes:
        events: the step's events (the world's reused object: read it before the next step).
        frame: what the robots see after the step (None for an episode that does not look).
        collided: (n,) bool, every robot's body touches an obstacle, if the episode measures
            contacts (else None).
        success: robot 0 reached the task's goal (:meth:`TaskSpec.reached`).
        terminated: the episode ended in a terminal state: its success, or a death that ends
            the task (:meth:`TaskSpec.dead`).
        truncated: it was cut after ``episode_steps`` without terminating.
        terms: each term of the reward, (rewarded,) each, by name in the order they sum.
        reward: (rewarded,) the terms' sum.
        steps: control steps of the episode so far, this one included.
        measure: the spec's measure of robot 0 (:data:`~cyber_rodent.tasks.spec.MEASURES`).
    """

    events: StepEvents
    frame: VisionFrame | None
    collided: np.ndarray | None
    success: bool
    terminated: bool
    truncated: bool
    terms: dict[str, np.ndarray]
    reward: np.ndarray
    steps: int
    measure: tuple[str, bool | int]

    def info(self, robot: int = 0) -> dict[str, Any]:
        """Robot ``robot``'s info (the Gymnasium environments'): ``steps``, ``collided`` (if
        measured), the spec's measure (robot 0's) and ``reward_terms``, each term by name."""
        info: dict[str, Any] = {"steps": self.steps}
        if self.collided is not None:
            info["collided"] = bool(self.collided[robot])
        name, value = self.measure
        info[name] = value
        info["reward_terms"] = {name: float(value[robot]) for name, value in self.terms.items()}
        return info


@dataclass(frozen=True)
class EpisodeOptions:
    """How an interface runs a task's episodes (:class:`TaskEpisode`); every default is the
    spec's own."""

    reward: str = "sparse"
    """the reward kind, ``"sparse"`` or ``"shaped"`` (:meth:`TaskSpec.rewards`)"""
    scales: RewardScales | None = None
    """the reward's scales (None: :class:`RewardScales`' defaults)"""
    rewarded: int | None = None
    """robots rewarded, ``0 .. rewarded-1`` (None: the learners)"""
    switches: tuple[str, ...] | None = None
    """the switches the learners' actions set (None: the spec's open ones,
    :attr:`TaskSpec.switches`); the others keep the spec's values"""
    episode_steps: int | None = None
    """control steps after which an episode is truncated (None: the spec's)"""
    start: bool = True
    """re-draw the placement until the spec's start condition holds (False: any placement)"""
    max_start_draws: int = START_DRAWS
    """placements drawn for the start condition before giving up"""
    collisions: bool = False
    """measure every robot's contacts after each step (:attr:`EpisodeStep.collided`);
    otherwise only a reward term that needs them measures them"""
    track_cells: bool = False
    """count the coverage cells robot 0 visits even if no term needs them (the
    ``coverage_cells`` measure)"""
    max_range: float | None = None
    """the camera's range, an unseen target's distance in :meth:`TaskEpisode.observations`"""


class TaskEpisode:
    """Episodes of the task ``spec`` on the world ``survival`` (see the module docstring).

    Args:
        spec: the task.
        survival: its world (the field of the spec or of the caller's choice).
        look: what the robots see in the world's current state (called once per draw of the
            start and once per step); None where the task looks at nothing.
        options: how the interface runs the episodes (:class:`EpisodeOptions`).

    Attributes:
        k: the learners (robots ``0 .. k-1``); the others are parked.
        wheels: (n, 2) the step's wheel speeds, m/s (a robot no action moves stands still).
        led, mate, recharge: (n,) bool, the step's switches (the spec's where fixed).
        action_switches: the arrays of ``switches``, in that order.
        rewards: the reward's terms, step by step (:class:`TaskRewards`).
        frame: what the robots saw last (None before the first reset).
        steps: control steps of the current episode.

    Raises:
        ValueError: the field has fewer robots than the task's learners.
    """

    def __init__(
        self,
        spec: TaskSpec,
        survival: SurvivalWorld,
        look: Look,
        options: EpisodeOptions | None = None,
    ) -> None:
        options = options or EpisodeOptions()
        n = survival.n_robots
        k = spec.n_learners(n)
        if k > n:
            raise ValueError(
                f"n_robots must be >= {k} for the {spec.name} task (it controls {k}), got {n}"
            )
        self.spec, self.survival, self.world, self.look = spec, survival, survival.world, look
        self.k = k
        steps = options.episode_steps
        self.episode_steps = spec.episode_steps if steps is None else steps
        self.start = spec.start if options.start else None
        self.max_start_draws = options.max_start_draws
        self.max_range = options.max_range
        fixed = spec.switch_values(n)
        self.start_led = fixed["led"].copy()
        self.wheels = np.zeros((n, 2))
        self.led, self.mate, self.recharge = fixed["led"], fixed["mate"], fixed["recharge"]
        self.switches = spec.switches if options.switches is None else options.switches
        arrays = dict(zip(SWITCHES, (self.led, self.mate, self.recharge), strict=True))
        self.action_switches = tuple(arrays[name] for name in self.switches)
        rewarded = options.rewarded
        self.rewards = TaskRewards(
            spec.rewards(options.reward),
            options.scales or RewardScales(),
            survival,
            k if rewarded is None else rewarded,
            spec.target,
            track_cells=options.track_cells,
        )
        self._collisions = np.zeros(n, dtype=bool) if options.collisions else None
        self._captures = 0
        self.frame: VisionFrame | None = None
        self.steps = 0

    # --- reset ------------------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> VisionFrame | None:
        """A new placement drawn with ``rng``, re-drawn until the start condition holds; the
        spec's LEDs, robots standing still, newborn energies. Returns what the robots see.

        Raises:
            RuntimeError: no placement met the start condition in ``max_start_draws`` draws.
        """
        start = self.start
        for _ in range(self.max_start_draws):
            self.survival.reset(rng)
            self.world.set_led(self.start_led)
            frame = self.look()
            if start is None or (frame is not None and start.holds(frame)):
                break
        else:
            assert start is not None
            raise RuntimeError(
                f"{self.spec.name}: no start placement met the start condition "
                f"({start.description}) in {self.max_start_draws} draws"
            )
        self.frame = frame
        self.wheels[:] = 0.0
        self.steps = 0
        self._captures = 0
        self.rewards.reset(frame)
        return frame

    # --- commands ---------------------------------------------------------------------------------
    def set_switches(self, robot: int, on: np.ndarray) -> None:
        """Robot ``robot``'s action switches (``switches`` order) from ``on``."""
        for target, value in zip(self.action_switches, on, strict=True):
            target[robot] = value

    def stop(self) -> None:
        """Every robot stands still with its action switches off (before a step's actions)."""
        self.wheels[:] = 0.0
        for target in self.action_switches:
            target[:] = False

    # --- step -------------------------------------------------------------------------------------
    def step(self) -> EpisodeStep:
        """One control step of the commands: :meth:`begin`, the physics, :meth:`end`."""
        self.begin()
        self.survival.advance_physics()
        return self.end()

    def begin(self) -> None:
        """Before the physics: the reward's start of the step, the commands to the world."""
        self.rewards.begin()
        self.survival.begin_step(self.wheels, self.led, self.mate, self.recharge)

    def end(self) -> EpisodeStep:
        """After the physics: the step's events, sight, termination, reward (module docstring)."""
        survival, spec, k = self.survival, self.spec, self.k
        events = survival.end_step()
        self.steps += 1
        self.frame = frame = self.look()
        collided = None
        if self._collisions is not None:
            collided = survival.collisions(out=self._collisions)
        success = spec.reached(events)
        terminated = success or spec.dead(survival.alive, k)
        if spec.release_docking:  # recharging is not the task's job
            for robot in range(k):
                survival.end_recharge(robot, reflex=False)
        self._captures += bool(events.captured[0])
        terms = self.rewards.end(events, frame, success, collided)
        return EpisodeStep(
            events=events,
            frame=frame,
            collided=collided,
            success=success,
            terminated=terminated,
            truncated=not terminated and self.steps >= self.episode_steps,
            terms=terms,
            reward=total_reward(terms),
            steps=self.steps,
            measure=self._measure(success),
        )

    def _measure(self, success: bool) -> tuple[str, bool | int]:
        """The spec's measure of robot 0 after a step."""
        measure = self.spec.measure
        if measure == "is_success":
            return measure, success
        if measure == "coverage_cells":
            return measure, self.rewards.cells_visited[0]
        return measure, self._captures

    # --- observation ------------------------------------------------------------------------------
    def observations(self, dtype: type[np.floating[Any]] = np.float32) -> np.ndarray:
        """(n, 21) every robot's raw observation now (:func:`~cyber_rodent.observations.
        robot_observations`, the one table), from the last frame."""
        if self.frame is None or self.max_range is None:
            raise RuntimeError("no observation before the first reset (or without max_range)")
        return robot_observations(self.survival, self.frame, self.max_range, dtype)


__all__ = ["START_DRAWS", "EpisodeOptions", "EpisodeStep", "Look", "TaskEpisode", "task_rules"]
