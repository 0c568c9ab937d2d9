"""Colour segmentation of omni strips (OpenCV): blobs with bearing, distance and pixel area.

What the real CR's vision does, on the simulated image:

1. HSV thresholds (from :class:`CameraConfig`) give one binary mask per colour class; red wraps
   around hue 0.
2. Connected components (8-connectivity) of each mask, per robot. A strip is a full circle, so a
   blob cut by the strip's left/right edge is joined back into one.
3. Battery packs only: the grey electrode ring cuts a pack's blue into an upper and a lower band
   (and a nearer chassis may hide its middle, or the frame's bottom cut off its lower band).
   Components that overlap in bearing, the lower no wider than the upper, are grouped into one
   target (see :func:`~cyber_rodent.vision.segmentation_kernels.join_stacked`).
4. Per blob: **pixel area**; **bearing** = circular mean of its pixels' column bearings;
   **distance** from image geometry with the camera height, as a real omni camera allows: the
   blob's bottom edge is the target's near bottom rim (known height, e.g. the floor for a pack),
   its top edge the far top rim (known height), and a point of known height seen ``v`` below the
   horizon lies at horizontal distance ``Δh·sqrt(1+u²)/v`` (see
   :class:`~cyber_rodent.vision.projection.OmniProjection`). The two edge estimates are
   combined with weights ``v²`` (the lower edge is more precise). A face plate seen obliquely
   has its top edge's highest pixel at its far corner and its bottom edge's lowest at its near
   corner: each edge is placed at the bearing of its own row, and the plate's centre is half
   way between the two corners.
   If the bottom edge is cut off by the frame or hidden behind something (its estimate is
   farther than the top edge's by more than the pixel quantisation allows), the top edge alone
   is used; if it is nearer than the top edge's by more than that, the blob holds several
   targets of one colour that touch in the image (a pack peeking out behind another), and its
   bottom edge, the nearest one's, is used.

Steps 1–3 and the pixel statistics of step 4 run in :mod:`.segmentation_kernels`: an
OpenCV-built colour look-up table (a pixel's classes are exactly OpenCV's cvtColor + inRange
ones), a labelling pass over all robots' strips and the pack grouping's pair test. The
segmenter's ``backend`` picks the compiled kernels (``"numba"``) or their numpy references
(``"numpy"``), which give the same detections, bit for bit; the tests also compare them with
OpenCV's connected components. Step 4's distances are shared.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, cast

import cv2
import numpy as np

from cyber_rodent.backend import DEFAULT_BACKEND, Backend, bind, check_backend, pick
from cyber_rodent.vision import segmentation_kernels as kernels
from cyber_rodent.vision.config import CameraConfig, ColourThreshold
from cyber_rodent.vision.projection import OmniProjection
from cyber_rodent.vision.targets import TargetGeometry
from cyber_rodent.vision.types import BATTERY, N_CLASSES

#: Pixel tolerance on each edge when deciding that a blob's bottom edge is hidden: the two
#: distance estimates may disagree by the effect of this many pixels on each before the bottom
#: one is dropped.
_EDGE_TOLERANCE_PX = 1.5
#: A blob at most this many rows tall is measured by its middle row, not its edges.
_FEW_ROWS = 3


def _hsv_bounds(t: ColourThreshold) -> kernels.HsvBounds:
    """inRange bounds for a threshold; two intervals when the hue range wraps around 180."""
    if t.hue_low <= t.hue_high:
        hues = [(t.hue_low, t.hue_high)]
    else:
        hues = [(t.hue_low, 179), (0, t.hue_high)]
    return [
        (
            np.array([lo, t.sat_min, t.val_min], dtype=np.uint8),
            np.array([hi, 255, 255], dtype=np.uint8),
        )
        for lo, hi in hues
    ]


class OmniSegmenter:
    """Finds the coloured targets in omni strips.

    Args:
        config: the camera (thresholds, resolution, field of view, minimum blob area).
        geometry: camera height and target shapes (from :func:`target_geometry`).
        backend: ``"numba"`` (the compiled kernels) or ``"numpy"`` (their numpy references);
            see the module docstring.

    Attributes:
        table: the classes' colour look-up table (:func:`~.segmentation_kernels.class_lut`).
        labeller: the labelling's buffers (made by the first :meth:`detect`, remade when the
            strips' shape changes).

    Raises:
        ValueError: for an unknown backend.
    """

    def __init__(
        self, config: CameraConfig, geometry: TargetGeometry, backend: Backend = DEFAULT_BACKEND
    ):
        self.backend = check_backend(backend)
        self.config = config
        self.geometry = geometry
        self.projection = OmniProjection(config)
        self._bounds = [_hsv_bounds(t) for t in config.thresholds]
        self._join_stacked = pick(
            self.backend, kernels.join_stacked, kernels.join_stacked_reference
        )
        self.table = kernels.class_lut(self._bounds)
        self.labeller: Labeller | None = None

    # ------------------------------------------------------------------------------------
    def masks(self, rgb: np.ndarray) -> np.ndarray:
        """Binary masks (uint8 0/255) of the three classes for an RGB image of any height.

        Args:
            rgb: (rows, strip_width, 3) uint8 RGB, e.g. all robots' strips stacked.

        Returns:
            (3, rows, strip_width) uint8, class order LED, FACE, BATTERY.
        """
        rgb = np.ascontiguousarray(rgb)
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        out = np.empty((N_CLASSES,) + rgb.shape[:2], dtype=np.uint8)
        for c, bounds in enumerate(self._bounds):
            cv2.inRange(hsv, bounds[0][0], bounds[0][1], dst=out[c])
            for lo, hi in bounds[1:]:
                cv2.bitwise_or(out[c], cv2.inRange(hsv, lo, hi), dst=out[c])
        return out

    def detect(self, strips: np.ndarray) -> tuple[np.ndarray, ...]:
        """Detections in the strips of all robots.

        Args:
            strips: (n_robots, height, strip_width, 3) uint8 RGB.

        Returns:
            Flat arrays ``robot, cls, bearing, distance, area`` (one entry per blob, ordered by
            robot, class, then first pixel in raster order) and, for overlays, ``classes``:
            (n_robots, height, strip_width) uint8 whose bit ``c`` marks class ``c``'s pixels
            (:meth:`masks_from_classes` expands it; it may be overwritten by the next call).
        """
        n, h, w, _ = strips.shape
        rgb = np.ascontiguousarray(strips.reshape(n * h, w, 3))
        lab = self.labeller
        if lab is None or lab.strip.bits.shape != (n * h, w):
            lab = self.labeller = self._labeller(n * h, w, h, self.table)
        blobs = self._measure(lab, rgb, n, h)
        classes = lab.strip.bits.reshape(n, h, w)
        if blobs is None:
            return _flat_detections([[]], classes)
        robot, cls, bearing, distance, area = blobs
        min_area = np.asarray(self.config.min_blob_area, dtype=float)[cls]
        keep = (area >= min_area) & (distance <= self.config.max_range)
        out = [[robot[keep]], [cls[keep]], [bearing[keep]], [distance[keep]], [area[keep]]]
        return _flat_detections(out, classes)

    @staticmethod
    def masks_from_classes(classes: np.ndarray) -> np.ndarray:
        """(3, …) uint8 0/255 masks, class order LED, FACE, BATTERY, from a class-bit image."""
        return np.stack([((classes >> c) & 1) * np.uint8(255) for c in range(N_CLASSES)])

    def _labeller(self, rows: int, width: int, height: int, table: kernels.ClassTable) -> Labeller:
        """Labelling buffers for ``rows`` stacked rows of strips of ``height`` rows."""
        return Labeller(
            rows, width, height, N_CLASSES, self.projection.column_bearing, table, self.backend
        )

    def _measure(
        self, lab: Labeller, rgb: np.ndarray, n: int, h: int
    ) -> tuple[np.ndarray, ...] | None:
        """Robot, class, bearing, distance and area of every target in ``n`` stacked strips of
        ``h`` rows (a pack's two bands grouped), before the area and range limits; None if
        there is none."""
        blobs = lab.label(rgb)
        robot, cls = blobs.robot, blobs.cls
        area, sin_sum, cos_sum = blobs.area, blobs.sin_sum, blobs.cos_sum
        top, bottom = blobs.top, blobs.bottom
        top_bearing, bottom_bearing = blobs.top_bearing, blobs.bottom_bearing
        bearing = np.arctan2(sin_sum, cos_sum)
        order = np.lexsort((np.arange(len(robot)), cls, robot))
        battery = cls == BATTERY
        counts = np.bincount(robot[battery], minlength=n)
        extents = lab.extents(bearing, BATTERY) if (counts > 1).any() else None
        # Per (robot, class): robot, cls, area, sin, cos, top, bottom, top and bottom bearing.
        out: list[list[Any]] = [[], [], [], [], [], [], [], [], []]
        start = 0
        while start < len(order):
            i, c = robot[order[start]], cls[order[start]]
            stop = start
            while stop < len(order) and robot[order[stop]] == i and cls[order[stop]] == c:
                stop += 1
            idx = order[start:stop]
            a, s, co, t, b = area[idx], sin_sum[idx], cos_sum[idx], top[idx], bottom[idx]
            tb, bb = top_bearing[idx], bottom_bearing[idx]
            if c == BATTERY and len(idx) > 1 and extents is not None:
                merged = self._group_stacked(
                    bearing[idx], extents[0][idx], extents[1][idx], t, b
                )
                if merged is not None:
                    a, s, co, t, b = _merge_groups(merged, a, s, co, t, b, h)
                    tb = bb = np.arctan2(s, co)  # a pack's distance needs no edge bearings
            out[0].append(np.full(len(a), i))
            out[1].append(np.full(len(a), c))
            for j, v in enumerate((a, s, co, t, b, tb, bb)):
                out[2 + j].append(v)
            start = stop
        if not out[0]:
            return None
        robot, cls, area, sin_sum, cos_sum, top, bottom, top_bearing, bottom_bearing = (
            np.concatenate(v) for v in out
        )
        bearing = np.arctan2(sin_sum, cos_sum)
        distance = np.empty(len(robot))
        for c in range(N_CLASSES):
            sel = cls == c
            if sel.any():
                distance[sel] = self.distance_from_edges(
                    c,
                    bearing[sel],
                    top[sel].astype(float),
                    bottom[sel].astype(float) + 1.0,
                    top_bearing[sel],
                    bottom_bearing[sel],
                )
        return robot, cls, bearing, distance, area

    # ------------------------------------------------------------------------------------
    def measure_blobs(self, mask: np.ndarray, cls: int) -> tuple[np.ndarray, ...]:
        """Bearing (rad), distance (m) and pixel area of every blob of one class in one strip,
        whatever its area and range (a pack's two bands grouped into one).

        Args:
            mask: (height, strip_width) uint8, nonzero where the class's colour is.
            cls: the colour class (selects the target shape for the distance estimate).
        """
        height, width = mask.shape
        rgb = np.zeros((height, width, 3), dtype=np.uint8)
        rgb[..., 2] = np.where(mask > 0, 1 << cls, 0)
        lab = self._labeller(height, width, height, kernels.identity_table(N_CLASSES))
        blobs = self._measure(lab, rgb, 1, height)
        if blobs is None:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        _, _, bearing, distance, area = blobs
        return bearing, distance, area

    def distance_from_edges(
        self,
        cls: int,
        bearing: np.ndarray,
        top_edge: np.ndarray,
        bottom_edge: np.ndarray,
        top_bearing: np.ndarray | None = None,
        bottom_bearing: np.ndarray | None = None,
    ) -> np.ndarray:
        """Horizontal distance of blobs of class ``cls`` from their top and bottom image edges.

        Args:
            cls: colour class (its target shape gives the heights of the edges).
            bearing: (k,) rad, the blobs' bearings (select the view and the abscissa u).
            top_edge, bottom_edge: (k,) continuous row coordinates of the blobs' upper and
                lower boundaries (0 = top of the strip; a blob covering rows a..b has edges
                a and b + 1).
            top_bearing, bottom_bearing: (k,) rad, where along the blob its top and bottom
                rows lie (default: ``bearing``). A face plate seen obliquely has its top edge's
                highest pixel at its far corner and its bottom edge's lowest at its near
                corner: the two corners, each placed at its own bearing, have the plate's
                centre half way between them.
        """
        proj = self.projection
        shape = self.geometry.shapes[cls]
        hc = self.geometry.camera_height
        top_bearing = bearing if top_bearing is None else top_bearing
        bottom_bearing = bearing if bottom_bearing is None else bottom_bearing
        v_top = cast(np.ndarray, proj.v_at_row(top_edge))
        v_bot = cast(np.ndarray, proj.v_at_row(bottom_edge))
        height_top, height_bottom = np.asarray(hc - shape.z_top), np.asarray(hc - shape.z_bottom)
        pixel = 1.0 / proj.px_per_v
        in_frame = bottom_edge < self.config.height
        if shape.plate:
            _, offset_top = proj.view_coordinates(top_bearing)
            _, offset_bot = proj.view_coordinates(bottom_bearing)
            d_top = proj.horizontal_distance(height_top, v_top, np.tan(offset_top))
            d_bot = proj.horizontal_distance(height_bottom, v_bot, np.tan(offset_bot))
        else:
            _, offset = proj.view_coordinates(bearing)
            u = np.tan(offset)
            d_top = proj.horizontal_distance(height_top, v_top, u) - shape.rim_offset
            d_bot = proj.horizontal_distance(height_bottom, v_bot, u) + shape.rim_offset
        with np.errstate(divide="ignore", invalid="ignore"):
            tolerance = _EDGE_TOLERANCE_PX * pixel * (1.0 / np.abs(v_top) + 1.0 / np.abs(v_bot))
            if shape.plate:
                # The two corners' plan positions: as far apart as the plate is wide, at most.
                x_top, y_top = d_top * np.cos(top_bearing), d_top * np.sin(top_bearing)
                x_bot, y_bot = d_bot * np.cos(bottom_bearing), d_bot * np.sin(bottom_bearing)
                chord = np.hypot(x_top - x_bot, y_top - y_bot)
                slack = 2.0 * shape.half_width + tolerance * d_top
                # Its bottom edge is seen if it lies no higher than a plate's whose top edge is
                # where this one's is (seen obliquely, the near corner's bottom lies lower).
                lowest = -height_bottom * np.sqrt(1.0 + np.tan(offset_top) ** 2) / d_top
                bottom_seen = in_frame & (v_bot <= lowest + _EDGE_TOLERANCE_PX * pixel)
                agree = bottom_seen & (chord <= slack)
                several = bottom_seen & ~agree & (d_bot < d_top)
                both = 0.5 * np.hypot(x_top + x_bot, y_top + y_bot)
            else:
                agree = in_frame & (np.abs(d_bot - d_top) <= d_top * tolerance)
                several = in_frame & (d_bot < d_top * (1.0 - tolerance))
                w_top, w_bot = v_top**2, v_bot**2
                both = (w_top * d_top + w_bot * d_bot) / (w_top + w_bot)
                # A blob a few rows tall (a far LED): each edge is off by up to a row, while
                # the middle row is its centre's to within half a row.
                middle = proj.horizontal_distance(
                    0.5 * (height_top + height_bottom), 0.5 * (v_top + v_bot), u
                )
                both = np.where(bottom_edge - top_edge <= _FEW_ROWS, middle, both)
        d = np.where(agree, both, np.where(several, d_bot, d_top))
        d = np.where(np.isfinite(d), d, np.inf)
        return np.maximum(d, 0.0)

    def _group_stacked(
        self,
        bearing: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        top: np.ndarray,
        bottom: np.ndarray,
    ) -> np.ndarray | None:
        """Group blobs stacked vertically at the same bearing: one pack cut in two by its
        electrode ring, by something nearer that hides its middle, or with its lower band cut
        off by the bottom of the frame.

        The bands of one pack have the same angular width (same cylinder, same distance); the
        pair test is :func:`~cyber_rodent.vision.segmentation_kernels.join_stacked`. A farther
        pack seen *above* a nearer one without touching it must be more than 2.4 times as far
        (its bottom rim, 17 cm below the camera, has to appear above the near pack's top, 7 cm
        below), hence at most 41 % as wide: it stays separate.

        Args:
            bearing: (k,) mean bearings; lo, hi: bearing interval relative to the mean (rad);
            top, bottom: first and last image row of each blob.

        Returns:
            The group label of each blob, or None if nothing is grouped.
        """
        parent = np.arange(len(bearing))
        joined = self._join_stacked(
            np.asarray(bearing, dtype=np.float64), np.asarray(lo, dtype=np.float64),
            np.asarray(hi, dtype=np.float64), np.asarray(top, dtype=np.int64),
            np.asarray(bottom, dtype=np.int64), parent, self.config.height,
            2.0 * math.pi / self.config.strip_width,
        )  # fmt: skip
        return _roots(parent) if joined else None


def _flat_detections(out: list[list[Any]], classes: np.ndarray) -> tuple[np.ndarray, ...]:
    """``detect``'s return value from per-(robot, class) lists of robot, cls, bearing,
    distance and area arrays."""
    if not out[0]:
        empty = np.zeros(0)
        return (empty.astype(np.int64), empty.astype(np.int64), empty, empty, empty, classes)
    robot, cls, bearing, distance, area = (np.concatenate(a) for a in out)
    return (
        robot.astype(np.int64),
        cls.astype(np.int64),
        bearing,
        distance,
        area.astype(float),
        classes,
    )


def _merge_groups(
    merged: np.ndarray,
    area: np.ndarray,
    sin_sum: np.ndarray,
    cos_sum: np.ndarray,
    top: np.ndarray,
    bottom: np.ndarray,
    height: int,
) -> tuple[np.ndarray, ...]:
    """Pool the statistics of blobs with the same group label (from
    :meth:`OmniSegmenter._group_stacked`)."""
    m_groups, m_of = np.unique(merged, return_inverse=True)
    k = len(m_groups)
    area = np.bincount(m_of, weights=area, minlength=k)
    sin_sum = np.bincount(m_of, weights=sin_sum, minlength=k)
    cos_sum = np.bincount(m_of, weights=cos_sum, minlength=k)
    new_top = np.full(k, height, dtype=np.int64)
    new_bottom = np.full(k, -1, dtype=np.int64)
    np.minimum.at(new_top, m_of, top)
    np.maximum.at(new_bottom, m_of, bottom)
    return area, sin_sum, cos_sum, new_top, new_bottom


def _roots(parent: np.ndarray) -> np.ndarray:
    """Resolve a union-find parent array to every element's root."""
    root = parent.copy()
    while True:
        nxt = root[root]
        if np.array_equal(nxt, root):
            return root
        root = nxt


class Blobs(NamedTuple):
    """Per component of a :meth:`Labeller.label` call (ordered by robot, then in each robot by
    first pixel in raster order)."""

    robot: np.ndarray  #: (k,) int64
    cls: np.ndarray  #: (k,) int64 colour class
    top: np.ndarray  #: (k,) int64 first row in the strip
    bottom: np.ndarray  #: (k,) int64 last row in the strip
    area: np.ndarray  #: (k,) pixels
    sin_sum: np.ndarray  #: (k,) sum over its pixels of the column bearing's sine
    cos_sum: np.ndarray  #: (k,) and of its cosine
    top_bearing: np.ndarray  #: (k,) rad, mean bearing of its top row's pixels
    bottom_bearing: np.ndarray  #: (k,) rad, and of its bottom row's


class Labeller:
    """The labelling's buffers for strips of one shape, and its kernels (bound where they can
    be).

    The run buffers start small and grow to the worst case (a checkerboard) the first time a
    frame overflows them.

    Args:
        rows, width: the stacked strips' shape (all robots' rows, strip width).
        height: rows per robot strip.
        n_classes: colour classes (bits of the look-up table).
        column_bearing: (width,) rad, each column's bearing.
        table: the classes' look-up table (:func:`~.segmentation_kernels.class_lut`).
        backend: the compiled kernels (``"numba"``) or their numpy references (``"numpy"``).
    """

    def __init__(
        self,
        rows: int,
        width: int,
        height: int,
        n_classes: int,
        column_bearing: np.ndarray,
        table: kernels.ClassTable,
        backend: Backend = DEFAULT_BACKEND,
    ):
        self.table = table
        self._label = pick(backend, kernels.label, kernels.label_reference)
        self._extents_kernel = pick(backend, kernels.extents, kernels.extents_reference)
        bearing = np.ascontiguousarray(column_bearing, dtype=np.float64)
        self.strip = kernels.StripBuffers(
            height=height,
            n_classes=n_classes,
            column_bearing=bearing,
            sin_col=np.sin(bearing),
            cos_col=np.cos(bearing),
            half_px=0.5 * (2.0 * math.pi / width),
            bits=np.zeros((rows, width), dtype=np.uint8),
            edge_left=np.empty((rows, n_classes), dtype=np.int64),
            edge_right=np.empty((rows, n_classes), dtype=np.int64),
        )
        self.worst = rows * n_classes * ((width + 1) // 2)
        self._allocate(min(self.worst, rows * n_classes * 8))

    def _allocate(self, capacity: int) -> None:
        self.capacity = capacity
        self.runs = kernels.Runs(
            row=np.empty(capacity, dtype=np.int64),
            c0=np.empty(capacity, dtype=np.int64),
            c1=np.empty(capacity, dtype=np.int64),
            cls=np.empty(capacity, dtype=np.int64),
            parent=np.empty(capacity, dtype=np.int64),
            comp=np.empty(capacity, dtype=np.int64),
            comp_stats=np.empty((capacity, 7), dtype=np.float64),
            comp_ints=np.empty((capacity, 4), dtype=np.int64),
        )
        self.extent_buffers = kernels.Extents(
            counts=np.zeros(3, dtype=np.int64),
            bearing=np.empty(capacity, dtype=np.float64),
            lo=np.empty(capacity, dtype=np.float64),
            hi=np.empty(capacity, dtype=np.float64),
        )
        self._extents = bind(self._extents_kernel, self.runs, self.strip, self.extent_buffers)

    def label(self, rgb: np.ndarray) -> Blobs:
        """Connected class blobs of stacked omni strips, with their pixel statistics.

        Args:
            rgb: (rows, width, 3) uint8 C-contiguous RGB, every robot's strip stacked.
        """
        # The image is an argument, not a bound buffer: MuJoCo's renderer returns a new array
        # every frame, and rebinding costs more than numba's dispatch on these named buffers.
        while True:
            n, k = self._label(rgb, self.table, self.strip, self.runs)
            if n >= 0:
                break
            self._allocate(self.worst)
        self.extent_buffers.counts[0] = n
        ints, stats = self.runs.comp_ints[:k], self.runs.comp_stats[:k]
        return Blobs(
            robot=ints[:, 0].copy(),
            cls=ints[:, 1].copy(),
            top=ints[:, 2].copy(),
            bottom=ints[:, 3].copy(),
            area=stats[:, 0].copy(),
            sin_sum=stats[:, 1].copy(),
            cos_sum=stats[:, 2].copy(),
            top_bearing=np.arctan2(stats[:, 3], stats[:, 4]),
            bottom_bearing=np.arctan2(stats[:, 5], stats[:, 6]),
        )

    def extents(self, bearing: np.ndarray, cls: int) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) bearing interval of every component of class ``cls`` of the last
        :meth:`label` call, given every component's mean ``bearing`` (other components: half a
        pixel either side). The arrays are overwritten by the next call."""
        k = len(bearing)
        ext = self.extent_buffers
        ext.counts[1] = k
        ext.counts[2] = cls
        ext.bearing[:k] = bearing
        self._extents()
        return ext.lo[:k], ext.hi[:k]
