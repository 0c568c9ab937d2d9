"""The rendered vision provider: off-screen omni images, segmented by colour.

This is the camera as the real CR has it: every robot's 360° strip is rendered off-screen
(:class:`~cyber_rodent.vision.rendering.OmniRenderer`, all robots in one buffer) and segmented
with OpenCV (:class:`~cyber_rodent.vision.segmentation.OmniSegmenter`). Use it for videos,
behaviour checks and sim-to-real studies; long evolution runs use the geometric provider, which
``benchmarks/vision_agreement.py`` shows to agree with this one.
"""

from __future__ import annotations

import numpy as np

from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.detections import apply_noise, frame_from_detections
from cyber_rodent.vision.rendering import OmniRenderer
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import target_geometry
from cyber_rodent.vision.types import VisionFrame
from cyber_rodent.world import World


class RenderedVision:
    """Vision from rendered omni images and colour segmentation.

    Args:
        world: the world to observe (bound: every call renders its current state).
        config: the camera.
        rng: generator for the noise model; required only if ``config.noise`` is enabled.

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
    ):
        self.world = world
        self.config = config or CameraConfig()
        if self.config.noise.enabled and rng is None:
            raise ValueError("config.noise is enabled, so pass rng=np.random.Generator")
        self.rng = rng
        self.renderer = OmniRenderer(world, self.config)
        self.segmenter = OmniSegmenter(self.config, target_geometry(world))
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

    def __exit__(self, *exc) -> None:
        self.close()
