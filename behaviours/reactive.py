"""Hand-written reactive policies: the baseline the learned behaviours are compared against.

They act on exactly the inputs the learned policies see (:mod:`behaviours.inputs`) and choose
from the same discrete wheel commands (:data:`cyber_rodent.commands.WHEEL_COMMANDS`), so a
comparison measures learning, not information. They also make the package usable before any
training (the evolution runner's tests run on them).

* **Approach** (Forage and Mate): turn on the spot towards the target while it is far off the
  heading, steer with an arc while it is a little off, drive straight when it is ahead; slow
  down near the target. Mate additionally stops inside ``stop_distance`` while aligned, because
  an IR exchange needs both robots to hold still facing each other; Forage never stops (docking
  needs the teeth to touch the pack).
* **Avoid** (Search): drive straight in free space; steer away once the closest obstacle is
  near, spin when it is very near. Search sees only the two largest proximity readings, not
  which sensors they came from, so it always turns the same way (left); a fixed turning
  direction also cannot oscillate between left and right in a corner.

Each policy is a pure vectorised function of a (batch, 2) input array; thresholds are config
fields with documented defaults (chosen by hand on the physics world, not tuned by search).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cyber_rodent.commands import command_index
from cyber_rodent.validation import check_number, number, validate_fields
from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE

_FORWARD = command_index("forward")
_FORWARD_SLOW = command_index("forward_slow")
_ARC_LEFT = command_index("arc_left")
_ARC_RIGHT = command_index("arc_right")
_SPIN_LEFT = command_index("spin_left")
_SPIN_RIGHT = command_index("spin_right")
_STOP = command_index("stop")


@dataclass(frozen=True)
class ApproachConfig:
    """Thresholds of the reactive approach (Forage, Mate).

    Attributes:
        spin_deg: turn on the spot when the target is more than this off the heading.
        arc_deg: steer with an arc when it is more than this (but at most ``spin_deg``) off.
        slow_distance: m, drive at the slow speed nearer than this.
        stop_distance: m, hold still nearer than this while within ``arc_deg`` (0 = never).
        max_distance: m, the distance normalised to 1 (the inputs' convention).
    """

    spin_deg: float = number(25.0, 0.0, 180.0)
    arc_deg: float = number(6.0, 0.0, 180.0)
    slow_distance: float = number(0.6, 0.0, 100.0)
    stop_distance: float = number(0.0, 0.0, 100.0)
    max_distance: float = number(DEFAULT_MAX_DISTANCE, 1e-3, 100.0)

    def __post_init__(self) -> None:
        validate_fields(self)
        check_number("arc_deg", self.arc_deg, 0.0, self.spin_deg)
        check_number("slow_distance", self.slow_distance, 0.0, self.max_distance)
        check_number("stop_distance", self.stop_distance, 0.0, self.max_distance)


@dataclass(frozen=True)
class AvoidConfig:
    """Thresholds of the reactive obstacle avoidance (Search), in proximity units [0, 1].

    Attributes:
        turn_proximity: steer left (arc) when the largest proximity exceeds this.
        spin_proximity: spin left on the spot when it exceeds this.
    """

    turn_proximity: float = number(0.2, 0.0, 1.0)
    spin_proximity: float = number(0.45, 0.0, 1.0)

    def __post_init__(self) -> None:
        validate_fields(self)
        check_number("turn_proximity", self.turn_proximity, 0.0, self.spin_proximity)


class ReactiveApproach:
    """Reactive target approach on ``[bearing, distance]`` inputs (Forage and Mate).

    Args:
        config: the thresholds.
    """

    def __init__(self, config: ApproachConfig | None = None) -> None:
        self.config = config or ApproachConfig()
        c = self.config
        # Thresholds in input units: normalised bearing offset from 0.5, normalised distance.
        self._spin = c.spin_deg / 360.0
        self._arc = c.arc_deg / 360.0
        self._slow = c.slow_distance / c.max_distance
        self._stop = c.stop_distance / c.max_distance

    def act(self, states: np.ndarray) -> np.ndarray:
        """Commands (batch,) for inputs (batch, 2) ``[bearing, distance]`` in [0, 1]."""
        x = np.asarray(states, dtype=np.float64).reshape(-1, 2)
        off = x[:, 0] - 0.5  # > 0: target on the left
        dist = x[:, 1]
        mag = np.abs(off)
        ahead = np.where(dist < self._slow, _FORWARD_SLOW, _FORWARD)
        ahead = np.where(dist < self._stop, _STOP, ahead)
        return np.select(
            [mag > self._spin, mag > self._arc],
            [
                np.where(off > 0, _SPIN_LEFT, _SPIN_RIGHT),
                np.where(off > 0, _ARC_LEFT, _ARC_RIGHT),
            ],
            default=ahead,
        ).astype(np.int64)


class ReactiveAvoid:
    """Reactive obstacle avoidance on ``[largest, second largest]`` proximity (Search).

    Args:
        config: the thresholds.
    """

    def __init__(self, config: AvoidConfig | None = None) -> None:
        self.config = config or AvoidConfig()

    def act(self, states: np.ndarray) -> np.ndarray:
        """Commands (batch,) for inputs (batch, 2) ``[largest, second]`` proximity in [0, 1]."""
        x = np.asarray(states, dtype=np.float64).reshape(-1, 2)
        near = x[:, 0]
        c = self.config
        return np.select(
            [near > c.spin_proximity, near > c.turn_proximity],
            [_SPIN_LEFT, _ARC_LEFT],
            default=_FORWARD,
        ).astype(np.int64)


#: The baseline of each behaviour (Mate stops within mating range: 0.45 m between the camera
#: axes puts the IR ports about 0.23 m apart, inside the 0.35 m exchange distance).
def reactive_mate() -> ReactiveApproach:
    """Reactive Mate: approach the other CR and hold still, facing it, within mating range."""
    return ReactiveApproach(ApproachConfig(stop_distance=0.45))


def reactive_forage() -> ReactiveApproach:
    """Reactive Forage: approach the nearest pack head-on until the teeth dock."""
    return ReactiveApproach(ApproachConfig())


def reactive_search() -> ReactiveAvoid:
    """Reactive Search: straight ahead, turn left away from near obstacles."""
    return ReactiveAvoid(AvoidConfig())
