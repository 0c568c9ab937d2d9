"""The basic behaviours' episode settings and training rewards, defined once.

The behaviours (``behaviours/``) are trained with these rewards (``behaviours.episodes`` imports
them from here), and the Gymnasium environments (:mod:`cyber_rodent.gym_env`) offer the same
numbers as ``reward="shaped"``. They live in ``cyber_rodent`` because imports run evolution →
behaviours → cyber_rodent: the package that defines the robot's world cannot import the
behaviours, so the behaviours import the rule from it.

Rewards (per robot, per control step; ``γ`` is the learner's discount):

* **Forage** and **Mate** (:func:`approach_reward`): ``goal_reward`` at the step the goal is
  reached (docking, or the IR exchange; terminal), minus ``step_cost`` on every step, plus the
  potential-based shaping ``γ Φ(s') − Φ(s)`` (:func:`shaping_reward`) with ``Φ(s) = −shaping ·
  d(s)``, ``d`` the normalised distance of the nearest target (pack; other robot's LED, else its
  face; 1 when none is seen), and ``Φ = 0`` at the terminal state. Example (γ = 0.98, scale 1):
  docking from d = 0.05 earns ``0 + 0.05 − 0.02 + 1 = 1.03``.
* **Search** (:func:`search_reward`): forward progress minus a collision penalty,
  ``clip(p / (reference_speed · dt), −1, 1) − collision_penalty · c``.

Search's quality measure, the area covered, counts the distinct ``COVERAGE_CELL`` squares the
robot's centre visits (:func:`coverage_cells`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.validation import integer, number, validate_fields

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
        max_steps: control steps after which an episode is cut (the issue's budget: 100).
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


def shaping_reward(gamma: float, scale: float, d_before: Reward, d_after: Reward) -> Reward:
    """Potential-based shaping ``γ Φ(s') − Φ(s)`` with ``Φ = −scale · d``.

    Floats or arrays (one entry per robot), with the same operations in the same order.
    Example: γ = 0.98, scale 1, the pack's normalised distance goes from 0.30 to 0.28:
    ``0.98 · (−0.28) − (−0.30) = 0.0256``.
    """
    return gamma * (-scale * d_after) + scale * d_before


def approach_reward(
    config: EpisodeConfig, d_before: Reward, d_after: Reward, reached: bool
) -> Reward:
    """Forage's and Mate's step reward: shaping, minus the step cost, plus the goal reward.

    Args:
        config: the episode's reward settings.
        d_before: normalised distance of the target before the step (float or per robot).
        d_after: the same after the step; ignored when ``reached`` (``Φ = 0`` at the goal).
        reached: the step reached the goal (docking, IR exchange), a terminal state.
    """
    after = d_after * 0.0 if reached else d_after
    reward = shaping_reward(config.gamma, config.shaping, d_before, after)
    reward = reward - config.step_cost
    if reached:
        reward = reward + config.goal_reward
    return reward


def search_reward(progress: float, collided: bool, reference_step: float, penalty: float) -> float:
    """Search's step reward: ``clip(progress / reference_step, −1, 1) − penalty · collided``.

    Args:
        progress: m moved along the heading at the start of the step.
        collided: the body touches an obstacle at the end of the step.
        reference_step: ``reference_speed · control_dt``, m.
        penalty: the collision penalty.
    """
    return min(1.0, max(-1.0, progress / reference_step)) - (penalty if collided else 0.0)


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


__all__ = [
    "COVERAGE_CELL",
    "ENDLESS_ENERGY",
    "EpisodeConfig",
    "approach_reward",
    "coverage_cells",
    "coverage_keys",
    "episode_rules",
    "search_reward",
    "shaping_reward",
]
