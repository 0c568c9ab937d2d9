"""The CR's omnidirectional vision: one output type, two providers (rendered, geometric)."""

from cyber_rodent.vision.types import (
    BATTERY,
    CLASS_NAMES,
    FACE,
    LED,
    N_CLASSES,
    Blob,
    VisionFrame,
    normalise_bearing,
    normalise_distance,
)

__all__ = [
    "BATTERY",
    "CLASS_NAMES",
    "FACE",
    "LED",
    "N_CLASSES",
    "Blob",
    "VisionFrame",
    "normalise_bearing",
    "normalise_distance",
]
