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
  ``[largest, second largest]`` of the six proximities (sensors ``RobotModel.proximity``: the
  Cyber Rodent's 5 front and its back one), sorted in decreasing order; which sensors they
  came from is not an input, exactly as the paper states it.

Behaviour indices are the order of the evolved controller's outputs (Mate, Forage, Search).
"""

from __future__ import annotations

import numpy as np

from behaviours.kernels import (
    BehaviourInputs,
    InputBuffers,
    InputRules,
    RangeSensors,
    map_inputs_reference,
)
from cyber_rodent.robot import CYBER_RODENT_PROXIMITY
from cyber_rodent.vision.kernels import NearestTargets
from cyber_rodent.vision.types import BATTERY, DEFAULT_MAX_DISTANCE, FACE, LED, VisionFrame

#: Behaviour indices, the order of the evolved controller's three outputs.
MATE, FORAGE, SEARCH = 0, 1, 2
BEHAVIOUR_NAMES: tuple[str, ...] = ("mate", "forage", "search")
N_BEHAVIOURS = len(BEHAVIOUR_NAMES)
#: Input dimensions of every behaviour (bearing + distance, or the two largest proximities).
N_INPUT_DIMS = 2
#: Version of the input mapping above; stored with trained values (a table learned on one
#: mapping is meaningless under another).
INPUTS_VERSION = 1

_PROXIMITY = np.asarray(CYBER_RODENT_PROXIMITY, dtype=np.int64)


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


def search_inputs(
    ranges: np.ndarray, range_max: np.ndarray, proximity: tuple[int, ...] | None = None
) -> np.ndarray:
    """Search's input: the two largest of the six (5 front + 1 back) proximity readings.

    The same rule as :func:`behaviour_inputs` (one mapping,
    :func:`behaviours.kernels.map_inputs_reference`), for callers that need only Search's.

    Args:
        ranges: (n, 8) range readings in metres.
        range_max: (n, 8) or (8,) each sensor's range in metres.
        proximity: the six sensors read (default the Cyber Rodent's; :func:`behaviour_inputs`).

    Returns:
        (n, 2) ``[largest, second largest]`` proximity, in [0, 1].
    """
    ranges = np.asarray(ranges, dtype=np.float64)
    n = ranges.shape[0] if ranges.ndim == 2 else 0
    return behaviour_inputs(VisionFrame.empty(n), ranges, range_max, proximity=proximity).search

def behaviour_inputs(
    frame: VisionFrame,
    ranges: np.ndarray,
    range_max: np.ndarray,
    max_distance: float = DEFAULT_MAX_DISTANCE,
    proximity: tuple[int, ...] | None = None,
) -> BehaviourInputs:
    """Map what the robots see and sense to the three behaviours' normalised inputs.

    Args:
        frame: every robot's vision (nearest LED, face and battery).
        ranges: (n, 8) range readings in metres (``World.range_readings``).
        range_max: (n, 8) or (8,) each sensor's range in metres (``World.range_max``).
        max_distance: distance (m) normalised to 1; default the field's diagonal.
        proximity: the six range sensors of the proximity inputs (``RobotModel.proximity``;
            default the Cyber Rodent's five front and one back sensor).

    Returns:
        The inputs and availability flags of every robot.

    Raises:
        ValueError: if the shapes of ``frame`` and ``ranges`` disagree.
    """
    n = frame.visible.shape[0]
    columns = _PROXIMITY if proximity is None else np.asarray(proximity, dtype=np.int64)
    ranges = np.asarray(ranges, dtype=np.float64)
    if ranges.shape[0] != n:
        raise ValueError(
            f"ranges: expected one row per robot of the frame ({n}), got {ranges.shape}"
        )
    if ranges.ndim != 2 or ranges.shape[1] <= columns.max():
        raise ValueError(f"ranges: expected shape (n_robots, 8), got {ranges.shape}")
    range_max = np.broadcast_to(np.asarray(range_max, dtype=np.float64), ranges.shape)
    if not (range_max[:, columns] > 0).all():
        raise ValueError("range_max: every sensor range must be > 0 m")
    visible = np.asarray(frame.visible, dtype=bool)
    # The vision's convention for an unseen target (bearing 0, distance inf) maps to [0.5, 1].
    nearest = NearestTargets(
        bearing=np.where(visible, frame.bearing, 0.0),
        distance=np.where(visible, frame.distance, np.inf),
        visible=visible,
    )
    inputs = BehaviourInputs(
        mate=np.empty((n, 2)),
        forage=np.empty((n, 2)),
        search=np.empty((n, 2)),
        mate_available=np.empty(n, dtype=bool),
        forage_available=np.empty(n, dtype=bool),
    )
    sensors = RangeSensors(
        raw=ranges,
        range_max=range_max,
        ranges=np.empty_like(ranges),
        proximity_columns=columns,
        proximity_max=np.ascontiguousarray(range_max[:, columns]),
    )
    buffers = InputBuffers(
        proximity=np.empty((n, len(columns))),
        norm_bearing=np.empty((n, 3)),
        norm_distance=np.empty((n, 3)),
        behaviour=inputs,
    )
    map_inputs_reference(sensors, nearest, InputRules(max_distance, LED, FACE, BATTERY), buffers)
    return inputs


__all__ = [
    "BEHAVIOUR_NAMES",
    "FORAGE",
    "INPUTS_VERSION",
    "MATE",
    "N_BEHAVIOURS",
    "N_INPUT_DIMS",
    "SEARCH",
    "BehaviourInputs",
    "behaviour_index",
    "behaviour_inputs",
    "search_inputs",
]
