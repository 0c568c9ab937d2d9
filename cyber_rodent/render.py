"""Off-screen rendering of the field: a top-down view and a per-robot chase view, and the
annotations drawn on them (robot IDs, heading arrows, labels that never overlap).

Rendering is real OpenGL through ``mujoco.Renderer`` on a headless context (EGL by default, see
``cyber_rodent/__init__.py``). Settings follow what is fast under Mesa's software rasteriser
(docs/design.md §6): no shadows, no reflections, no skybox, no anti-aliasing
(``offsamples=0`` in the arena), untextured surfaces. Sites, rangefinder rays and the wheels'
collision spheres are hidden. With the skybox off, empty space renders pure black; a renderer
given a ``background`` colour paints it instead, so that pictures have no dead black areas.

Labels are placed by :func:`place_labels`, which guarantees that no two label boxes intersect
whatever the robot positions (robots parked around one pack included): it tries spots around
each robot, then the nearest free spot anywhere in the image, then a tidy grid of cells, and
reports failure (None) only when the image cannot hold the labels at all.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.atomic import atomic_output
from cyber_rodent.world import World

#: Geom group of collision-only helper geoms (the wheels' contact spheres): hidden in images.
COLLISION_ONLY_GROUP = 3
MAX_IMAGE_SIDE = 4096

RGB = tuple[int, int, int]
#: A box (x0, y0, x1, y1) in pixels, x1 and y1 exclusive.
Box = Sequence[float] | np.ndarray
#: Empty space (around the field, the sky in side views): a dark slate rather than black.
BACKGROUND_RGB: RGB = (58, 64, 76)
#: Heading arrows: near-black with a white edge, readable on the grey floor and on the white
#: robot bodies they mostly lie on.
HEADING_RGB: RGB = (16, 16, 20)
HEADING_EDGE_RGB: RGB = (255, 255, 255)
#: Dark outlines that keep light marks (leader lines, rings) apart from what lies under them.
OUTLINE_RGB: RGB = (16, 16, 20)
#: Label boxes: light text on a dark box, with a thin leader line when moved off the robot.
LABEL_BOX_RGB: RGB = (22, 24, 30)
LEADER_RGB: RGB = (235, 235, 235)
#: Energy bars: green, red below :data:`LOW_ENERGY` of the maximum.
ENERGY_RGB: RGB = (60, 200, 60)
LOW_ENERGY_RGB: RGB = (230, 60, 40)
LOW_ENERGY = 0.25
#: Least distance between two label boxes (px).
LABEL_GAP = 3
FONT = cv2.FONT_HERSHEY_SIMPLEX
#: Height of a robot's top above the floor (m): where labels and arrows are anchored.
ROBOT_TOP_Z = 0.17


def fast_scene_option() -> mujoco.MjvOption:
    """Visual options for clean, fast images: no sites, rays or collision-only geoms."""
    opt = mujoco.MjvOption()
    opt.sitegroup[:] = 0
    opt.geomgroup[COLLISION_ONLY_GROUP] = 0
    opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0
    return opt


def disable_slow_effects(scene: mujoco.MjvScene) -> None:
    """Turn off the rendering effects that cost the most in software GL."""
    scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
    scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = 0


def check_image_size(width: int, height: int) -> None:
    """Raise a clear error for sizes a renderer cannot or should not allocate."""
    for name, value in (("width", width), ("height", height)):
        if not isinstance(value, int) or not 1 <= value <= MAX_IMAGE_SIDE:
            raise ValueError(
                f"image {name} must be an integer in [1, {MAX_IMAGE_SIDE}] px, got {value!r}"
            )


class FieldRenderer:
    """Renders a :class:`World` off-screen.

    Args:
        world: the world to draw (its current ``MjData`` state).
        width: image width in pixels.
        height: image height in pixels.
        background: colour painted where nothing was drawn (None: leave it black).
    """

    def __init__(
        self, world: World, width: int = 640, height: int = 640, background: RGB | None = None
    ):
        check_image_size(width, height)
        self.world = world
        self.background = background
        model = world.model
        # The offscreen buffer must hold the image; grow it on this model if asked for more.
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        disable_slow_effects(self._renderer.scene)
        self._option = fast_scene_option()
        self._chase = np.array(
            [
                mujoco.mj_name2id(
                    model, mujoco.mjtObj.mjOBJ_CAMERA, C.robot_prefix(i) + C.CHASE_CAMERA
                )
                for i in range(world.config.n_robots)
            ]
        )

    def top_down(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the whole field from above."""
        return self._render(self.world.top_camera)

    def robot_view(self, robot: int) -> np.ndarray:
        """(H, W, 3) uint8 image from behind and above robot ``robot``."""
        if not 0 <= robot < len(self._chase):
            raise ValueError(f"robot must be in [0, {len(self._chase) - 1}], got {robot}")
        return self._render(int(self._chase[robot]))

    def _render(self, camera: int) -> np.ndarray:
        self._renderer.update_scene(self.world.data, camera=camera, scene_option=self._option)
        disable_slow_effects(self._renderer.scene)
        image: np.ndarray = self._renderer.render()
        if self.background is not None:
            image = fill_background(np.ascontiguousarray(image), self.background)
        return image

    def project_top_down(self, xyz: np.ndarray) -> np.ndarray:
        """Pixel (col, row) of world points in the top-down image (pinhole projection).

        Used to annotate images and to check them: the camera looks straight down with image
        right = world +x and image up = world +y.
        """
        m = self.world.model
        cam = self.world.top_camera
        height, width = self._renderer.height, self._renderer.width
        fovy = math.radians(float(m.cam_fovy[cam]))
        focal = (height / 2) / math.tan(fovy / 2)
        cam_pos = m.cam_pos[cam]
        xyz = np.atleast_2d(xyz)
        depth = cam_pos[2] - xyz[:, 2]
        col = width / 2 + (xyz[:, 0] - cam_pos[0]) * focal / depth
        row = height / 2 - (xyz[:, 1] - cam_pos[1]) * focal / depth
        return np.column_stack([col, row])

    def metres_to_px(self, z: float = ROBOT_TOP_Z) -> float:
        """Pixels per metre in the top-down image at height ``z``."""
        a, b = self.project_top_down(np.array([[0.0, 0.0, z], [1.0, 0.0, z]]))
        return float(b[0] - a[0])

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> FieldRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_writable_output(path: str | os.PathLike[str]) -> Path:
    """Resolve an output file path and fail early, clearly, if it cannot be written.

    Raises:
        ValueError: if the parent directory is missing, not a directory, or not writable, or
            the path is an existing directory.
    """
    out = Path(path).expanduser().resolve()
    if out.is_dir():
        raise ValueError(f"--out {path!s} is a directory; give a file name such as field.png")
    parent = out.parent
    if not parent.is_dir():
        raise ValueError(f"--out {path!s}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"--out {path!s}: directory {parent} is not writable")
    if out.exists() and not os.access(out, os.W_OK):
        raise ValueError(f"--out {path!s}: file exists and is not writable")
    return out


def write_png(image: np.ndarray, path: str | os.PathLike[str]) -> Path:
    """Write an RGB image as PNG atomically (see :func:`cyber_rodent.atomic.atomic_output`)."""
    import imageio.v3 as iio

    out = check_writable_output(path)
    with atomic_output(out) as temp:
        iio.imwrite(temp, image, extension=".png")
    return out


def fill_background(image: np.ndarray, rgb: RGB) -> np.ndarray:
    """Paint pure-black pixels ``rgb`` in place and return ``image``.

    Pure black is exactly where no geom was drawn: the headlight's ambient light (0.45) lifts
    every surface, the darkest included, above zero.
    """
    image[~image.any(axis=2)] = rgb
    return image


def text_scale(height: int, base: float = 0.5, low: float = 0.35, high: float = 1.2) -> float:
    """A font scale that reads the same at any image height (``base`` at 720 px)."""
    return float(min(high, max(low, base * height / 720)))


#: Font scale per pixel per metre of a robot label (:func:`annotate_robots`): a label about as
#: tall as a robot is long. In the paper's field the image height's scale is always smaller;
#: in a large field seen whole, this keeps 100 robots' labels from covering the field.
LABEL_SCALE_PER_PX_PER_M = 0.004


def label_scale(height: int, px_per_m: float) -> float:
    """The font scale of robot labels on a top-down image ``height`` px tall that shows
    ``px_per_m`` pixels per metre: :func:`text_scale`, no larger than the robots' own scale."""
    return float(min(text_scale(height), max(0.35, LABEL_SCALE_PER_PX_PER_M * px_per_m)))


def default_image_size(field_size: float, base: int = 640, most: int = 2048) -> int:
    """Side (px) of a top-down snapshot of a field of side ``field_size`` (m): ``base`` for
    the paper's 2.3 m field and at least as many pixels per metre for a larger one, up to
    ``most``. For a world of several arenas pass the side of their layout,
    ``WorldConfig.extent``, which the top-down camera frames (25 arenas of 2.3 m: 13.1 m,
    2048 px)."""
    return int(min(most, max(base, round(base * field_size / C.FIELD_SIZE))))


def text_thickness(scale: float) -> int:
    return 1 if scale < 0.7 else 2


def draw_text(
    image: np.ndarray, text: str, origin: tuple[int, int], scale: float, rgb: RGB
) -> None:
    """Anti-aliased text with its baseline's left end at ``origin``."""
    cv2.putText(image, text, origin, FONT, scale, rgb, text_thickness(scale), cv2.LINE_AA)


def draw_caption(image: np.ndarray, text: str, scale: float | None = None) -> None:
    """A caption in a dark box at the image's top-left corner (e.g. whose view this is)."""
    scale = text_scale(image.shape[0]) if scale is None else scale
    (tw, th), base = cv2.getTextSize(text, FONT, scale, text_thickness(scale))
    pad = max(3, round(th * 0.4))
    cv2.rectangle(image, (0, 0), (tw + 2 * pad, th + base + 2 * pad), LABEL_BOX_RGB, -1)
    draw_text(image, text, (pad, pad + th), scale, (255, 255, 255))


def draw_heading(
    image: np.ndarray, centre: np.ndarray, yaw: float, length: float, width: int = 2
) -> None:
    """An arrow from a robot's centre along its heading (image up = world +y): dark, on a white
    edge (``width`` px wide, the edge 2 px more on each side)."""
    x, y = float(centre[0]), float(centre[1])
    tip = (round(x + length * math.cos(yaw)), round(y - length * math.sin(yaw)))
    start = (round(x), round(y))
    cv2.arrowedLine(image, start, tip, HEADING_EDGE_RGB, width + 4, cv2.LINE_AA, tipLength=0.35)
    cv2.arrowedLine(image, start, tip, HEADING_RGB, width, cv2.LINE_AA, tipLength=0.35)


@dataclass(frozen=True)
class RobotTag:
    """What a robot's label says.

    Attributes:
        text: e.g. ``"CR0 Forage"``; the first word alone is the compact form (the robot ID)
            used when the full labels do not fit the image.
        rgb: text and border colour.
        energy: energy as a fraction of the maximum, drawn as a bar under the text (None: no
            bar).
    """

    text: str
    rgb: RGB = (255, 255, 255)
    energy: float | None = None

    def compact(self) -> RobotTag:
        return RobotTag(self.text.split()[0] if self.text.split() else self.text, self.rgb)


def label_size(tag: RobotTag, scale: float) -> tuple[int, int]:
    """(width, height) in pixels of ``tag``'s label box at font ``scale``."""
    (tw, th), base = cv2.getTextSize(tag.text, FONT, scale, text_thickness(scale))
    pad = max(2, round(th * 0.3))
    height = th + base + 2 * pad
    if tag.energy is not None:
        height += _bar_height(th) + pad
    return tw + 2 * pad, height


def _bar_height(text_height: int) -> int:
    return max(3, round(text_height * 0.45))


def draw_label(image: np.ndarray, box: Box, tag: RobotTag, scale: float) -> None:
    """Draw ``tag`` in ``box`` (x0, y0, x1, y1; x1 and y1 exclusive)."""
    x0, y0, x1, y1 = (int(v) for v in box)
    (_, th), _ = cv2.getTextSize(tag.text, FONT, scale, text_thickness(scale))
    pad = max(2, round(th * 0.3))
    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), LABEL_BOX_RGB, -1)
    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), tag.rgb, 1)
    draw_text(image, tag.text, (x0 + pad, y0 + pad + th), scale, tag.rgb)
    if tag.energy is not None:
        bar_h = _bar_height(th)
        top = y1 - pad - bar_h
        inner = x1 - x0 - 2 * pad
        cv2.rectangle(image, (x0 + pad, top), (x1 - pad - 1, top + bar_h - 1), (70, 70, 70), -1)
        filled = round(inner * min(1.0, max(0.0, tag.energy)))
        if filled > 0:
            colour = ENERGY_RGB if tag.energy > LOW_ENERGY else LOW_ENERGY_RGB
            right = x0 + pad + filled - 1
            cv2.rectangle(image, (x0 + pad, top), (right, top + bar_h - 1), colour, -1)


def boxes_intersect(a: Box, b: Box, gap: int = 0) -> bool:
    """Do boxes (x0, y0, x1, y1; x1, y1 exclusive) come closer than ``gap`` pixels?"""
    return bool(
        a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap
    )


def place_labels(
    anchors: np.ndarray,
    sizes: np.ndarray,
    bounds: tuple[int, int],
    clearance: float,
    gap: int = 3,
) -> np.ndarray | None:
    """Boxes for labels near their robots such that no two intersect (nor come within ``gap``).

    Each label goes to the first free spot, in order: just below, above, right, left or
    diagonally beside its robot, clear of every robot's disc (radius ``clearance`` px); the
    same directions farther out; the same spots even if they cover a robot; the free spot
    nearest to "just below" anywhere in the image; and if earlier labels left no room, every
    label is moved into a grid of cells, each to the free cell nearest its robot.

    Args:
        anchors: (n, 2) robot centres in pixels (col, row).
        sizes: (n, 2) label (width, height) in pixels.
        bounds: (width, height) of the image; every box lies inside it.
        clearance: robot radius in pixels.
        gap: least distance between two boxes in pixels.

    Returns:
        (n, 4) int boxes (x0, y0, x1, y1; x1 and y1 exclusive), or None if the labels cannot
        all fit in the image.
    """
    anchors = np.asarray(anchors, dtype=float).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=np.int64).reshape(-1, 2)
    width, height = bounds
    n = len(anchors)
    if n and (sizes[:, 0].max() > width or sizes[:, 1].max() > height):
        return None
    robots = [
        (a[0] - clearance, a[1] - clearance, a[0] + clearance, a[1] + clearance) for a in anchors
    ]
    boxes = np.zeros((n, 4), dtype=np.int64)
    for i in range(n):
        box = _nearby_box(anchors[i], sizes[i], bounds, clearance, gap, boxes[:i], robots)
        if box is None:
            box = _nearest_free_box(anchors[i], sizes[i], bounds, clearance, gap, boxes[:i])
        if box is None:
            return _grid_boxes(anchors, sizes, bounds, gap)
        boxes[i] = box
    return boxes


#: Unit directions tried around a robot: below, above, right, left, then the diagonals.
_DIRECTIONS = (
    (0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0),
    (1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0),
)  # fmt: skip


def _nearby_box(
    anchor: np.ndarray,
    size: np.ndarray,
    bounds: tuple[int, int],
    clearance: float,
    gap: int,
    placed: np.ndarray,
    robots: list[tuple[float, float, float, float]],
) -> np.ndarray | None:
    w, h = int(size[0]), int(size[1])
    width, height = bounds
    fallback = None
    for ring in range(6):
        reach = clearance + gap + ring * (h + gap)
        for dx, dy in _DIRECTIONS:
            cx = anchor[0] + dx * (reach + w / 2)
            cy = anchor[1] + dy * (reach + h / 2)
            x0 = int(min(max(round(cx - w / 2), 0), width - w))
            y0 = int(min(max(round(cy - h / 2), 0), height - h))
            box = np.array([x0, y0, x0 + w, y0 + h])
            if any(boxes_intersect(box, p, gap) for p in placed):
                continue
            if not any(boxes_intersect(box, r) for r in robots):
                return box
            if fallback is None:
                fallback = box
    return fallback


def _nearest_free_box(
    anchor: np.ndarray,
    size: np.ndarray,
    bounds: tuple[int, int],
    clearance: float,
    gap: int,
    placed: np.ndarray,
) -> np.ndarray | None:
    """The free box nearest to "just below the robot", by a summed-area table of the taken
    pixels (each placed box grown by ``gap``)."""
    w, h = int(size[0]), int(size[1])
    width, height = bounds
    taken = np.zeros((height, width), dtype=np.int32)
    for x0, y0, x1, y1 in placed:
        taken[max(0, y0 - gap) : y1 + gap, max(0, x0 - gap) : x1 + gap] = 1
    table = np.zeros((height + 1, width + 1), dtype=np.int64)
    table[1:, 1:] = taken.cumsum(0).cumsum(1)
    # Taken pixels in the box whose top-left is (x, y), for every x ≤ width - w, y ≤ height - h.
    area = table[h:, w:] - table[:-h, w:] - table[h:, :-w] + table[:-h, :-w]
    free_y, free_x = np.nonzero(area == 0)
    if not len(free_x):
        return None
    want_x = anchor[0] - w / 2
    want_y = anchor[1] + clearance + gap
    k = int(np.argmin((free_x - want_x) ** 2 + (free_y - want_y) ** 2))
    x0, y0 = int(free_x[k]), int(free_y[k])
    return np.array([x0, y0, x0 + w, y0 + h])


def _grid_boxes(
    anchors: np.ndarray, sizes: np.ndarray, bounds: tuple[int, int], gap: int
) -> np.ndarray | None:
    width, height = bounds
    cell_w = int(sizes[:, 0].max()) + gap
    cell_h = int(sizes[:, 1].max()) + gap
    cols, rows = (width + gap) // cell_w, (height + gap) // cell_h
    if cols * rows < len(anchors):
        return None
    cells = [(c, r) for r in range(rows) for c in range(cols)]
    centres = np.array([(c * cell_w + cell_w / 2, r * cell_h + cell_h / 2) for c, r in cells])
    free = np.ones(len(centres), dtype=bool)
    boxes = np.zeros((len(anchors), 4), dtype=np.int64)
    for i, anchor in enumerate(anchors):
        distance = np.hypot(*(centres - anchor).T)
        distance[~free] = np.inf
        k = int(np.argmin(distance))
        free[k] = False
        x0, y0 = (k % cols) * cell_w, (k // cols) * cell_h
        boxes[i] = (x0, y0, x0 + sizes[i, 0], y0 + sizes[i, 1])
    return boxes


def _leader_end(anchor: np.ndarray, box: Box) -> tuple[int, int]:
    """The point of ``box`` nearest to ``anchor``."""
    x = min(max(anchor[0], box[0]), box[2] - 1)
    y = min(max(anchor[1], box[1]), box[3] - 1)
    return round(x), round(y)


def annotate_robots(
    image: np.ndarray,
    anchors: np.ndarray,
    yaws: np.ndarray,
    tags: Sequence[RobotTag],
    px_per_m: float,
    scale: float | None = None,
) -> np.ndarray | None:
    """Draw heading arrows and labels that never overlap on a top-down image, in place.

    Args:
        image: (H, W, 3) uint8 RGB, contiguous.
        anchors: (n, 2) robot centres in pixels (see :meth:`FieldRenderer.project_top_down`).
        yaws: (n,) headings in radians.
        tags: what each robot's label says.
        px_per_m: image scale at the robots' tops (arrow length, label clearance).
        scale: font scale (default: from the image height, no larger than the robots' scale:
            :func:`label_scale`).

    Returns:
        The (n, 4) label boxes drawn, or None if not even the compact labels (IDs alone) fit,
        in which case no label is drawn.
    """
    height, width = image.shape[:2]
    scale = label_scale(height, px_per_m) if scale is None else scale
    clearance = 0.11 * px_per_m  # the chassis' half-diagonal, about
    anchors = np.asarray(anchors, dtype=float).reshape(-1, 2)
    for anchor, yaw in zip(anchors, yaws, strict=True):
        draw_heading(image, anchor, float(yaw), 0.17 * px_per_m, max(1, round(scale * 4)))
    boxes = None
    for shown in (list(tags), [tag.compact() for tag in tags]):
        sizes = np.array([label_size(tag, scale) for tag in shown]).reshape(-1, 2)
        boxes = place_labels(anchors, sizes, (width, height), clearance, LABEL_GAP)
        if boxes is not None:
            break
    if boxes is None:
        return None
    near = clearance + 2 * LABEL_GAP + 2
    for anchor, box in zip(anchors, boxes, strict=True):
        end = _leader_end(anchor, box)
        if math.hypot(end[0] - anchor[0], end[1] - anchor[1]) > near:
            start = (round(anchor[0]), round(anchor[1]))
            cv2.line(image, start, end, OUTLINE_RGB, 3, cv2.LINE_AA)
            cv2.line(image, start, end, LEADER_RGB, 1, cv2.LINE_AA)
    for box, tag in zip(boxes, shown, strict=True):
        draw_label(image, box, tag, scale)
    return boxes


def annotate_world(
    image: np.ndarray,
    renderer: FieldRenderer,
    tags: Sequence[RobotTag] | None = None,
    scale: float | None = None,
) -> np.ndarray | None:
    """:func:`annotate_robots` for the robots of ``renderer``'s world on its top-down image;
    by default each label is the robot's ID, ``CRi`` for robot index i (as in ``--robot i``)."""
    poses = renderer.world.poses()
    n = len(poses)
    top = np.column_stack([poses[:, :2], np.full(n, ROBOT_TOP_Z)])
    anchors = renderer.project_top_down(top)
    tags = [RobotTag(f"CR{i}") for i in range(n)] if tags is None else tags
    return annotate_robots(image, anchors, poses[:, 2], tags, renderer.metres_to_px(), scale)


def snapshot(
    world: World, robot: int | None = None, size: int | None = None, plain: bool = False
) -> np.ndarray:
    """A square picture of ``world`` as it stands (nothing is stepped): the field from above
    with robot IDs (``CRi`` for robot i) and heading arrows, or, with ``robot``, that robot's
    chase view with a caption.

    Args:
        world: the world to draw.
        robot: whose chase view to draw instead of the field (None: the field).
        size: the image side in px (default: :func:`default_image_size` of the world's extent,
            which keeps the paper field's pixels per metre in a larger one).
        plain: the bare render: no IDs, arrows or caption, and empty space left black.

    Raises:
        ValueError: ``robot`` is not a robot of the world, or ``size`` is out of range.
    """
    background = None if plain else BACKGROUND_RGB
    side = default_image_size(world.config.extent) if size is None else size
    with FieldRenderer(world, side, side, background=background) as renderer:
        if robot is not None:
            image = renderer.robot_view(robot)
            if not plain:
                draw_caption(image, f"CR{robot} chase view")
        else:
            image = renderer.top_down()
            if not plain:
                annotate_world(image, renderer)
    return image
