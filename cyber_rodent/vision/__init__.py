"""The CR's omnidirectional vision: one output type, two interchangeable providers.

* ``"geometric"`` (:class:`GeometricVision`): bearing and distance from poses, with field of
  view, range, resolution limit and ray-cast occlusion. Cheap; the default for long runs.
* ``"rendered"`` (:class:`RenderedVision`): a 360° image per robot rendered off-screen (EGL)
  and segmented by colour with OpenCV, the way the real robot sees. For videos, behaviour
  checks and sim-to-real studies.

Both return a :class:`VisionFrame` for all robots of the bound world. Distances are horizontal,
from the observer's camera axis to the target's vertical axis (see
:mod:`cyber_rodent.vision.targets`); bearings are in the robot frame, positive to the left.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend
from cyber_rodent.vision.config import (
    BLUE_BATTERY,
    GREEN_LED,
    RED_FACE,
    CameraConfig,
    ColourThreshold,
    VisionNoise,
    camera_for_field,
    default_max_range,
    follow_field,
)
from cyber_rodent.vision.geometric import GeometricVision
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
from cyber_rodent.world import World

PROVIDER_NAMES = ("geometric", "rendered")


@runtime_checkable
class VisionProvider(Protocol):
    """Anything that reports what every robot of its bound world sees right now.

    Attributes:
        world: the world whose robots look.
        config: the camera; callers may replace it (a frozen config) between episodes, e.g.
            to change the noise model.
        rng: generator of the noise model (None: the config's noise is off).
    """

    world: World
    config: CameraConfig
    rng: np.random.Generator | None

    def observe(self) -> VisionFrame:
        """Vision of all robots of the bound world, from its current ``MjData`` state."""
        ...


def make_provider(
    name: str,
    world: World,
    config: CameraConfig | None = None,
    rng: np.random.Generator | None = None,
    backend: Backend = DEFAULT_BACKEND,
) -> VisionProvider:
    """Create the vision provider ``name`` bound to ``world``.

    Args:
        name: ``"geometric"`` or ``"rendered"``.
        world: the world whose robots look.
        config: the camera (default: :func:`camera_for_field` of the world's field).
        rng: generator for the optional noise model (required only if ``config.noise`` is on).
        backend: ``"numba"`` (compiled kernels) or ``"numpy"`` (their references).

    Raises:
        ValueError: for an unknown provider name (the message lists the allowed names), or an
            invalid camera config.
    """
    if config is not None and not isinstance(config, CameraConfig):
        raise ValueError(f"config must be a CameraConfig, got {type(config).__name__}")
    if name == "geometric":
        return GeometricVision(world, config, rng, backend=backend)
    if name == "rendered":
        from cyber_rodent.vision.rendered import RenderedVision  # needs OpenGL: import lazily

        return RenderedVision(world, config, rng, backend=backend)
    raise ValueError(
        f"unknown vision provider {name!r}; allowed names: {', '.join(PROVIDER_NAMES)}"
    )


def save_omni_png(
    world: World, robot: int, out_path: str | Path, config: CameraConfig | None = None
) -> Path:
    """Render robot ``robot``'s omni image and save it with its segmentation overlay as a PNG.

    See :func:`cyber_rodent.vision.snapshot.save_omni_png` (imported lazily: it needs OpenGL).
    """
    from cyber_rodent.vision.snapshot import save_omni_png as _save

    return _save(world, robot, out_path, config)


__all__ = [
    "BATTERY",
    "BLUE_BATTERY",
    "CLASS_NAMES",
    "FACE",
    "GREEN_LED",
    "LED",
    "N_CLASSES",
    "PROVIDER_NAMES",
    "RED_FACE",
    "Blob",
    "CameraConfig",
    "ColourThreshold",
    "GeometricVision",
    "VisionFrame",
    "VisionNoise",
    "VisionProvider",
    "camera_for_field",
    "default_max_range",
    "follow_field",
    "make_provider",
    "normalise_bearing",
    "normalise_distance",
    "save_omni_png",
]
