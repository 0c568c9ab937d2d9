"""The vision output shared by the rendered and the geometric provider.

Both providers return a :class:`VisionFrame` for all robots at once: arrays indexed
``[robot, class]`` for the nearest target of each colour class (what the controller and the
behaviours read every step), plus the full blob lists (for overlays, analysis and tests).
Class order is fixed: green LED, red face, blue battery.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cyber_rodent import constants as C

LED, FACE, BATTERY = 0, 1, 2
CLASS_NAMES = ("led", "face", "battery")
N_CLASSES = 3

#: m, the paper field's diagonal (2.3 m x sqrt(2) = 3.25 m). The inputs normalise distances by
#: it in any field (docs/design.md §9.19: the shipped behaviours learned on it), and it is the
#: camera's default range (``CameraConfig.max_range``) in the paper's field.
DEFAULT_MAX_DISTANCE = C.FIELD_SIZE * math.sqrt(2)


@dataclass(frozen=True)
class Blob:
    """One detected target.

    Attributes:
        cls: colour class (``LED``, ``FACE`` or ``BATTERY``).
        bearing: rad in the robot frame, 0 = straight ahead, positive = to the left, in (-π, π].
        distance: m from the camera axis to the target, estimated.
        area: pixel area (rendered provider) or apparent solid-angle proxy (geometric).
    """

    cls: int
    bearing: float
    distance: float
    area: float


@dataclass
class VisionFrame:
    """What every robot sees at one instant.

    Attributes:
        bearing: (n_robots, 3) rad, nearest target of each class; 0 where not visible.
        distance: (n_robots, 3) m, nearest target of each class; ``inf`` where not visible.
        visible: (n_robots, 3) bool.
        blobs: per robot, every detected blob.
    """

    bearing: np.ndarray
    distance: np.ndarray
    visible: np.ndarray
    blobs: list[list[Blob]] = field(default_factory=list)

    @classmethod
    def empty(cls, n_robots: int) -> VisionFrame:
        return cls(
            bearing=np.zeros((n_robots, N_CLASSES)),
            distance=np.full((n_robots, N_CLASSES), np.inf),
            visible=np.zeros((n_robots, N_CLASSES), dtype=bool),
            blobs=[[] for _ in range(n_robots)],
        )


def normalise_bearing(bearing: np.ndarray) -> np.ndarray:
    """Map a bearing in [-π, π] to [0, 1]; straight ahead is 0.5 (docs/design.md §5)."""
    return np.clip((np.asarray(bearing) + math.pi) / (2 * math.pi), 0.0, 1.0)


def normalise_distance(
    distance: np.ndarray, visible: np.ndarray, max_distance: float = DEFAULT_MAX_DISTANCE
) -> np.ndarray:
    """Map a distance to [0, 1]; an unseen target's distance is 1 (docs/design.md §5)."""
    d = np.clip(np.asarray(distance, dtype=float) / max_distance, 0.0, 1.0)
    return np.where(visible, d, 1.0)
