"""Save one robot's omni image and its colour segmentation as a PNG (``cyber-rodent snapshot``).

The PNG stacks two panels of the same 360° strip: the rendered image, and the segmentation
overlay (class masks painted in pure green / red / blue over a dimmed copy). The overlay is cut
a little below its lowest detected pixel, so it ends where its content does; under it, each
blob's class, distance and pixel area stand in rows of labels, each joined to its blob by a
leader line in the class's colour (:func:`place_strip_labels`: no two labels overlap, none
covers a blob, all lie inside the image, and a leader passes behind a label only where blobs
crowd too tightly for every plan it tries). The strip is rolled so that straight ahead is in
the middle (bearing +180° at the left edge, −180° at the right), and scaled up with square
pixels in angle, so the picture reads like a panorama.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from cyber_rodent.atomic import atomic_output
from cyber_rodent.vision.config import CameraConfig
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.vision.types import CLASS_NAMES, VisionFrame
from cyber_rodent.world import World

#: Overlay colours (RGB) of the classes LED, FACE, BATTERY, and of their leader lines (a
#: shade darker, so that a leader never passes for segmented pixels).
_CLASS_RGB = ((40, 255, 40), (255, 40, 40), (60, 120, 255))
_LEADER_RGB = tuple(tuple(round(0.8 * c) for c in rgb) for rgb in _CLASS_RGB)
_MIN_WIDTH = 1024  # px, the PNG is scaled up to at least this width
#: Blob labels: font, rows (px), the gap between a leader and its label's text, and the least
#: horizontal room between two labels of a row (px).
_LABEL_FONT, _LABEL_SCALE = cv2.FONT_HERSHEY_SIMPLEX, 0.4
_LABEL_ROW = 16
_LEADER_GAP = 3
_LABEL_SPACE = 8
#: Most splits of the labels that :func:`place_strip_labels` tries (evenly spaced).
_MAX_CUTS = 12


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
        expected: extra (bearing, class, label) marks: a tick on the image panel's top edge
            and the label above the panel, e.g. where the geometric provider expects targets.
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

    # The overlay ends a little below its lowest class pixel (at least below the horizon).
    rows = np.flatnonzero(masks.any(axis=(0, 2)))
    horizon = math.ceil(proj.v_top * proj.px_per_v)
    margin = max(2, config.height // 24)
    content = max(int(rows[-1]) + 1 if len(rows) else 0, horizon)
    bottom = bottom[: min(config.height, content + margin) * scale_y]
    rolled = np.roll(masks, shift, axis=2)
    blobs = sorted(frame.blobs[robot], key=lambda b: column_of(b.bearing))
    labels = [f"{CLASS_NAMES[b.cls]} {b.distance:.2f}m {int(b.area)}px" for b in blobs]
    xs = [column_of(b.bearing) for b in blobs]
    widths = [cv2.getTextSize(t, _LABEL_FONT, _LABEL_SCALE, 1)[0][0] for t in labels]
    places = place_strip_labels(xs, widths, width)
    n_rows = 1 + max((row for row, _ in places), default=0)
    band = np.zeros((8 + _LABEL_ROW * n_rows, width, 3), dtype=np.uint8)
    if not blobs:
        cv2.putText(
            band, "no blobs detected", (4, 4 + _LABEL_ROW - 4), _LABEL_FONT, _LABEL_SCALE,
            (200, 200, 200), 1, cv2.LINE_AA,
        )  # fmt: skip
    # Leaders first: down from the blob's lowest pixel in its column, through the dimmed floor
    # (the class pixels are painted again over them) to the label's row.
    for x, blob, (row, _) in zip(xs, blobs, places, strict=True):
        shade = _LEADER_RGB[blob.cls]
        in_column = np.flatnonzero(rolled[blob.cls, :, x // scale_x])
        lowest = bottom.shape[0] - 1
        start = min((int(in_column[-1]) + 1) * scale_y, lowest) if len(in_column) else lowest
        cv2.line(bottom, (x, start), (x, lowest), shade, 1)
        cv2.line(band, (x, 0), (x, 4 + _LABEL_ROW * row + _LABEL_ROW // 2), shade, 1)
    kept = cv2.resize(
        rolled.transpose(1, 2, 0).astype(np.uint8),
        size, interpolation=cv2.INTER_NEAREST,
    )[: bottom.shape[0]]  # fmt: skip
    for c, rgb in enumerate(_CLASS_RGB):
        bottom[kept[..., c] > 0] = rgb
    # Then the labels, each on a dark box (a leader that must pass one goes behind it).
    for x, blob, label, w_text, (row, left) in zip(
        xs, blobs, labels, widths, places, strict=True
    ):
        rgb = _CLASS_RGB[blob.cls]
        y_mid = 4 + _LABEL_ROW * row + _LABEL_ROW // 2
        cv2.rectangle(band, (left - 1, y_mid - 7), (left + w_text, y_mid + 6), (0, 0, 0), -1)
        if not left <= x <= left + w_text:  # a short foot from the leader to the text
            foot = left - 1 if left > x else left + w_text
            cv2.line(band, (x, y_mid), (foot, y_mid), _LEADER_RGB[blob.cls], 1)
        cv2.putText(
            band, label, (left, y_mid + 4), _LABEL_FONT, _LABEL_SCALE, rgb, 1, cv2.LINE_AA
        )
    # Extra marks: a tick on the image panel's top edge, the label in a band above the panel
    # (laid out like the blob labels, upside down: row 0 nearest the image).
    marks = sorted(expected, key=lambda m: column_of(m[0]))
    mark_xs = [column_of(bearing) for bearing, _, _ in marks]
    mark_widths = [cv2.getTextSize(t, _LABEL_FONT, _LABEL_SCALE, 1)[0][0] for _, _, t in marks]
    mark_places = place_strip_labels(mark_xs, mark_widths, width)
    mark_rows = 1 + max((row for row, _ in mark_places), default=-1)
    above = np.zeros((4 + _LABEL_ROW * mark_rows if marks else 0, width, 3), dtype=np.uint8)
    white = (255, 255, 255)

    def mark_y(row: int) -> int:
        return above.shape[0] - 4 - _LABEL_ROW * row - _LABEL_ROW // 2

    tick = max(3, horizon * scale_y - 3)  # ends above the horizon, clear of far targets
    for x, (_, cls, _), (row, _) in zip(mark_xs, marks, mark_places, strict=True):
        cv2.line(top, (x, 0), (x, tick), white, 3)
        cv2.line(top, (x, 0), (x, tick), _CLASS_RGB[cls], 1)
        cv2.line(above, (x, above.shape[0] - 1), (x, mark_y(row)), white, 1)
    for x, (_, _, label), w_text, (row, left) in zip(
        mark_xs, marks, mark_widths, mark_places, strict=True
    ):
        y_mid = mark_y(row)
        cv2.rectangle(above, (left - 1, y_mid - 7), (left + w_text, y_mid + 6), (0, 0, 0), -1)
        if not left <= x <= left + w_text:
            cv2.line(above, (x, y_mid), (left - 1 if left > x else left + w_text, y_mid), white, 1)
        cv2.putText(above, label, (left, y_mid + 4), _LABEL_FONT, _LABEL_SCALE, white, 1,
                    cv2.LINE_AA)  # fmt: skip
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
    return np.concatenate([header, above, top, gap, bottom, band], axis=0)


def place_strip_labels(
    xs: Sequence[int], widths: Sequence[int], width: int
) -> list[tuple[int, int]]:
    """Rows and left edges for labels hung from columns ``xs`` of an image ``width`` px wide.

    Each label ``i`` (``widths[i]`` px of text) hangs from a vertical leader at ``xs[i]`` that
    runs down from the top of the label band to its row. A label starts just right of its
    leader or ends just left of it, whichever the image has room for (only a label wider than
    either side is shifted to fit, its leader then ending on its top edge). It takes the first
    row where it overlaps no label of that row (with :data:`_LABEL_SPACE` between), no leader
    crosses it and its own leader crosses no label above, so a run of close blobs makes a
    staircase. Only if no row allows that does a label go below the others, its leader passing
    behind a label.

    Several plans are tried. Labels right of their leaders, placed right to left; left of them,
    placed left to right; and splits of the labels into those left and right of a column (up to
    :data:`_MAX_CUTS` splits, evenly spaced), the left ones pointing left and the right ones
    right (their leaders can then never cross the other side's labels), or the other way round.
    Each plan is also tried letting a label take the other side where that fits an earlier row.
    The layout with the fewest crossings, then the fewest rows, is kept, after moving each
    label, deepest first, to the earliest row and side where it still breaks none of the rules.

    Returns:
        (row, left) per label, rows from 0 (the top one), every label inside the image.
    """
    n = len(xs)
    by_x = sorted(range(n), key=lambda k: (xs[k], k))
    plans: list[tuple[list[int], dict[int, bool]]] = [
        (by_x[::-1], dict.fromkeys(by_x, True)),
        (by_x, dict.fromkeys(by_x, False)),
    ]
    for cut in sorted({round(n * k / _MAX_CUTS) for k in range(_MAX_CUTS + 1)}):
        left_part, right_part = by_x[:cut], by_x[cut:]
        outward = {**dict.fromkeys(left_part, False), **dict.fromkeys(right_part, True)}
        plans.append((left_part + right_part[::-1], outward))
        inward = {**dict.fromkeys(left_part, True), **dict.fromkeys(right_part, False)}
        plans.append((left_part[::-1] + right_part, inward))
    best: tuple[tuple[int, int], list[tuple[int, int]]] | None = None
    for order, right_first in plans:
        for either in (False, True):
            crossings, places = _stack_labels(xs, widths, width, order, right_first, either)
            rows = 1 + max((row for row, _ in places), default=0)
            if best is None or (crossings, rows) < best[0]:
                best = ((crossings, rows), places)
    assert best is not None
    return best[1]


def _stack_labels(
    xs: Sequence[int],
    widths: Sequence[int],
    width: int,
    order: Sequence[int],
    right_first: dict[int, bool],
    either: bool,
) -> tuple[int, list[tuple[int, int]]]:
    """One greedy pass of :func:`place_strip_labels` in ``order``: each label on the side of its
    leader that ``right_first`` says, on the other side only where the image leaves no room or,
    if ``either``, where that fits an earlier row; then compacted. Returns the number of leaders
    that pass behind a label, and (row, left) per label."""
    placed: dict[int, tuple[int, int, int, int]] = {}  # label -> (row, left, right, x)
    options: dict[int, list[int]] = {}  # label -> the left edges that fit the image
    for k in order:
        x, w = int(xs[k]), int(widths[k])
        right_of, left_of = x + _LEADER_GAP, x - _LEADER_GAP - w
        sides = [a for a in (right_of, left_of) if 1 <= a and a + w <= width - 1]
        if not right_first[k]:
            sides.reverse()
        if not sides:  # wider than either side: shifted to fit, centred on its leader
            sides = [min(max(x - w // 2, 1), max(1, width - 1 - w))]
        options[k] = sides
        if not either:
            sides = sides[:1]
        deepest = max((r for r, _, _, _ in placed.values()), default=-1)
        choice = next(
            ((row, left) for row in range(deepest + 2) for left in sides
             if _fits(placed.values(), row, left, w, x)),
            (deepest + 1, sides[0]),
        )  # fmt: skip
        placed[k] = (choice[0], choice[1], choice[1] + w, x)
    moved = True
    while moved:  # compact: labels up into earlier rows where the rules allow
        moved = False
        for k in sorted(placed, key=lambda j: (-placed[j][0], j)):
            row, _, _, x = placed[k]
            w = int(widths[k])
            others = [v for j, v in placed.items() if j != k]
            spot = next(
                ((r, left) for r in range(row) for left in options[k]
                 if _fits(others, r, left, w, x)),
                None,
            )  # fmt: skip
            if spot is not None:
                placed[k] = (spot[0], spot[1], spot[1] + w, x)
                moved = True
    crossings = sum(
        1
        for row, _, _, x in placed.values()
        for r, left, right, _ in placed.values()
        if r < row and left - 1 <= x <= right + 1
    )
    return crossings, [(placed[k][0], placed[k][1]) for k in range(len(xs))]


def _fits(
    placed: Iterable[tuple[int, int, int, int]], row: int, left: int, w: int, x: int
) -> bool:
    """Can a label ``w`` px wide start at ``left`` in ``row``, its leader at column ``x``, among
    the ``placed`` labels (row, left, right, leader column)?"""
    right = left + w
    for r, p_left, p_right, p_x in placed:
        if r == row and left < p_right + _LABEL_SPACE and p_left < right + _LABEL_SPACE:
            return False  # overlaps a label of the row
        if r > row and left - 1 <= p_x <= right + 1:
            return False  # a deeper label's leader would cross it
        if r < row and p_left - 1 <= x <= p_right + 1:
            return False  # its leader would cross a label above
    return True
