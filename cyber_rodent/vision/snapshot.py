"""Save one robot's omni image and its colour segmentation as a PNG (``cyber-rodent snapshot``).

The PNG stacks two panels of the same 360° strip: the rendered image, and the segmentation
overlay (class masks painted in pure green / red / blue over a dimmed copy, each blob marked at
its bearing with its class, distance and pixel area). The strip is rolled so that straight
ahead is in the middle (bearing +180° at the left edge, −180° at the right), and scaled up with
square pixels in angle, so the picture reads like a panorama.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from cyber_rodent.atomic import atomic_output
from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.vision.types import CLASS_NAMES, VisionFrame
from cyber_rodent.world import World

#: Overlay colours (RGB) of the classes LED, FACE, BATTERY.
_CLASS_RGB = ((40, 255, 40), (255, 40, 40), (60, 120, 255))
_MIN_WIDTH = 1024  # px, the PNG is scaled up to at least this width


def save_omni_png(
    world: World, robot: int, out_path: str | Path, config: CameraConfig | None = None
) -> Path:
    """Render ``robot``'s omni strip in the world's current state and save it with its
    segmentation overlay as one PNG.

    Args:
        world: the world (its current ``MjData`` state is rendered; nothing is stepped).
        robot: index of the robot whose camera to show.
        out_path: where to write the PNG (parent directories are created).
        config: the camera (default: the world's field's, :func:`camera_for_field`).

    Returns:
        The path written.

    Raises:
        ValueError: if ``robot`` is not a robot of the world.
    """
    n = world.config.n_robots
    if not isinstance(robot, int | np.integer) or not 0 <= int(robot) < n:
        raise ValueError(f"robot must be an integer in [0, {n - 1}], got {robot!r}")
    robot = int(robot)
    with RenderedVision(world, config) as vision:
        frame = vision.observe()
        strips, all_masks = vision.last_strips, vision.last_masks
        if strips is None or all_masks is None:
            raise RuntimeError("the rendered provider kept no image of its observation")
        strip = strips[robot].copy()
        masks = all_masks[:, robot].copy()
        image = compose_omni_panels(strip, masks, frame, robot, vision)
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(out) as temp:
        if not cv2.imwrite(str(temp), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
            raise OSError(f"could not write {out}")
    return out


def compose_omni_panels(
    strip: np.ndarray,
    masks: np.ndarray,
    frame: VisionFrame,
    robot: int,
    vision: RenderedVision,
    expected: Sequence[tuple[float, int, str]] = (),
    title: str = "",
) -> np.ndarray:
    """The two stacked panels (RGB uint8) for one robot: image, and segmentation overlay.

    Args:
        strip, masks: the robot's RGB strip and its (3, height, width) class masks.
        frame: the rendered frame whose blobs label the overlay.
        robot: the robot's index.
        vision: the rendered provider (projection and camera).
        expected: extra (bearing, class, label) marks drawn on the image panel, e.g. where the
            geometric provider expects targets.
        title: replaces the header line's text.
    """
    proj = vision.projection
    config = vision.config
    overlay = (strip.astype(np.float32) * 0.35).astype(np.uint8)
    for c, rgb in enumerate(_CLASS_RGB):
        overlay[masks[c] > 0] = rgb
    # Roll so that bearing 0 is the middle column (the strip starts at bearing π + π/n).
    shift = config.strip_width // 2 - int(np.argmin(np.abs(proj.column_bearing)))
    strip = np.roll(strip, shift, axis=1)
    overlay = np.roll(overlay, shift, axis=1)
    # Square pixels in angle, then at least _MIN_WIDTH wide.
    aspect = proj.px_per_v / proj.px_per_u  # horizontal / vertical angular size of a pixel
    scale_x = max(1, math.ceil(_MIN_WIDTH / config.strip_width))
    scale_y = max(1, round(scale_x / aspect)) if aspect > 1 else scale_x
    scale_x = max(1, round(scale_y * aspect))
    size = (config.strip_width * scale_x, config.height * scale_y)
    top = cv2.resize(strip, size, interpolation=cv2.INTER_NEAREST)
    bottom = cv2.resize(overlay, size, interpolation=cv2.INTER_NEAREST)
    width = size[0]

    def column_of(bearing: float) -> int:
        col = int(np.argmin(np.abs(np.angle(np.exp(1j * (proj.column_bearing - bearing))))))
        return ((col + shift) % config.strip_width) * scale_x + scale_x // 2

    # Blob labels, left to right, on staggered lines so that neighbours do not overlap.
    marks = sorted(((column_of(b.bearing), b) for b in frame.blobs[robot]), key=lambda m: m[0])
    line_end = [-1] * 6
    for x, blob in marks:
        rgb = _CLASS_RGB[blob.cls]
        cv2.line(bottom, (x, 0), (x, 10), rgb, 2)
        label = f"{CLASS_NAMES[blob.cls]} {blob.distance:.2f}m {int(blob.area)}px"
        (w_text, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
        left = min(x + 3, width - w_text - 2)
        line = next((k for k, end in enumerate(line_end) if end < left), len(line_end) - 1)
        line_end[line] = left + w_text + 4
        cv2.putText(
            bottom,
            label,
            (left, 24 + 15 * line),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.4,
            rgb,
            1,
            cv2.LINE_AA,
        )
    # Extra marks on the image panel, from its top edge, staggered like the blob labels.
    line_end = [-1] * 4
    for bearing, cls, label in sorted(expected, key=lambda m: column_of(m[0])):
        x = column_of(bearing)
        rgb = _CLASS_RGB[cls]
        cv2.line(top, (x, 0), (x, 12), (255, 255, 255), 3)
        cv2.line(top, (x, 0), (x, 12), rgb, 1)
        (w_text, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
        left = min(x + 3, width - w_text - 2)
        line = next((k for k, end in enumerate(line_end) if end < left), len(line_end) - 1)
        line_end[line] = left + w_text + 4
        cv2.putText(
            top, label, (left, 12 + 14 * line), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
            (255, 255, 255), 1, cv2.LINE_AA,
        )  # fmt: skip
    # Bearing ticks every 45° on the image panel.
    for deg in range(-180, 181, 45):
        x = column_of(math.radians(deg)) if abs(deg) < 180 else (0 if deg > 0 else width - 1)
        cv2.line(top, (x, size[1] - 8), (x, size[1] - 1), (255, 255, 0), 1)
        cv2.putText(
            top,
            f"{deg:+d}",
            (min(max(x - 14, 0), width - 36), size[1] - 10),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.4,
            (255, 255, 0),
            1,
            cv2.LINE_AA,
        )
    header = np.zeros((20, width, 3), dtype=np.uint8)
    cv2.putText(
        header,
        title
        or (
            f"robot {robot}: omni image (top), segmentation (bottom); "
            f"front = centre, left of centre = robot's left"
        ),
        (4, 14),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (255, 255, 255),
        1,
        cv2.LINE_AA,
    )
    gap = np.full((4, width, 3), 255, dtype=np.uint8)
    return np.concatenate([header, top, gap, bottom], axis=0)
