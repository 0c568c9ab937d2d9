"""The tasks' reward terms, episode settings and Search's progress, defined once.

Every task (:mod:`cyber_rodent.tasks.spec`) declares its rewards as a tuple of named terms, in
the style of MuJoCo Playground's ``_reward_*`` functions: a :class:`RewardTerm` is a name, a
small function of what the step did (:class:`StepOutcome`) and the reward settings
(:class:`RewardScales`), and what it needs measured. A step's reward is the sum of its terms in
their declared order; the Gymnasium environments name each term in ``info["reward_terms"]``.
:class:`TaskRewards` computes them step by step for the dm-control tasks, the Gymnasium and
PettingZoo environments and the behaviour episodes (``behaviours.episodes``) alike, so all of
them compute one task's reward with the same functions on the same numbers.

The terms (per rewarded robot, per control step; ``γ`` is the learner's discount):

* ``success``: 1 at the step the task's goal is reached (docking, IR exchange), else 0.
* ``goal``, ``step_cost``, ``shaping`` (Forage and Mate, the behaviours' training reward,
  :func:`approach_reward`): ``goal_reward`` at the goal (terminal), minus ``step_cost`` on every
  step, plus the potential-based shaping ``γ Φ(s') − Φ(s)`` (:func:`shaping_reward`) with
  ``Φ(s) = −shaping · d(s)``, ``d`` the normalised distance of the task's target (pack; the
  other robot's LED, else its face; 1 when none is seen), and ``Φ = 0`` at the terminal state.
  Example (γ = 0.98, scale 1): docking from d = 0.05 earns ``0.05 − 0.02 + 1 = 1.03``.
* ``progress`` and ``collision`` (Search, :func:`search_reward`): forward progress minus a
  collision penalty, ``clip(p / (reference_speed · dt), −1, 1) − collision_penalty · c``, ``p``
  the displacement along the heading held at the start of the step (:func:`heading_progress`,
  the one definition of Search's progress, which evolution's learning mode uses too).
* ``new_cell``: 1 when the robot's centre enters a ``COVERAGE_CELL`` square of the field it has
  not visited in this episode (Search's area covered, :func:`coverage_cells`).
* ``capture`` and ``mating`` (Survival): ``dock_reward`` per captured battery (by the rules'
  ``capture_rule``), ``mate_reward`` per IR exchange.

They live in ``cyber_rodent`` because imports run evolution → behaviours → cyber_rodent: the
package that defines the robot's world cannot import the behaviours, so the behaviours import
their training rewards from here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.survival import StepEvents, SurvivalConfig, SurvivalWorld
from cyber_rodent.validation import integer, number, validate_fields
from cyber_rodent.vision import VisionFrame

#: Energy of a robot in a behaviour episode: enough never to die (energy is no behaviour's task).
ENDLESS_ENERGY = 1e6
#: Cell side (m) of the grid on which Search's covered area is counted.
COVERAGE_CELL = 0.1
_FIELD_HALF = C.FIELD_SIZE / 2

Reward = TypeVar("Reward", float, np.ndarray)


@dataclass(frozen=True)
class EpisodeConfig:
    """Settings of behaviour episodes (training and evaluation).

    Attributes:
        max_steps: control steps after which an episode is cut (the behaviours' budget: 100).
        goal_reward: reward of Forage's docking and Mate's IR exchange, ≥ 0.
        step_cost: reward subtracted on every step of Forage and Mate, ≥ 0.
        shaping: scale of the distance shaping of Forage and Mate (0 disables it), ≥ 0.
        gamma: discount used in the shaping term; must equal the learner's ``gamma`` for the
            shaping to be policy-invariant.
        reference_speed: Search's forward speed (m/s) that earns the full progress reward.
        collision_penalty: Search's reward subtracted per step in contact, ≥ 0.
        max_start_draws: placements drawn for a start condition before giving up.
    """

    max_steps: int = integer(100, 1, 1_000_000)
    goal_reward: float = number(1.0, 0.0)
    step_cost: float = number(0.02, 0.0)
    shaping: float = number(1.0, 0.0)
    gamma: float = number(0.98, 0.0, 1.0)
    reference_speed: float = number(0.5, 0.0, 1.3, low_open=True)
    collision_penalty: float = number(3.0, 0.0)
    max_start_draws: int = integer(500, 1)

    def __post_init__(self) -> None:
        validate_fields(self)


@dataclass(frozen=True)
class RewardScales:
    """The scales and settings the reward terms read (each term names the ones it reads).

    The defaults are the behaviours' training settings (:class:`EpisodeConfig`'s) and unit
    rewards for the colony's events.

    Attributes:
        goal_reward: ``goal``: reward at the goal, ≥ 0.
        step_cost: ``step_cost``: reward subtracted on every step, ≥ 0.
        shaping: ``shaping``: scale of the potential ``Φ = −shaping · d``, ≥ 0.
        gamma: ``shaping``: the learner's discount, in [0, 1].
        reference_speed: ``progress``: forward speed (m/s) that earns the full progress reward.
        collision_penalty: ``collision``: reward subtracted per step in contact, ≥ 0.
        dock_reward: ``capture``: reward of a captured battery.
        mate_reward: ``mating``: reward of an IR exchange, to each partner.
    """

    goal_reward: float = number(1.0, 0.0)
    step_cost: float = number(0.02, 0.0)
    shaping: float = number(1.0, 0.0)
    gamma: float = number(0.98, 0.0, 1.0)
    reference_speed: float = number(0.5, 0.0, low_open=True)
    collision_penalty: float = number(3.0, 0.0)
    dock_reward: float = number(1.0)
    mate_reward: float = number(1.0)

    def __post_init__(self) -> None:
        validate_fields(self)

    @classmethod
    def from_episode(cls, episode: EpisodeConfig) -> RewardScales:
        """The scales of the behaviours' training reward under ``episode``'s settings."""
        return cls(
            goal_reward=episode.goal_reward,
            step_cost=episode.step_cost,
            shaping=episode.shaping,
            gamma=episode.gamma,
            reference_speed=episode.reference_speed,
            collision_penalty=episode.collision_penalty,
        )


@dataclass
class StepOutcome:
    """What one control step did, for the reward terms: one entry per rewarded robot.

    A :class:`TaskRewards` fills only what its terms need (:attr:`RewardTerm.needs`); the rest
    stays zero.

    Attributes:
        success: the task's goal was reached this step (a terminal state), shared by all.
        captured: (k,) bool, the robot captured a battery (``StepEvents.captured``).
        mated: (k,) bool, the robot took part in an IR exchange.
        collided: (k,) bool, the robot's body touches a wall, a pack or a robot.
        distance_before: (k,) normalised distance of the task's target before the step.
        distance_after: (k,) the same after the step.
        progress: (k,) m moved along the heading held at the start of the step.
        new_cell: (k,) bool, the robot entered a coverage cell not visited in this episode.
        control_dt: s of simulated time per control step.
    """

    success: bool
    captured: np.ndarray
    mated: np.ndarray
    collided: np.ndarray
    distance_before: np.ndarray
    distance_after: np.ndarray
    progress: np.ndarray
    new_cell: np.ndarray
    control_dt: float

    @classmethod
    def zeros(cls, k: int, control_dt: float) -> StepOutcome:
        """An outcome of ``k`` robots with nothing happened (buffers to fill)."""
        return cls(
            False,
            np.zeros(k, dtype=bool),
            np.zeros(k, dtype=bool),
            np.zeros(k, dtype=bool),
            np.zeros(k),
            np.zeros(k),
            np.zeros(k),
            np.zeros(k, dtype=bool),
            control_dt,
        )


#: What a reward term may need measured beyond the step's events.
DISTANCE, PROGRESS, COLLIDED, NEW_CELL = "distance", "progress", "collided", "new_cell"


@dataclass(frozen=True)
class RewardTerm:
    """One named reward term.

    Attributes:
        name: the term's name (a key of ``info["reward_terms"]``).
        value: ``value(outcome, scales)``: the term's reward, (k,), scale included.
        scales: the :class:`RewardScales` fields it reads.
        needs: what it needs measured (:data:`DISTANCE`, :data:`PROGRESS`, :data:`COLLIDED`,
            :data:`NEW_CELL`).
    """

    name: str
    value: Callable[[StepOutcome, RewardScales], np.ndarray]
    scales: tuple[str, ...] = ()
    needs: frozenset[str] = frozenset()


# --- the formulas -----------------------------------------------------------------------------
def heading_progress(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Search's progress: metres moved along the heading held at the start of the step.

    ``(x' − x) cos θ + (y' − y) sin θ`` for poses ``(x, y, θ)`` before and ``(x', y', ·)``
    after; one robot's (3,) poses or (n, 3) arrays of them.
    """
    before, after = np.asarray(before), np.asarray(after)
    progress: np.ndarray = (after[..., 0] - before[..., 0]) * np.cos(before[..., 2]) + (
        after[..., 1] - before[..., 1]
    ) * np.sin(before[..., 2])
    return progress


def progress_reward(progress: Reward, reference_step: float) -> Reward:
    """Search's progress reward ``clip(progress / reference_step, −1, 1)``.

    Args:
        progress: m moved along the heading (:func:`heading_progress`).
        reference_step: ``reference_speed · control_dt``, m.
    """
    clipped: Reward = np.clip(progress / reference_step, -1.0, 1.0)
    return clipped


def shaping_reward(gamma: float, scale: float, d_before: Reward, d_after: Reward) -> Reward:
    """Potential-based shaping ``γ Φ(s′) − Φ(s)`` with ``Φ = −scale · d``.

    Floats or arrays (one entry per robot), with the same operations in the same order.
    Example: γ = 0.98, scale 1, the pack's normalised distance goes from 0.30 to 0.28:
    ``0.98 · (−0.28) − (−0.30) = 0.0256``.
    """
    return gamma * (-scale * d_after) + scale * d_before


def search_reward(progress: float, collided: bool, reference_step: float, penalty: float) -> float:
    """Search's step reward, its terms ``progress`` and ``collision`` summed:
    ``clip(progress / reference_step, −1, 1) − penalty · collided``.

    Args:
        progress: m moved along the heading at the start of the step.
        collided: the body touches an obstacle at the end of the step.
        reference_step: ``reference_speed · control_dt``, m.
        penalty: the collision penalty.
    """
    return float(progress_reward(progress, reference_step) + -penalty * collided)


# --- the terms --------------------------------------------------------------------------------
def _k(outcome: StepOutcome) -> int:
    return len(outcome.captured)


def reward_success(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """1 at the step the task's goal is reached, else 0."""
    return np.full(_k(outcome), 1.0 if outcome.success else 0.0)


def reward_goal(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``goal_reward`` at the step the task's goal is reached, else 0."""
    return np.full(_k(outcome), scales.goal_reward if outcome.success else 0.0)


def reward_step_cost(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``−step_cost`` on every step."""
    return np.full(_k(outcome), -scales.step_cost)


def reward_shaping(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``γ Φ(s′) − Φ(s)``, ``Φ = −shaping · d`` of the target's distance; ``Φ = 0`` at the goal."""
    after = outcome.distance_after * 0.0 if outcome.success else outcome.distance_after
    return shaping_reward(scales.gamma, scales.shaping, outcome.distance_before, after)


def reward_progress(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``clip(progress / (reference_speed · dt), −1, 1)``."""
    return progress_reward(outcome.progress, scales.reference_speed * outcome.control_dt)


def reward_collision(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``−collision_penalty`` per step in contact."""
    penalty: np.ndarray = -scales.collision_penalty * outcome.collided
    return penalty


def reward_new_cell(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """1 per coverage cell entered for the first time in the episode."""
    return np.where(outcome.new_cell, 1.0, 0.0)


def reward_capture(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``dock_reward`` per captured battery."""
    return np.where(outcome.captured, scales.dock_reward, 0.0)


def reward_mating(outcome: StepOutcome, scales: RewardScales) -> np.ndarray:
    """``mate_reward`` per IR exchange."""
    return np.where(outcome.mated, scales.mate_reward, 0.0)


SUCCESS = RewardTerm("success", reward_success)
GOAL = RewardTerm("goal", reward_goal, ("goal_reward",))
STEP_COST = RewardTerm("step_cost", reward_step_cost, ("step_cost",))
SHAPING = RewardTerm("shaping", reward_shaping, ("shaping", "gamma"), frozenset({DISTANCE}))
PROGRESS_TERM = RewardTerm(
    "progress", reward_progress, ("reference_speed",), frozenset({PROGRESS})
)
COLLISION = RewardTerm("collision", reward_collision, ("collision_penalty",), frozenset({COLLIDED}))
NEW_CELL_TERM = RewardTerm("new_cell", reward_new_cell, (), frozenset({NEW_CELL}))
CAPTURE = RewardTerm("capture", reward_capture, ("dock_reward",))
MATING = RewardTerm("mating", reward_mating, ("mate_reward",))
#: Forage's and Mate's training reward, in the order it is summed.
APPROACH: tuple[RewardTerm, ...] = (SHAPING, STEP_COST, GOAL)
#: Search's training reward, in the order it is summed.
SEARCH_TERMS: tuple[RewardTerm, ...] = (PROGRESS_TERM, COLLISION)


def total_reward(terms: dict[str, np.ndarray]) -> np.ndarray:
    """The step's reward: the terms summed in their order (the first one as it is)."""
    values = iter(terms.values())
    total = next(values)
    for value in values:
        total = total + value
    return total


def approach_reward(
    config: EpisodeConfig, d_before: Reward, d_after: Reward, reached: bool
) -> np.ndarray:
    """Forage's and Mate's step reward: its terms ``shaping``, ``step_cost`` and ``goal`` summed.

    Args:
        config: the episode's reward settings.
        d_before: normalised distance of the target before the step (float or per robot).
        d_after: the same after the step; ignored when ``reached`` (``Φ = 0`` at the goal).
        reached: the step reached the goal (docking, IR exchange), a terminal state.
    """
    before = np.atleast_1d(np.asarray(d_before, dtype=np.float64))
    outcome = StepOutcome.zeros(len(before), 0.0)
    outcome.success = reached
    outcome.distance_before[:] = before
    outcome.distance_after[:] = d_after
    scales = RewardScales.from_episode(config)
    total = total_reward({t.name: t.value(outcome, scales) for t in APPROACH})
    return total if np.ndim(d_before) else total[0]


# --- coverage ---------------------------------------------------------------------------------
def coverage_keys(positions: np.ndarray, cell: float = COVERAGE_CELL) -> np.ndarray:
    """One integer per position naming the ``cell`` × ``cell`` square of the field it lies in.

    Args:
        positions: (steps, 2) x, y of the robot's centre, m.
        cell: side of a square, m.
    """
    idx = np.floor((np.asarray(positions) + _FIELD_HALF) / cell).astype(np.int64)
    keys: np.ndarray = idx[:, 0] * 10_000 + idx[:, 1]
    return keys


def coverage_cells(positions: np.ndarray, cell: float = COVERAGE_CELL) -> int:
    """Number of distinct ``cell`` × ``cell`` squares of the field visited by ``positions``.

    Args:
        positions: (steps, 2) x, y of the robot's centre, m.
        cell: side of a square, m.
    """
    return int(np.unique(coverage_keys(positions, cell)).size)


# --- rules ------------------------------------------------------------------------------------
def episode_rules(survival: SurvivalConfig | None = None) -> SurvivalConfig:
    """The survival rules of a behaviour episode: ``survival`` (default: the paper's) with endless
    energy.

    Raises:
        ValueError: ``survival`` is not a ``SurvivalConfig`` (or None).
    """
    if survival is None:
        survival = SurvivalConfig()
    if not isinstance(survival, SurvivalConfig):
        raise ValueError(
            f"survival: must be a SurvivalConfig or None, got {type(survival).__name__}"
        )
    return dataclasses.replace(
        survival, initial_energy=ENDLESS_ENERGY, max_energy=ENDLESS_ENERGY
    )


# --- step by step -----------------------------------------------------------------------------
Target = Callable[[VisionFrame], np.ndarray]


class TaskRewards:
    """A task's reward terms, computed step by step for the first ``k`` robots of a world.

    Call :meth:`reset` at the start of an episode, :meth:`begin` before the step's physics and
    :meth:`end` after it (after the step's vision); :meth:`end` returns the terms by name, and
    :func:`total_reward` sums them. Only what the terms need is measured: the target's distance
    (from the vision frame), the progress along the heading (poses before and after), contacts,
    the coverage cells visited.

    Args:
        terms: the terms, in the order they are summed.
        scales: their scales.
        survival: the world the robots live in.
        k: robots rewarded (robots ``0 .. k-1``).
        target: per robot, the normalised distance of the task's target in a frame (needed by
            a term that needs :data:`DISTANCE`).
        track_cells: count the coverage cells visited even if no term needs them
            (:attr:`cells_visited`).

    Raises:
        ValueError: a term needs the target's distance and ``target`` is None.
    """

    def __init__(
        self,
        terms: tuple[RewardTerm, ...],
        scales: RewardScales,
        survival: SurvivalWorld,
        k: int,
        target: Target | None = None,
        track_cells: bool = False,
    ) -> None:
        if not terms:
            raise ValueError("a reward needs at least one term")
        self.terms, self.scales, self.survival, self.k = terms, scales, survival, k
        needs = frozenset().union(*(term.needs for term in terms))
        if DISTANCE in needs and target is None:
            raise ValueError("a term needs the target's distance, and the task has no target")
        self.target = target
        self._distance = DISTANCE in needs
        self._progress = PROGRESS in needs
        self._collided = COLLIDED in needs
        self._cells = NEW_CELL in needs or track_cells
        self.outcome = StepOutcome.zeros(k, survival.config.control_dt)
        self._before = np.zeros((k, 3))
        self._collisions = np.zeros(survival.n_robots, dtype=bool)
        self._visited: list[set[int]] = [set() for _ in range(k)]

    @property
    def cells_visited(self) -> list[int]:
        """Per rewarded robot, the coverage cells visited in this episode (if tracked)."""
        return [len(cells) for cells in self._visited]

    def _cell_keys(self) -> np.ndarray:
        return coverage_keys(self.survival.world.poses()[: self.k, :2])

    def reset(self, frame: VisionFrame | None) -> None:
        """Start an episode: the target's distance in ``frame``, the start cells."""
        if self._distance:
            assert frame is not None and self.target is not None
            self.outcome.distance_after[:] = self.target(frame)[: self.k]
        if self._cells:
            for cells, key in zip(self._visited, self._cell_keys().tolist(), strict=True):
                cells.clear()
                cells.add(key)

    def begin(self) -> None:
        """Before the step's physics: the poses its progress is measured from."""
        if self._progress:
            self._before[:] = self.survival.world.poses()[: self.k]

    def end(
        self,
        events: StepEvents,
        frame: VisionFrame | None,
        success: bool,
        collided: np.ndarray | None = None,
    ) -> dict[str, np.ndarray]:
        """After the step (and its vision): every term's reward, (k,) each, by name.

        Args:
            events: the step's events.
            frame: what the robots see after the step (for the target's distance).
            success: the step reached the task's goal.
            collided: (≥ k,) contacts after the step if the caller has them; else measured
                here when a term needs them.
        """
        o, k = self.outcome, self.k
        o.success = success
        o.captured[:] = events.captured[:k]
        np.greater_equal(events.mate_partner[:k], 0, out=o.mated)
        if self._distance:
            assert frame is not None and self.target is not None
            o.distance_before[:] = o.distance_after
            o.distance_after[:] = self.target(frame)[:k]
        if self._progress:
            o.progress[:] = heading_progress(self._before, self.survival.world.poses()[:k])
        if self._collided:
            if collided is None:
                collided = self.survival.collisions(out=self._collisions)
            o.collided[:] = collided[:k]
        if self._cells:
            for i, key in enumerate(self._cell_keys().tolist()):
                o.new_cell[i] = key not in self._visited[i]
                self._visited[i].add(key)
        return {term.name: term.value(o, self.scales) for term in self.terms}


__all__ = [
    "APPROACH",
    "CAPTURE",
    "COLLISION",
    "COVERAGE_CELL",
    "ENDLESS_ENERGY",
    "GOAL",
    "MATING",
    "NEW_CELL_TERM",
    "PROGRESS_TERM",
    "SEARCH_TERMS",
    "SHAPING",
    "STEP_COST",
    "SUCCESS",
    "EpisodeConfig",
    "RewardScales",
    "RewardTerm",
    "StepOutcome",
    "TaskRewards",
    "approach_reward",
    "coverage_cells",
    "coverage_keys",
    "episode_rules",
    "heading_progress",
    "progress_reward",
    "search_reward",
    "shaping_reward",
    "total_reward",
]
