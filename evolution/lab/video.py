"""MP4 videos of a run, rendered off-screen, with a legend in every frame.

A frame is tiled, with no empty area, from these panels (:func:`frame_layout`):

- ``top`` (the default camera): the top-down field on the left; on the right, every robot's
  360° omni strip (what its camera sees, straight ahead in the middle) under a status line
  (agent, generation, energy, behaviour, LED, and at its right end the energy bar of the
  robot's label), then the legend.
- ``chase:N``: robot N's chase view (from behind and above) on the left; on the right, the
  top-down field, robot N's status line and omni strip, then the legend.
- ``omni:N``: robot N's status line and omni strip across the whole width; below, the top-down
  field, and on the right the other robots' strips (when they fit) and the legend.

The top-down field shows each robot's heading arrow (dark with a white edge, so that it reads on
the floor and on the white bodies) and a label (``CRi`` = robot index i, its behaviour in the
behaviour's colour, an energy bar); labels never overlap
(:func:`cyber_rodent.render.place_labels`) and get a leader line when moved off their robot. A
yellow ring marks a docked robot, a magenta line two robots at the moment they exchange genomes,
and a white ring the robot that ``chase:N`` or ``omni:N`` follows. The legend says all this in
the frame, under a line with the run, generation, time and control step. One frame per control
step at 5 fps is real time (a control step is 0.2 s by default).

The video continues the run from a checkpoint by stepping it (:func:`render_video`); the run
directory on disk is never modified. The MP4 (H.264 via imageio-ffmpeg's bundled ffmpeg) is
written to a temporary file and renamed when complete.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import cv2
import numpy as np

from cyber_rodent.atomic import atomic_output
from cyber_rodent.render import (
    BACKGROUND_RGB,
    ENERGY_RGB,
    FONT,
    HEADING_RGB,
    LABEL_BOX_RGB,
    LOW_ENERGY,
    LOW_ENERGY_RGB,
    OUTLINE_RGB,
    RGB,
    ROBOT_TOP_Z,
    FieldRenderer,
    RobotTag,
    annotate_world,
    check_writable_output,
    draw_caption,
    draw_heading,
    draw_text,
    fill_background,
    label_scale,
    text_scale,
    text_thickness,
)
from cyber_rodent.validation import check_integer, integer, validate_fields
from cyber_rodent.vision import CameraConfig
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.rendering import MAX_BUFFER_SIDE, OmniRenderer
from evolution.lab.api import CHECKPOINT_DIR, RUN_FILE
from evolution.runner import list_checkpoints

if TYPE_CHECKING:
    from evolution.runner import EvolutionRunner

#: Behaviour index → (label, RGB colour) for overlays; -1 = recharging, no behaviour.
BEHAVIOUR_STYLE = {
    0: ("Mate", (60, 220, 60)),
    1: ("Forage", (70, 130, 255)),
    2: ("Search", (200, 200, 200)),
    -1: ("Recharge", (255, 200, 40)),
}
DOCKED_RGB: RGB = (255, 200, 40)
MATING_RGB: RGB = (255, 60, 200)
FOLLOWED_RGB: RGB = (255, 255, 255)
PACK_RGB: RGB = (30, 40, 235)
LED_RGB: RGB = (40, 230, 40)
STATUS_RGB: RGB = (40, 44, 54)
LEGEND_RGB: RGB = (30, 33, 42)
MAX_FRAMES = 100_000
#: Frame size limits (px): a side column of at least MIN_COLUMN beside a field at least as wide
#: as the frame is tall, so the top-down field is never cropped.
MIN_HEIGHT, MAX_HEIGHT, MAX_WIDTH, MIN_COLUMN = 480, 2160, 3840, 256
#: Least height of an omni strip in a frame (px), and of the chase layout's top-down field.
MIN_STRIP, MIN_FIELD = 8, 120
#: The smallest font scale used (status lines shrink to it when many robots need the room).
SMALLEST_TEXT = 0.35
#: Most omni strips the top layout shows when not every robot's fits (the first ones).
MAX_STRIPS = 4

#: Most a strip is stretched vertically to fill spare room (beyond, the legend's rows spread).
MAX_STRETCH = 1.25
CAMERAS = ("top", "chase", "omni")
SIZE_RULE = (
    f"even W and H, H in [{MIN_HEIGHT}, {MAX_HEIGHT}] and W in [H + {MIN_COLUMN}, {MAX_WIDTH}]"
)


# --- options ---------------------------------------------------------------------------------
class Camera(NamedTuple):
    """What a frame's main panel shows: ``kind`` in :data:`CAMERAS`, ``robot`` for chase/omni."""

    kind: str
    robot: int | None = None

    def __str__(self) -> str:
        return self.kind if self.robot is None else f"{self.kind}:{self.robot}"


def parse_camera(text: str) -> Camera:
    """``"top"``, ``"chase:N"`` or ``"omni:N"`` (N a robot index, checked by
    :func:`check_camera_robot` once the robot count is known).

    Raises:
        ValueError: any other text.
    """
    match = re.fullmatch(r"\s*(top|chase|omni)\s*(?::\s*(\d+)\s*)?", str(text))
    if match is None or (match.group(1) == "top") != (match.group(2) is None):
        raise ValueError(
            f"--camera must be top, chase:N or omni:N (N a robot index in [0, robots - 1]), "
            f"got {text!r}"
        )
    robot = None if match.group(2) is None else int(match.group(2))
    return Camera(match.group(1), robot)


def check_camera_robot(camera: Camera, n_robots: int) -> None:
    """Raise ValueError unless ``camera`` follows a robot that exists."""
    if camera.robot is not None and not 0 <= camera.robot < n_robots:
        raise ValueError(
            f"--camera {camera.kind}:N needs a robot index N in [0, {n_robots - 1}] (the run "
            f"has {n_robots} robots), got {camera}"
        )


def check_frame_size(width: object, height: object) -> tuple[int, int]:
    """(width, height) if a frame of that size can be laid out; else ValueError naming --size."""
    if (
        isinstance(width, int | np.integer) and isinstance(height, int | np.integer)
        and not isinstance(width, bool) and not isinstance(height, bool)
        and width % 2 == 0 and height % 2 == 0 and MIN_HEIGHT <= height <= MAX_HEIGHT
        and height + MIN_COLUMN <= width <= MAX_WIDTH
    ):  # fmt: skip
        return int(width), int(height)
    raise ValueError(f"--size must be WxH with {SIZE_RULE}, got {width}x{height}")


def parse_size(text: str) -> tuple[int, int]:
    """``"1280x720"`` → (1280, 720), checked by :func:`check_frame_size`."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(text))
    if match is None:
        raise ValueError(f"--size must be WxH with {SIZE_RULE}, got {text!r}")
    return check_frame_size(int(match.group(1)), int(match.group(2)))


def parse_integer_option(name: str, text: str, low: int, high: float) -> int:
    """An integer option given as text, in [low, high], with the one-line rule message."""
    try:
        value: object = int(str(text).strip())
    except ValueError:
        value = text
    return check_integer(name, value, low, high)


def start_checkpoint(run_dir: str | os.PathLike[str], generation: int) -> Path:
    """The checkpoint a video with ``--start generation`` begins from: the one written when
    ``generation`` generations had completed.

    Raises:
        ValueError: the run directory kept no checkpoint of that generation; the message gives
            the generations it has.
    """

    kept = list_checkpoints(Path(run_dir) / CHECKPOINT_DIR)
    found = {int(p.stem.split("_")[-1]): p for p in kept}
    if generation in found:
        return found[generation]
    if not found:
        raise ValueError(f"{run_dir} has no checkpoint to render from (is it a run directory?)")
    have = sorted(found)
    contiguous = have == list(range(have[0], have[-1] + 1))
    allowed = f"in [{have[0]}, {have[-1]}]" if contiguous else f"one of {have}"
    raise ValueError(
        f"--start must be a generation whose checkpoint {run_dir} kept, {allowed}, got "
        f"{generation} (evolve with --keep-checkpoints 0 to keep every generation)"
    )


def run_robot_count(source: str | os.PathLike[str]) -> int | None:
    """The robot count that a run directory (or a checkpoint inside one) records in its
    ``run.json``; None when there is no readable record (the video checks it again)."""

    path = Path(source)
    run_dir = path if path.is_dir() else path.parent.parent
    try:
        count = json.loads((run_dir / RUN_FILE).read_text())["config"]["world"]["n_robots"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return count if isinstance(count, int) else None


@dataclass(frozen=True)
class VideoConfig:
    """How a video looks.

    Attributes:
        fps: frames per second of the MP4 (with ``steps_per_frame=1``, 5 is real time at the
            default 0.2 s control step, and the default 10 is twice real time).
        steps_per_frame: control steps between frames.
        width, height: frame size in pixels (see :data:`SIZE_RULE`).
        camera: ``"top"``, ``"chase:N"`` or ``"omni:N"`` (see the module docstring).
        mating_flash_frames: frames a mating line stays visible.
    """

    fps: int = integer(10, 1, 120)
    steps_per_frame: int = integer(1, 1, 1000)
    width: int = integer(1280, MIN_HEIGHT + MIN_COLUMN, MAX_WIDTH, unit="px")
    height: int = integer(720, MIN_HEIGHT, MAX_HEIGHT, unit="px")
    camera: str = "top"
    mating_flash_frames: int = integer(8, 0)

    def __post_init__(self) -> None:
        validate_fields(self)
        check_frame_size(self.width, self.height)
        parse_camera(self.camera)


# --- layout ----------------------------------------------------------------------------------
class Rect(NamedTuple):
    """A panel of a frame, in pixels."""

    x: int
    y: int
    w: int
    h: int

    @property
    def slices(self) -> tuple[slice, slice]:
        return slice(self.y, self.y + self.h), slice(self.x, self.x + self.w)


@dataclass(frozen=True)
class FrameLayout:
    """Where each panel of a frame goes; the panels tile the frame exactly.

    Attributes:
        field: the top-down field (always at least as wide as tall: never cropped).
        chase: the chase view (camera ``chase:N``), else None.
        cells: one robot's status line (``status_h`` tall, font ``status_scale``) over its
            omni strip, per robot in ``cell_robots``.
        legend: the legend, under a line on the run's state.
        scale: font scale of the legend and captions (from the frame height).
    """

    width: int
    height: int
    camera: Camera
    field: Rect
    chase: Rect | None
    cells: tuple[Rect, ...]
    cell_robots: tuple[int, ...]
    status_h: int
    legend: Rect
    scale: float
    status_scale: float

    @property
    def panels(self) -> list[Rect]:
        found = [self.field, *self.cells, self.legend]
        return found if self.chase is None else [self.chase, *found]


class LegendItem(NamedTuple):
    """One line of the legend: an icon (a small drawing of the overlay) and what it means."""

    icon: str
    rgb: RGB
    text: str


def legend_items(
    camera: Camera, strips: Sequence[int] | None = None, n_robots: int = 0
) -> list[LegendItem]:
    """The legend of a frame shown with ``camera``; ``strips``: the robots whose omni strips
    the side panel shows, when not all ``n_robots`` fit (a line says which)."""
    items = [LegendItem("swatch", rgb, text) for text, rgb in (
        ("Mate: seek a partner", BEHAVIOUR_STYLE[0][1]),
        ("Forage: seek a pack", BEHAVIOUR_STYLE[1][1]),
        ("Search: explore", BEHAVIOUR_STYLE[2][1]),
        ("Recharge: docked", BEHAVIOUR_STYLE[-1][1]),
    )]  # fmt: skip
    items += [
        LegendItem("label", (255, 255, 255), "CRi = robot i (chase:i)"),
        LegendItem("bar", ENERGY_RGB, "energy (red below 25 %)"),
        LegendItem("arrow", HEADING_RGB, "heading"),
        LegendItem("ring", DOCKED_RGB, "docked at a pack"),
        LegendItem("line", MATING_RGB, "mating: genome exchange"),
        LegendItem("disc", PACK_RGB, "battery pack"),
        LegendItem("dot", LED_RGB, "LED on (green)"),
    ]
    if camera.robot is not None:
        items.append(LegendItem("ring", FOLLOWED_RGB, f"robot followed (CR{camera.robot})"))
    items.append(LegendItem("strip", (255, 255, 255), "omni strip: 360 deg, ahead mid"))
    if strips is not None and len(strips) < n_robots:
        shown = f"CR{strips[0]}" if len(strips) == 1 else f"CR{strips[0]}-CR{strips[-1]}"
        items.append(LegendItem("strip", (255, 255, 255), f"strips: {shown} of {n_robots}"))
    return items


def _line_height(scale: float) -> int:
    (_, th), base = cv2.getTextSize("Ag", FONT, scale, text_thickness(scale))
    return th + base + max(4, round(th * 0.5))


def status_height(scale: float) -> int:
    return _line_height(scale) + 2


def _icon_width(line: int) -> int:
    return round(1.6 * line)


def _legend_geometry(width: int, items: Sequence[LegendItem], scale: float) -> tuple[int, int]:
    """(columns, least height in px) of the legend at ``width``."""
    line = _line_height(scale)
    pad = max(4, line // 3)
    icon = _icon_width(line)
    text_w = max(cv2.getTextSize(i.text, FONT, scale, text_thickness(scale))[0][0] for i in items)
    column = icon + text_w + 2 * pad
    columns = max(1, min(len(items), (width - pad) // column))
    rows = -(-len(items) // columns)
    return columns, pad + line + pad + rows * line + pad


def strip_ratio(camera: CameraConfig) -> float:
    """Height / width of an omni strip drawn with pixels that span the same angle both ways
    (so that it reads as a panorama)."""
    proj = OmniProjection(camera)
    aspect = proj.px_per_v / proj.px_per_u
    return camera.height / aspect / camera.strip_width


def _cell_height(n: int, width: int, room: int, status_h: int, ratio: float) -> int | None:
    """Height of each of ``n`` stacked cells in ``room`` px: the strip's natural height,
    stretched up to :data:`MAX_STRETCH` times to use spare room or squeezed to fit; None if a
    strip would be shorter than :data:`MIN_STRIP`."""
    natural = max(MIN_STRIP, round(width * ratio))
    if n == 0:
        return status_h + natural
    cell = min(room // n, status_h + round(MAX_STRETCH * natural))
    return cell if cell - status_h >= MIN_STRIP else None


def frame_layout(
    width: int, height: int, camera: Camera, n_robots: int, camera_config: CameraConfig
) -> FrameLayout:
    """Tile a ``width`` × ``height`` frame for ``camera`` and ``n_robots`` robots.

    Raises:
        ValueError: a bad size, a camera following a robot that does not exist, or a frame too
            small for the robots' strips (the message says the least height that works).
    """
    width, height = check_frame_size(width, height)
    check_camera_robot(camera, n_robots)
    layout = _tile(width, height, camera, n_robots, camera_config)
    if layout is not None:
        return layout
    for taller in range(height + 2, MAX_HEIGHT + 1, 2):
        wider = min(MAX_WIDTH, max(width, 2 * round(taller * 8 / 9)))  # 16:9 or wider
        if _tile(wider, taller, camera, n_robots, camera_config):
            raise ValueError(
                f"--size {width}x{height} is too small for {n_robots} robots with --camera "
                f"{camera}: H must be at least {taller} (e.g. --size {wider}x{taller})"
            )
    # No size shows every robot's strip (a large colony): the first MAX_STRIPS that fit.
    layout = _tile(width, height, camera, n_robots, camera_config, capped=True)
    if layout is not None:
        return layout
    raise ValueError(
        f"--camera {camera} cannot show {n_robots} robots in any --size ({SIZE_RULE}); use "
        "--camera chase:N or omni:N"
    )


def _tile(
    width: int,
    height: int,
    camera: Camera,
    n: int,
    camera_config: CameraConfig,
    capped: bool = False,
) -> FrameLayout | None:
    """The layout, with the status lines' font shrunk to the smallest if that makes the
    robots' strips fit; None if nothing fits."""
    scale = text_scale(height)
    for status_scale in (scale, SMALLEST_TEXT):
        layout = _tile_at(width, height, camera, n, camera_config, scale, status_scale, capped)
        if layout is not None:
            return layout
    return None


def _tile_at(
    width: int,
    height: int,
    camera: Camera,
    n: int,
    camera_config: CameraConfig,
    scale: float,
    status_scale: float,
    capped: bool = False,
) -> FrameLayout | None:
    status_h = status_height(status_scale)
    column = min(width - height, max(MIN_COLUMN, round(0.9 * height)))
    main = width - column
    _, need = _legend_geometry(column, legend_items(camera), scale)
    ratio = strip_ratio(camera_config)
    cells: list[Rect] = []
    robots: list[int] = []
    chase = None
    if camera.kind == "top":
        shown = n
        cell = _cell_height(n, column, height - need, status_h, ratio)
        if cell is None and capped:  # too many robots: the first MAX_STRIPS (or fewer) that fit
            robots = list(range(min(n, MAX_STRIPS)))
            _, need = _legend_geometry(column, legend_items(camera, robots, n), scale)
            for shown in range(min(n, MAX_STRIPS), 0, -1):
                cell = _cell_height(shown, column, height - need, status_h, ratio)
                if cell is not None:
                    break
            else:
                return None
        if cell is None:
            return None
        field = Rect(0, 0, main, height)
        robots = list(range(shown))
        cells = [Rect(main, k * cell, column, cell) for k in robots]
        legend = Rect(main, shown * cell, column, height - shown * cell)
    elif camera.kind == "chase":
        assert camera.robot is not None
        cell = status_h + round(column * ratio)
        side = min(column, height - cell - need)
        if side < MIN_FIELD:
            return None
        chase = Rect(0, 0, main, height)
        field = Rect(main, 0, column, side)
        robots = [camera.robot]
        cells = [Rect(main, side, column, cell)]
        legend = Rect(main, side + cell, column, height - side - cell)
    else:
        assert camera.robot is not None
        band = status_h + min(round(width * ratio), round(0.4 * height))
        lower = height - band
        if lower < need:
            return None
        field = Rect(0, band, main, lower)
        robots = [camera.robot]
        cells = [Rect(0, 0, width, band)]
        others = [i for i in range(n) if i != camera.robot]
        cell = _cell_height(len(others), column, lower - need, status_h, ratio)
        if cell is None:
            others, cell = [], 0
        robots += others
        cells += [Rect(main, band + k * cell, column, cell) for k in range(len(others))]
        top = band + len(others) * cell
        legend = Rect(main, top, column, height - top)
    return FrameLayout(
        width, height, camera, field, chase, tuple(cells), tuple(robots), status_h, legend,
        scale, status_scale,
    )  # fmt: skip


# --- drawing ---------------------------------------------------------------------------------
def draw_legend(
    image: np.ndarray, items: Sequence[LegendItem], scale: float, info_lines: int = 1
) -> None:
    """Draw ``items`` into ``image`` (the legend panel), below ``info_lines`` lines left free
    for the run's state."""
    image[:] = LEGEND_RGB
    height, width = image.shape[:2]
    columns, _ = _legend_geometry(width, items, scale)
    line = _line_height(scale)
    pad = max(4, line // 3)
    column_w = (width - pad) // columns
    top = pad + info_lines * line + pad
    rows = -(-len(items) // columns)
    # Spread the rows over spare height (up to 1.5 lines apart), so no empty band is left.
    pitch = max(line, min(round(1.5 * line), (height - top - pad) // rows))
    cv2.line(image, (pad, top - pad // 2), (width - pad, top - pad // 2), (80, 84, 96), 1)
    (_, th), _ = cv2.getTextSize("Ag", FONT, scale, text_thickness(scale))
    for k, item in enumerate(items):
        row, col = divmod(k, columns)
        x = pad + col * column_w
        y = top + row * pitch + (pitch - line) // 2
        if y + line > height:
            break
        icon = _icon_width(line)
        _draw_icon(image, item, (x, y), icon - pad, line, scale)
        draw_text(image, item.text, (x + icon, y + (line + th) // 2), scale, (230, 230, 230))


def _draw_icon(
    image: np.ndarray, item: LegendItem, at: tuple[int, int], w: int, h: int, scale: float
) -> None:
    x, y = at
    cy, cx = y + h // 2, x + w // 2
    r = max(3, h // 3)
    aa = cv2.LINE_AA
    if item.icon == "swatch":
        cv2.rectangle(image, (x + 2, y + 3), (x + w - 2, y + h - 4), item.rgb, -1)
    elif item.icon == "label":
        cv2.rectangle(image, (x + 1, y + 2), (x + w - 1, y + h - 3), LABEL_BOX_RGB, -1)
        cv2.rectangle(image, (x + 1, y + 2), (x + w - 1, y + h - 3), item.rgb, 1)
        s = scale * 0.7
        draw_text(image, "CR", (x + 4, cy + round(5 * s / 0.35)), s, item.rgb)
    elif item.icon == "bar":
        third = (w - 4) // 3
        cv2.rectangle(image, (x + 2, cy - 3), (x + w - 2, cy + 3), (70, 70, 70), -1)
        cv2.rectangle(image, (x + 2, cy - 3), (x + 2 + 2 * third, cy + 3), item.rgb, -1)
        cv2.rectangle(image, (x + 2 + 2 * third, cy - 3), (x + w - 2, cy + 3), LOW_ENERGY_RGB, -1)
    elif item.icon == "arrow":
        draw_heading(image, np.array([x + 3, cy]), 0.0, w - 6, max(1, round(scale * 4)))
    elif item.icon == "ring":
        cv2.circle(image, (cx, cy), r + 1, item.rgb, 2, aa)
    elif item.icon == "line":
        cv2.line(image, (x + 2, cy + r), (x + w - 2, cy - r), item.rgb, 3, aa)
    elif item.icon == "disc":
        cv2.circle(image, (cx, cy), r, item.rgb, -1, aa)
    elif item.icon == "dot":
        cv2.circle(image, (cx, cy), max(2, r // 2 + 1), item.rgb, -1, aa)
    elif item.icon == "strip":
        cv2.rectangle(image, (x + 1, y + 3), (x + w - 1, y + h - 4), (120, 120, 120), 1)
        cv2.line(image, (cx, y + 3), (cx, y + h - 4), item.rgb, 1)


def _fit(parts: Sequence[str], width: int, scale: float) -> str:
    """As many of ``parts`` (most important first) as fit in ``width`` px on one line."""
    text = parts[0]
    for part in parts[1:]:
        longer = f"{text}  {part}"
        if cv2.getTextSize(longer, FONT, scale, text_thickness(scale))[0][0] > width:
            break
        text = longer
    return text


class RunVideo:
    """Renders frames of a running :class:`EvolutionRunner`.

    Raises:
        ValueError: ``config.camera`` follows a robot the run does not have, or the frame is
            too small for the run's robots.
    """

    def __init__(self, runner: EvolutionRunner, config: VideoConfig | None = None):
        self.runner = runner
        self.config = config or VideoConfig()
        world = runner.world
        n = world.config.n_robots
        self.n = n
        self.camera = parse_camera(self.config.camera)
        self.camera_config = runner.config.camera
        self.layout = frame_layout(
            self.config.width, self.config.height, self.camera, n, self.camera_config
        )
        self.width, self.height = self.layout.width, self.layout.height
        proj = OmniProjection(self.camera_config)
        self._recentre = self.camera_config.strip_width // 2 - int(
            np.argmin(np.abs(proj.column_bearing))
        )
        self.items = legend_items(self.camera, self.layout.cell_robots, n)
        self.field = FieldRenderer(
            world, self.layout.field.w, self.layout.field.h, background=BACKGROUND_RGB
        )
        self._px_per_m = self.field.metres_to_px()
        self.chase = None
        if self.layout.chase is not None:
            self.chase = FieldRenderer(
                world, self.layout.chase.w, self.layout.chase.h, background=BACKGROUND_RGB
            )
        # Every robot's strip is rendered into one buffer; a large colony's get fewer rows
        # (only the shown strips are drawn, scaled to their cells, so the frame looks the same).
        rows = max(1, MAX_BUFFER_SIDE // n)
        strips = self.camera_config
        if strips.height > rows:
            strips = dataclasses.replace(strips, height=rows)
        self.omni = OmniRenderer(world, strips)
        legend = self.layout.legend
        self._legend = np.empty((legend.h, legend.w, 3), dtype=np.uint8)
        draw_legend(self._legend, self.items, self.layout.scale)
        self._flash: list[tuple[int, int, int]] = []  # (robot a, robot b, frames left)
        #: The label boxes of the last frame's field panel (panel pixels), None if none fit.
        self.label_boxes: np.ndarray | None = None

    def advance(self) -> None:
        """Step the run by ``steps_per_frame`` control steps, remembering matings to draw."""
        survival = self.runner.survival
        for _ in range(self.config.steps_per_frame):
            self.runner.step()
            partner = survival.events.mate_partner
            for a in np.flatnonzero(partner >= 0).tolist():
                b = int(partner[a])
                if a < b:
                    self._flash.append((a, b, self.config.mating_flash_frames))

    def frame(self) -> np.ndarray:
        """The current frame, (height, width, 3) uint8 RGB."""
        layout = self.layout
        out = np.zeros((self.height, self.width, 3), dtype=np.uint8)
        out[layout.field.slices] = self._field_panel()
        if layout.chase is not None:
            out[layout.chase.slices] = self._chase_panel()
        if layout.cells:
            strips = self.omni.render()
            for rect, i in zip(layout.cells, layout.cell_robots, strict=True):
                out[rect.slices] = self._cell(i, rect, strips[i])
        out[layout.legend.slices] = self._legend_panel()
        return out

    def _behaviour(self) -> np.ndarray:
        runner = self.runner
        shown = runner.controller.behaviour.astype(np.int64)  # the last step's choice
        shown[runner.survival.docked] = -1
        return shown

    def _field_panel(self) -> np.ndarray:
        runner, world = self.runner, self.runner.world
        image = self.field.top_down()
        top = np.column_stack([world.poses()[:, :2], np.full(self.n, ROBOT_TOP_Z)])
        ends = self.field.project_top_down(top).round().astype(int)
        behaviour = self._behaviour()
        max_energy = runner.survival.config.max_energy
        ppm = self._px_per_m
        thick = max(2, round(0.012 * ppm))
        for a, b, _ in self._flash:
            cv2.line(image, tuple(ends[a]), tuple(ends[b]), MATING_RGB, thick, cv2.LINE_AA)
        self._flash = [(a, b, k - 1) for a, b, k in self._flash if k > 1]
        for i in np.flatnonzero(runner.survival.docked).tolist():
            cv2.circle(image, tuple(ends[i]), round(0.16 * ppm), DOCKED_RGB, thick, cv2.LINE_AA)
        if self.camera.robot is not None:
            centre = tuple(ends[self.camera.robot])
            cv2.circle(image, centre, round(0.2 * ppm), OUTLINE_RGB, thick + 2, cv2.LINE_AA)
            cv2.circle(image, centre, round(0.2 * ppm), FOLLOWED_RGB, thick, cv2.LINE_AA)
        tags = []
        for i in range(self.n):
            label, rgb = BEHAVIOUR_STYLE[int(behaviour[i])]
            energy = float(runner.survival.energy[i]) / max_energy
            tags.append(RobotTag(f"CR{i} {label}", rgb, energy))
        # Labels no larger than the robots (as in the snapshot), so a large colony's stay apart.
        scale = min(self.layout.scale, label_scale(image.shape[0], ppm))
        self.label_boxes = annotate_world(image, self.field, tags, scale)
        return image

    def _chase_panel(self) -> np.ndarray:
        assert self.chase is not None and self.camera.robot is not None
        i = self.camera.robot
        image = self.chase.robot_view(i)
        label, _ = BEHAVIOUR_STYLE[int(self._behaviour()[i])]
        energy = float(self.runner.survival.energy[i])
        draw_caption(image, f"CR{i} chase view  {label}  energy {energy:.0f}", self.layout.scale)
        return image

    def _cell(self, i: int, rect: Rect, strip: np.ndarray) -> np.ndarray:
        cell = np.empty((rect.h, rect.w, 3), dtype=np.uint8)
        status_h = self.layout.status_h
        cell[:status_h] = self._status_line(i, rect.w)
        view = fill_background(np.roll(strip, self._recentre, axis=1), BACKGROUND_RGB)
        shrink = rect.w < view.shape[1]
        cell[status_h:] = cv2.resize(
            view,
            (rect.w, rect.h - status_h),
            interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR,
        )
        return cell

    def _status_line(self, i: int, width: int) -> np.ndarray:
        runner = self.runner
        scale = self.layout.status_scale
        line = np.empty((self.layout.status_h, width, 3), dtype=np.uint8)
        line[:] = STATUS_RGB
        sched = runner.scheduler
        slot = int(sched.active_slot[i])
        generation = int(sched.slot_generation[i, slot])
        label, rgb = BEHAVIOUR_STYLE[int(self._behaviour()[i])]
        energy = float(runner.survival.energy[i])
        led = "LED on" if runner.world.led_on[i] else "LED off"
        parts = [f"CR{i}", label, f"energy {energy:.0f}", f"agent {slot}", f"gen {generation}", led]
        if self.camera.kind == "omni" and i == self.camera.robot:
            parts.append("360 deg camera, straight ahead in the middle")
        pad = max(4, self.layout.status_h // 5)
        # The energy bar at the line's right end, drawn like the labels' bars and the legend's
        # "energy" icon: a grey track, filled green (red below LOW_ENERGY); the same length on
        # every line, so the robots' bars compare.
        bar_w = 2 * self.layout.status_h
        text = _fit(parts, width - 3 * pad - bar_w, scale)
        (_, th), _ = cv2.getTextSize(text, FONT, scale, text_thickness(scale))
        y = (self.layout.status_h + th) // 2
        fraction = min(1.0, max(0.0, energy / runner.survival.config.max_energy))
        bar_h = max(3, round(th * 0.45))
        x0, x1 = width - pad - bar_w, width - pad - 1
        top = y - (th + bar_h) // 2
        cv2.rectangle(line, (x0, top), (x1, top + bar_h - 1), (70, 70, 70), -1)
        fill = round(bar_w * fraction)
        colour = ENERGY_RGB if fraction > LOW_ENERGY else LOW_ENERGY_RGB
        if fill:
            cv2.rectangle(line, (x0, top), (x0 + fill - 1, top + bar_h - 1), colour, -1)
        draw_text(line, text, (pad, y), scale, rgb)
        return line

    def _legend_panel(self) -> np.ndarray:
        image = self._legend.copy()
        runner = self.runner
        scale = self.layout.scale
        line = _line_height(scale)
        pad = max(4, line // 3)
        info = [
            f"{runner.config.method.upper()} seed {runner.seed}",
            f"generation {runner.completed_generations}",
            f"t = {runner.world.data.time:.1f} s",
            f"step {runner.steps}",
        ]
        (_, th), _ = cv2.getTextSize("Ag", FONT, scale, text_thickness(scale))
        text = _fit(info, image.shape[1] - 2 * pad, scale)
        draw_text(image, text, (pad, pad + (line + th) // 2), scale, (255, 255, 255))
        return image

    def close(self) -> None:
        self.field.close()
        if self.chase is not None:
            self.chase.close()
        self.omni.close()


def render_video(
    runner: EvolutionRunner,
    out_path: str | os.PathLike[str],
    frames: int,
    config: VideoConfig | None = None,
    progress: bool = True,
) -> Path:
    """Continue ``runner`` for ``frames`` frames and write them as an MP4.

    Raises:
        ValueError: a bad frame count or config, an unwritable output path, or a camera or
            size that does not suit the run's robots (all checked before any file is created).
    """
    import imageio.v2 as imageio

    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_FRAMES:
        raise ValueError(f"frames must be an integer in [1, {MAX_FRAMES}], got {frames!r}")
    config = config or VideoConfig()
    out = check_writable_output(out_path)
    if out.suffix.lower() != ".mp4":
        raise ValueError(f"video output must be an .mp4 file, got {out.name}")
    video = RunVideo(runner, config)
    try:
        with atomic_output(out) as temp:
            writer = imageio.get_writer(
                str(temp),
                format="FFMPEG",
                fps=config.fps,
                codec="libx264",
                quality=7,
                macro_block_size=2,  # sizes are even; H.264 with yuv420p needs no more
                pixelformat="yuv420p",
            )
            bar = None
            if progress:
                from cyber_rodent.progress import progress_bar

                bar = progress_bar(
                    total=frames, unit="frame", desc=f"render {out.name}", dynamic_ncols=True
                )
            try:
                for _ in range(frames):
                    video.advance()
                    writer.append_data(video.frame())
                    if bar is not None:
                        bar.update()
            finally:
                writer.close()
                if bar is not None:
                    bar.close()
    finally:
        video.close()
    return out
