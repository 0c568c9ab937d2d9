"""The rendered vision provider: off-screen omni images, segmented by colour.

This is the camera as the real CR has it: every robot's 360° strip is rendered off-screen
(all robots in one buffer) and segmented by colour
(:class:`~cyber_rodent.vision.segmentation.OmniSegmenter`). Use it for videos, behaviour checks
and sim-to-real studies; long evolution runs use the geometric provider, which
``benchmarks/vision_agreement.py`` shows to agree with this one.

Two renderers draw the same scene: ``"batch"``
(:class:`~cyber_rodent.vision.batch_rendering.BatchOmniRenderer`, a few OpenGL 4.5 calls per
frame, much faster under llvmpipe) and ``"mujoco"``
(:class:`~cyber_rodent.vision.rendering.OmniRenderer`, MuJoCo's own renderer, one
``mjr_render`` per view; the reference the batch renderer is tested against, and the one that
works on any GL backend). ``"auto"`` takes the batch renderer under EGL (``MUJOCO_GL=egl``, the
default) and MuJoCo's elsewhere (e.g. OSMesa, whose GL version may be too old).

A different choice, ``backend`` (``"numba"`` or ``"numpy"``, ``docs/design.md`` §3), picks the
compiled kernels or their numpy references for both the batch renderer's per-frame views and
the segmentation; the images and detections are the same either way.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, check_backend
from cyber_rodent.vision.config import CameraConfig, camera_for_field
from cyber_rodent.vision.detections import (
    apply_noise,
    frame_from_detections,
    load_noise_state,
    noise_state,
)
from cyber_rodent.vision.rendering import OmniRenderer
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import target_geometry
from cyber_rodent.vision.types import VisionFrame
from cyber_rodent.world import World

#: Renderer names of :class:`RenderedVision` (see the module docstring).
RENDERERS = ("auto", "batch", "mujoco")


class RenderedVision:
    """Vision from rendered omni images and colour segmentation.

    Args:
        world: the world to observe (bound: every call renders its current state).
        config: the camera (default: :func:`~cyber_rodent.vision.config.camera_for_field` of
            the world's field).
        rng: generator for the noise model; required only if ``config.noise`` is enabled.
        renderer: ``"auto"``, ``"batch"`` or ``"mujoco"`` (see the module docstring).
        backend: ``"numba"`` (compiled kernels) or ``"numpy"`` (their references), passed to
            the batch renderer and the segmenter.

    Attributes:
        last_strips: (n_robots, height, strip_width, 3) RGB of the latest :meth:`observe`
            (overwritten by the next call).
        last_classes: (n_robots, height, strip_width) uint8 class bits of the latest call
            (bit c = class c; overwritten by the next call).
    """

    def __init__(
        self,
        world: World,
        config: CameraConfig | None = None,
        rng: np.random.Generator | None = None,
        renderer: str = "auto",
        backend: Backend = DEFAULT_BACKEND,
    ):
        self.backend = check_backend(backend)
        if renderer not in RENDERERS:
            raise ValueError(f"renderer must be one of {', '.join(RENDERERS)}, got {renderer!r}")
        if renderer == "auto":
            egl = os.environ.get("MUJOCO_GL", "egl").lower() == "egl"
            renderer = "batch" if egl else "mujoco"
        self.world = world
        self.config = config or camera_for_field(world.config.field_size)
        if self.config.noise.enabled and rng is None:
            raise ValueError("config.noise is enabled, so pass rng=np.random.Generator")
        self.rng = rng
        if renderer == "batch":
            from cyber_rodent.vision.batch_rendering import BatchOmniRenderer

            self.renderer: OmniRenderer | BatchOmniRenderer = BatchOmniRenderer(
                world, self.config, backend=self.backend
            )
        else:
            self.renderer = OmniRenderer(world, self.config)
        self.segmenter = OmniSegmenter(self.config, target_geometry(world), backend=self.backend)
        self.projection = self.renderer.projection
        self.last_strips: np.ndarray | None = None
        self.last_classes: np.ndarray | None = None

    def observe(self) -> VisionFrame:
        """Render every robot's omni strip and segment it."""
        strips = self.renderer.render()
        robot, cls, bearing, distance, area, classes = self.segmenter.detect(strips)
        self.last_strips, self.last_classes = strips, classes
        keep = np.ones(len(robot), dtype=bool)
        apply_noise(self.config.noise, self.rng, bearing, distance, keep)
        return frame_from_detections(
            self.world.config.n_robots,
            robot[keep],
            cls[keep],
            bearing[keep],
            distance[keep],
            area[keep],
        )

    @property
    def last_masks(self) -> np.ndarray | None:
        """(3, n_robots, height, strip_width) uint8 0/255 class masks of the latest call."""
        if self.last_classes is None:
            return None
        return self.segmenter.masks_from_classes(self.last_classes)

    def close(self) -> None:
        """Release the OpenGL context."""
        self.renderer.close()

    def __enter__(self) -> RenderedVision:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def state(self) -> dict[str, Any]:
        """The provider's checkpoint state (:func:`~cyber_rodent.vision.detections.noise_state`)."""
        return noise_state(self.rng)

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state` into this provider."""
        load_noise_state(self.rng, state)
