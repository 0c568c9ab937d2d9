"""The discrete wheel commands that the basic behaviours choose from, defined once.

The paper's behaviours (Mate, Forage, Search) are learned with Sarsa(λ) over a small discrete
action set; evolution never touches motor control. This module is the single place that set
is defined, so the learner, the shipped action values, the exported robot policies and any
hand-written reactive policy all index the same commands. Changing the set (order included)
invalidates trained action values, hence :data:`COMMAND_SET_VERSION`.

Speeds are wheel rim speeds in m/s (what :meth:`cyber_rodent.world.World.set_wheel_speeds` and
:meth:`cyber_rodent.survival.SurvivalWorld.step` take), well inside the Cyber Rodent's motor
limit (:data:`DESIGN_TOP_SPEED` = 1.3 m/s). They are chosen for docking and mating, which need
slow, precise approaches: at the default 0.2 s control step and 0.5 m/s the robot moves 10 cm
per step, about the width of a pack (8 cm) and its electrode ring, and a spin turns 0.5 rad
(29°) per step.

Another robot (``WorldConfig.robot``) drives the same commands scaled by its top speed over the
Cyber Rodent's (:func:`command_speeds`): the same share of what its motors can do. For the
paper's robot the factor is exactly 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cyber_rodent.robot import RobotModel
from cyber_rodent.validation import check_number

#: Bumped whenever the command set below changes; stored with trained action values.
COMMAND_SET_VERSION = 1
#: m/s, the top speed the command set was designed for: the Cyber Rodent's (its model's
#: ``top_speed``, read from ``assets/mjcf/cyber_rodent.xml``; a test checks the two agree).
DESIGN_TOP_SPEED = 1.3


@dataclass(frozen=True)
class WheelCommand:
    """One discrete motor command.

    Attributes:
        name: short identifier, stable across versions of the same set.
        left: left wheel rim speed in m/s (positive drives forward).
        right: right wheel rim speed in m/s.
    """

    name: str
    left: float
    right: float

    def __post_init__(self) -> None:
        # No field defaults (a command names its speeds), so the rule is checked here.
        for side in ("left", "right"):
            name = f"WheelCommand {self.name!r}: {side}"
            check_number(name, getattr(self, side), -DESIGN_TOP_SPEED, DESIGN_TOP_SPEED)


#: The command set, in action-index order. Forward motion dominates because docking (Forage)
#: and reaching the mating position (Mate) are approaches; the arcs steer while approaching;
#: the spins and the reverse let Search back out of corners and turn towards targets.
WHEEL_COMMANDS: tuple[WheelCommand, ...] = (
    WheelCommand("forward", 0.5, 0.5),
    WheelCommand("forward_slow", 0.2, 0.2),
    WheelCommand("arc_left", 0.2, 0.45),
    WheelCommand("arc_right", 0.45, 0.2),
    WheelCommand("spin_left", -0.2, 0.2),
    WheelCommand("spin_right", 0.2, -0.2),
    WheelCommand("reverse", -0.3, -0.3),
    WheelCommand("stop", 0.0, 0.0),
)
N_COMMANDS = len(WHEEL_COMMANDS)
COMMAND_NAMES: tuple[str, ...] = tuple(c.name for c in WHEEL_COMMANDS)

#: (N_COMMANDS, 2) left/right speeds in m/s, read-only (indexed in the hot loop).
COMMAND_SPEEDS: np.ndarray = np.array([(c.left, c.right) for c in WHEEL_COMMANDS], dtype=float)
COMMAND_SPEEDS.setflags(write=False)


def motor_scale(robot: RobotModel) -> float:
    """``robot.top_speed / DESIGN_TOP_SPEED``: what a speed chosen for the Cyber Rodent (a
    command, the survival reflex's spin) is multiplied by on ``robot``; exactly 1 for it."""
    return robot.top_speed / DESIGN_TOP_SPEED


def command_speeds(robot: RobotModel) -> np.ndarray:
    """(N_COMMANDS, 2) the command set for ``robot``, m/s, read-only: :data:`COMMAND_SPEEDS`
    times :func:`motor_scale` (the paper's robot: the set itself)."""
    factor = motor_scale(robot)
    if factor == 1.0:
        return COMMAND_SPEEDS
    speeds = COMMAND_SPEEDS * factor
    speeds.setflags(write=False)
    return speeds


def command_index(name: str) -> int:
    """Action index of the command called ``name``.

    Raises:
        ValueError: if no command has that name (the message lists the names).
    """
    try:
        return COMMAND_NAMES.index(name)
    except ValueError:
        raise ValueError(
            f"unknown wheel command {name!r}; known commands: {', '.join(COMMAND_NAMES)}"
        ) from None


def wheel_speeds(indices: np.ndarray | int, out: np.ndarray | None = None) -> np.ndarray:
    """Left/right rim speeds (m/s) for command indices, shape ``indices.shape + (2,)``.

    Args:
        indices: one command index or an array of them (one per robot).
        out: optional preallocated result, to keep the per-step path allocation-free.

    Raises:
        ValueError: if an index is not an integer in ``[0, N_COMMANDS)``.
    """
    idx = np.asarray(indices)
    if idx.dtype.kind not in "iu":
        raise ValueError(
            f"command indices must be integers in [0, {N_COMMANDS}), got dtype {idx.dtype}"
        )
    if idx.size and (idx.min() < 0 or idx.max() >= N_COMMANDS):
        raise ValueError(
            f"command indices must be in [0, {N_COMMANDS}), got values from "
            f"{int(idx.min())} to {int(idx.max())}"
        )
    if out is None:
        speeds: np.ndarray = COMMAND_SPEEDS[idx]
        return speeds
    np.take(COMMAND_SPEEDS, idx, axis=0, out=out)
    return out
