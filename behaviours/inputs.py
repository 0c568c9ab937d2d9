"""What each basic behaviour perceives: the paper's inputs, normalised to [0, 1], per robot.

The paper (Elfwing et al., §3.4) gives every behaviour two sensory inputs, all "mapped to the
normalized linear interval [0, 1]":

* **Mate** (index :data:`MATE`): bearing and distance of the nearest green LED, or of the nearest
  red face if no LED is seen. Available only with another CR in view (an LED or a face seen).
* **Forage** (:data:`FORAGE`): bearing and distance of the nearest battery pack. Available only
  with a pack in view.
* **Search** (:data:`SEARCH`): "the two largest readings from five front and one back proximity
  distance sensors". Always available.

Normalisation (one convention for the whole package, shared with the evolved controller):

* **Bearing**: ``(bearing + π) / 2π`` (:func:`cyber_rodent.vision.normalise_bearing`), so
  straight ahead is 0.5, a target on the left is above 0.5, straight behind is 0 ≡ 1 (the tile
  coders treat this dimension as periodic).
* **Distance**: metres divided by the field's diagonal (3.25 m) and clipped
  (:func:`cyber_rodent.vision.normalise_distance`); an unseen target's distance is 1 and its
  bearing 0.5 (ahead), so an unavailable behaviour still has a valid input.
* **Proximity**: the CR's IR sensors measure *proximity* (a larger reading means a closer
  obstacle), while the simulated sensors return ranges in metres. We convert each reading to
  ``proximity = 1 - range / range_max`` (0 = nothing within the sensor's range, 1 = touching),
  so "the two largest readings" are the two *closest* obstacles. Search's input is
  ``[largest, second largest]`` of the six proximities (sensors ``PROXIMITY_SIX``: the 5 front
  and the back one), sorted in decreasing order; which sensors they came from is not an input,
  exactly as the paper states it.

Behaviour indices are the order of the evolved controller's outputs (Mate, Forage, Search).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cyber_rodent.constants import PROXIMITY_SIX
from cyber_rodent.vision.types import (
    BATTERY,
    DEFAULT_MAX_DISTANCE,
    FACE,
    LED,
    VisionFrame,
    normalise_bearing,
)

#: Behaviour indices, the order of the evolved controller's three outputs.
MATE, FORAGE, SEARCH = 0, 1, 2
BEHAVIOUR_NAMES: tuple[str, ...] = ("mate", "forage", "search")
N_BEHAVIOURS = len(BEHAVIOUR_NAMES)
#: Input dimensions of every behaviour (bearing + distance, or the two largest proximities).
N_INPUT_DIMS = 2
#: Version of the input mapping above; stored with trained values (a table learned on one
#: mapping is meaningless under another).
INPUTS_VERSION = 1

_PROXIMITY = np.asarray(PROXIMITY_SIX, dtype=np.intp)


def behaviour_index(name: str) -> int:
    """Index of the behaviour called ``name`` (``"mate"``, ``"forage"`` or ``"search"``).

    Raises:
        ValueError: for any other name (the message lists the allowed ones).
    """
    if name not in BEHAVIOUR_NAMES:
        raise ValueError(
            f"behaviour: unknown behaviour {name!r}; allowed: {', '.join(BEHAVIOUR_NAMES)}"
        )
    return BEHAVIOUR_NAMES.index(name)


@dataclass(frozen=True)
class BehaviourInputs:
    """Every robot's inputs of the three behaviours at one instant, all in [0, 1].

    Attributes:
        mate: (n, 2) ``[bearing, distance]`` of the nearest green LED, or of the nearest red face
            if no LED is seen; ``[0.5, 1]`` if neither.
        forage: (n, 2) ``[bearing, distance]`` of the nearest battery pack; ``[0.5, 1]`` if none.
        search: (n, 2) ``[largest, second largest]`` of the six proximity readings.
        mate_available: (n,) bool, another CR is in view (its LED or face is seen).
        forage_available: (n,) bool, a battery pack is in view.
    """

    mate: np.ndarray
    forage: np.ndarray
    search: np.ndarray
    mate_available: np.ndarray
    forage_available: np.ndarray

    @property
    def n_robots(self) -> int:
        """Number of robots (rows)."""
        return self.mate.shape[0]

    def of(self, behaviour: int) -> np.ndarray:
        """The (n, 2) input array of behaviour index ``behaviour``."""
        return (self.mate, self.forage, self.search)[behaviour]


def proximity(ranges: np.ndarray, range_max: np.ndarray) -> np.ndarray:
    """Proximity readings ``1 - range / range_max`` in [0, 1] (larger = closer).

    Args:
        ranges: (n, 8) range readings in metres (``World.range_readings``).
        range_max: (n, 8) or (8,) each sensor's range in metres.

    Returns:
        (n, 8) proximities, clipped to [0, 1].
    """
    p = 1.0 - np.asarray(ranges, dtype=np.float64) / range_max
    return np.clip(p, 0.0, 1.0, out=p)


def search_inputs(ranges: np.ndarray, range_max: np.ndarray) -> np.ndarray:
    """Search's input: the two largest of the six (5 front + 1 back) proximity readings.

    Args:
        ranges: (n, 8) range readings in metres.
        range_max: (n, 8) or (8,) each sensor's range in metres.

    Returns:
        (n, 2) ``[largest, second largest]`` proximity, in [0, 1].
    """
    ranges = np.asarray(ranges, dtype=np.float64)
    range_max = np.asarray(range_max, dtype=np.float64)
    if ranges.ndim != 2 or ranges.shape[1] <= _PROXIMITY.max():
        raise ValueError(f"ranges: expected shape (n_robots, 8), got {ranges.shape}")
    if range_max.ndim == 2:
        range_max = range_max[:, _PROXIMITY]
    else:
        range_max = range_max[_PROXIMITY]
    if not (range_max > 0).all():
        raise ValueError("range_max: every sensor range must be > 0 m")
    p = proximity(ranges[:, _PROXIMITY], range_max)
    p.sort(axis=1)
    return p[:, :-3:-1].copy()


def behaviour_inputs(
    frame: VisionFrame,
    ranges: np.ndarray,
    range_max: np.ndarray,
    max_distance: float = DEFAULT_MAX_DISTANCE,
) -> BehaviourInputs:
    """Map what the robots see and sense to the three behaviours' normalised inputs.

    Args:
        frame: every robot's vision (nearest LED, face and battery).
        ranges: (n, 8) range readings in metres (``World.range_readings``).
        range_max: (n, 8) or (8,) each sensor's range in metres (``World.range_max``).
        max_distance: distance (m) normalised to 1; default the field's diagonal.

    Returns:
        The inputs and availability flags of every robot.

    Raises:
        ValueError: if the shapes of ``frame`` and ``ranges`` disagree.
    """
    n = frame.visible.shape[0]
    if np.shape(ranges)[0] != n:
        raise ValueError(
            f"ranges: expected one row per robot of the frame ({n}), got {np.shape(ranges)}"
        )
    visible = frame.visible
    # (n, 3 classes, [bearing, distance]) for all classes at once; unseen: [0.5, 1].
    target = np.empty((n, 3, 2))
    np.copyto(target[:, :, 0], normalise_bearing(frame.bearing))
    target[:, :, 0][~visible] = 0.5
    np.divide(frame.distance, max_distance, out=target[:, :, 1])
    np.clip(target[:, :, 1], 0.0, 1.0, out=target[:, :, 1])
    target[:, :, 1][~visible] = 1.0
    led_seen = visible[:, LED]
    return BehaviourInputs(
        mate=np.where(led_seen[:, None], target[:, LED], target[:, FACE]),
        forage=target[:, BATTERY].copy(),
        search=search_inputs(ranges, range_max),
        mate_available=led_seen | visible[:, FACE],
        forage_available=visible[:, BATTERY].copy(),
    )
