"""Colour segmentation of omni strips (OpenCV): blobs with bearing, distance and pixel area.

What the real CR's vision does, on the simulated image:

1. HSV thresholds (from :class:`CameraConfig`) give one binary mask per colour class; red wraps
   around hue 0.
2. Connected components (8-connectivity) of each mask, per robot. A strip is a full circle, so a
   blob cut by the strip's left/right edge is joined back into one.
3. Battery packs only: the grey electrode ring cuts a pack's blue into an upper and a lower band.
   Components that overlap in bearing, have similar widths and are separated vertically by less
   than the taller one's height are grouped into one target (see
   :func:`~cyber_rodent.vision.segmentation_kernels.join_stacked`).
4. Per blob: **pixel area**; **bearing** = circular mean of its pixels' column bearings;
   **distance** from image geometry with the camera height, as a real omni camera allows: the
   blob's bottom edge is the target's near bottom rim (known height, e.g. the floor for a pack),
   its top edge the far top rim (known height), and a point of known height seen ``v`` below the
   horizon lies at horizontal distance ``Δh·sqrt(1+u²)/v`` (see
   :class:`~cyber_rodent.vision.projection.OmniProjection`). The two edge estimates are
   combined with weights ``v²`` (the lower edge is more precise); if the bottom edge is cut off
   by the frame or hidden behind something (its estimate is farther than the top edge's by more
   than the pixel quantisation allows), the top edge alone is used.

The segmenter's ``backend`` chooses how steps 1–3 and the pixel statistics of step 4 run:
``"numpy"`` (cvtColor, inRange, connectedComponents, numpy; the reference) or ``"numba"``
(:mod:`cyber_rodent.vision.segmentation_kernels`: an OpenCV-built colour look-up table and one
compiled labelling pass, tested to give the same detections, bit for bit). Step 4's distances
are shared.
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
        backend: ``"numba"`` (the compiled labelling) or ``"numpy"`` (OpenCV and numpy, the
            reference); see the module docstring.

    Attributes:
        labeller: the compiled labelling's buffers (``backend="numba"``; made by the first
            :meth:`detect`, remade when the strips' shape changes).

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
        self._cos_col = np.cos(self.projection.column_bearing)
        self._sin_col = np.sin(self.projection.column_bearing)
        self._join_stacked = pick(
            self.backend, kernels.join_stacked, kernels.join_stacked_reference
        )
        self._detect = pick(self.backend, self._detect_labelled, self._detect_opencv)
        self._table = kernels.class_lut(self._bounds) if self.backend == "numba" else None
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
        return self._detect(strips)

    def _detect_opencv(self, strips: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`detect` with OpenCV's masks and connected components (the reference)."""
        n, h, w, _ = strips.shape
        masks = self.masks(strips.reshape(n * h, w, 3)).reshape(N_CLASSES, n, h, w)
        out: list[list[np.ndarray]] = [[], [], [], [], []]
        for i in range(n):
            for c in range(N_CLASSES):
                mask = masks[c, i]
                if not cv2.countNonZero(mask):
                    continue
                bearing, distance, area = self.measure_blobs(mask, c)
                keep = (area >= self.config.min_blob_area[c]) & (distance <= self.config.max_range)
                k = int(keep.sum())
                out[0].append(np.full(k, i))
                out[1].append(np.full(k, c))
                out[2].append(bearing[keep])
                out[3].append(distance[keep])
                out[4].append(area[keep])
        classes = np.zeros((n, h, w), dtype=np.uint8)
        for c in range(N_CLASSES):
            classes |= (masks[c] > 0).astype(np.uint8) << c
        return _flat_detections(out, classes)

    @staticmethod
    def masks_from_classes(classes: np.ndarray) -> np.ndarray:
        """(3, …) uint8 0/255 masks, class order LED, FACE, BATTERY, from a class-bit image."""
        return np.stack([((classes >> c) & 1) * np.uint8(255) for c in range(N_CLASSES)])

    def _detect_labelled(self, strips: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`detect` with the compiled labelling (:mod:`.segmentation_kernels`)."""
        n, h, w, _ = strips.shape
        rgb = np.ascontiguousarray(strips.reshape(n * h, w, 3))
        lab = self.labeller
        if lab is None or lab.strip.bits.shape != (n * h, w):
            assert self._table is not None
            lab = self.labeller = Labeller(
                n * h, w, h, N_CLASSES, self.projection.column_bearing, self._table
            )
        blobs = lab.label(rgb)
        robot, cls = blobs.robot, blobs.cls
        area, sin_sum, cos_sum = blobs.area, blobs.sin_sum, blobs.cos_sum
        top, bottom = blobs.top, blobs.bottom
        bearing = np.arctan2(sin_sum, cos_sum)
        order = np.lexsort((np.arange(len(robot)), cls, robot))
        battery = cls == BATTERY
        counts = np.bincount(robot[battery], minlength=n)
        extents = lab.extents(bearing, BATTERY) if (counts > 1).any() else None
        # Per (robot, class): robot, cls, area, sin, cos, top, bottom.
        out: list[list[Any]] = [[], [], [], [], [], [], []]
        start = 0
        while start < len(order):
            i, c = robot[order[start]], cls[order[start]]
            stop = start
            while stop < len(order) and robot[order[stop]] == i and cls[order[stop]] == c:
                stop += 1
            idx = order[start:stop]
            a, s, co, t, b = area[idx], sin_sum[idx], cos_sum[idx], top[idx], bottom[idx]
            if c == BATTERY and len(idx) > 1 and extents is not None:
                merged = self._group_stacked(
                    bearing[idx], extents[0][idx], extents[1][idx], t, b
                )
                if merged is not None:
                    a, s, co, t, b = _merge_groups(merged, a, s, co, t, b, h)
            out[0].append(np.full(len(a), i))
            out[1].append(np.full(len(a), c))
            for j, v in enumerate((a, s, co, t, b)):
                out[2 + j].append(v)
            start = stop
        if not out[0]:
            return _flat_detections([[]], lab.strip.bits.reshape(n, h, w))
        robot, cls, area, sin_sum, cos_sum, top, bottom = (np.concatenate(v) for v in out)
        bearing = np.arctan2(sin_sum, cos_sum)
        distance = np.empty(len(robot))
        for c in range(N_CLASSES):
            sel = cls == c
            if sel.any():
                distance[sel] = self.distance_from_edges(
                    c, bearing[sel], top[sel].astype(float), bottom[sel].astype(float) + 1.0
                )
        min_area = np.asarray(self.config.min_blob_area, dtype=float)[cls]
        keep = (area >= min_area) & (distance <= self.config.max_range)
        out = [[robot[keep]], [cls[keep]], [bearing[keep]], [distance[keep]], [area[keep]]]
        return _flat_detections(out, lab.strip.bits.reshape(n, h, w))

    # ------------------------------------------------------------------------------------
    def measure_blobs(self, mask: np.ndarray, cls: int) -> tuple[np.ndarray, ...]:
        """Bearing (rad), distance (m) and pixel area of every blob of one class in one strip.

        Args:
            mask: (height, strip_width) uint8, nonzero where the class's colour is.
            cls: the colour class (selects the target shape for the distance estimate).
        """
        n_labels, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_32S)
        parent = np.arange(n_labels)
        _join_wrapped(labels, parent)
        points = cv2.findNonZero(mask).reshape(-1, 2)  # x, y; much faster than np.nonzero
        cols = points[:, 0].astype(np.intp)
        rows = points[:, 1].astype(np.intp)
        root = _roots(parent)[labels[rows, cols]]
        groups, group = np.unique(root, return_inverse=True)
        n_groups = len(groups)
        # Blobs in the raster order of their first pixel (OpenCV's label order depends on its
        # block-based scan; the compiled backend gives this order too).
        first = np.full(n_groups, mask.size, dtype=np.int64)
        np.minimum.at(first, group, rows * mask.shape[1] + cols)
        rank = np.empty(n_groups, dtype=np.intp)
        rank[np.argsort(first)] = np.arange(n_groups)
        group = rank[group]
        area = np.bincount(group, minlength=n_groups).astype(float)
        sin_sum = np.bincount(group, weights=self._sin_col[cols], minlength=n_groups)
        cos_sum = np.bincount(group, weights=self._cos_col[cols], minlength=n_groups)
        top = np.full(n_groups, mask.shape[0], dtype=np.int64)
        bottom = np.full(n_groups, -1, dtype=np.int64)
        np.minimum.at(top, group, rows)
        np.maximum.at(bottom, group, rows)
        bearing = np.arctan2(sin_sum, cos_sum)
        if cls == BATTERY and n_groups > 1:
            lo, hi = self._angular_extent(group, cols, bearing)
            merged = self._group_stacked(bearing, lo, hi, top, bottom)
            if merged is not None:
                area, sin_sum, cos_sum, top, bottom = _merge_groups(
                    merged, area, sin_sum, cos_sum, top, bottom, mask.shape[0]
                )
                bearing = np.arctan2(sin_sum, cos_sum)
        distance = self.distance_from_edges(
            cls, bearing, top.astype(float), bottom.astype(float) + 1.0
        )
        return bearing, distance, area

    def distance_from_edges(
        self, cls: int, bearing: np.ndarray, top_edge: np.ndarray, bottom_edge: np.ndarray
    ) -> np.ndarray:
        """Horizontal distance of blobs of class ``cls`` from their top and bottom image edges.

        Args:
            cls: colour class (its target shape gives the heights of the edges).
            bearing: (k,) rad, the blobs' bearings (select the view and the abscissa u).
            top_edge, bottom_edge: (k,) continuous row coordinates of the blobs' upper and
                lower boundaries (0 = top of the strip; a blob covering rows a..b has edges
                a and b + 1).
        """
        proj = self.projection
        shape = self.geometry.shapes[cls]
        hc = self.geometry.camera_height
        _, offset = proj.view_coordinates(bearing)
        u = np.tan(offset)
        v_top = cast(np.ndarray, proj.v_at_row(top_edge))
        v_bot = cast(np.ndarray, proj.v_at_row(bottom_edge))
        height_top, height_bottom = np.asarray(hc - shape.z_top), np.asarray(hc - shape.z_bottom)
        d_top = proj.horizontal_distance(height_top, v_top, u) - shape.rim_offset
        d_bot = proj.horizontal_distance(height_bottom, v_bot, u) + shape.rim_offset
        pixel = 1.0 / proj.px_per_v
        with np.errstate(divide="ignore", invalid="ignore"):
            tolerance = _EDGE_TOLERANCE_PX * pixel * (1.0 / np.abs(v_top) + 1.0 / np.abs(v_bot))
            bottom_ok = (bottom_edge < self.config.height) & (d_bot <= d_top * (1.0 + tolerance))
            w_top, w_bot = v_top**2, v_bot**2
            both = (w_top * d_top + w_bot * d_bot) / (w_top + w_bot)
        d = np.where(bottom_ok, both, d_top)
        d = np.where(np.isfinite(d), d, np.inf)
        return np.maximum(d, 0.0)

    def _angular_extent(
        self, group: np.ndarray, cols: np.ndarray, bearing: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each group's bearing interval relative to its mean bearing (rad): (low, high),
        pixel edges included (low < 0 < high)."""
        dev = np.angle(np.exp(1j * (bearing[group] - self.projection.column_bearing[cols])))
        # dev > 0: the pixel is to the right of (at a smaller bearing than) the mean.
        half_px = 0.5 * (2.0 * math.pi / self.config.strip_width)
        lo = np.zeros(len(bearing))
        hi = np.zeros(len(bearing))
        np.maximum.at(lo, group, dev)
        np.maximum.at(hi, group, -dev)
        return -(lo + half_px), hi + half_px

    def _group_stacked(
        self,
        bearing: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        top: np.ndarray,
        bottom: np.ndarray,
    ) -> np.ndarray | None:
        """Group blobs stacked vertically at the same bearing (a pack cut by its electrode ring).

        The two bands of one pack have the same angular width (same cylinder, same distance)
        and the ring between them is shorter than the taller band; the pair test is
        :func:`~cyber_rodent.vision.segmentation_kernels.join_stacked`. A farther pack seen
        *above* a nearer one without touching it must be more than 2.4 times as far (its bottom
        rim, 17 cm below the camera, has to appear above the near pack's top, 7 cm below),
        hence at most 41 % as wide: it stays separate.

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
            np.asarray(bottom, dtype=np.int64), parent,
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


def _union(parent: np.ndarray, a: int, b: int) -> None:
    ra, rb = int(parent[a]), int(parent[b])
    while parent[ra] != ra:
        ra = int(parent[ra])
    while parent[rb] != rb:
        rb = int(parent[rb])
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


def _join_wrapped(labels: np.ndarray, parent: np.ndarray) -> None:
    """Join components that touch across the strip's left/right seam (8-connectivity)."""
    left, right = labels[:, 0], labels[:, -1]
    if not (left.any() and right.any()):
        return
    for dr in (-1, 0, 1):
        a = left[max(dr, 0) : len(left) + min(dr, 0)]
        b = right[max(-dr, 0) : len(right) + min(-dr, 0)]
        both = (a > 0) & (b > 0)
        for la, lb in set(zip(a[both].tolist(), b[both].tolist(), strict=True)):
            _union(parent, la, lb)


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


class Labeller:
    """The compiled labelling's buffers for strips of one shape, and its bound kernels.

    The run buffers start small and grow to the worst case (a checkerboard) the first time a
    frame overflows them.

    Args:
        rows, width: the stacked strips' shape (all robots' rows, strip width).
        height: rows per robot strip.
        n_classes: colour classes (bits of the look-up table).
        column_bearing: (width,) rad, each column's bearing.
        table: the classes' look-up table (:func:`~.segmentation_kernels.class_lut`).
    """

    def __init__(
        self,
        rows: int,
        width: int,
        height: int,
        n_classes: int,
        column_bearing: np.ndarray,
        table: kernels.ClassTable,
    ):
        self.table = table
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
            comp_stats=np.empty((capacity, 3), dtype=np.float64),
            comp_ints=np.empty((capacity, 4), dtype=np.int64),
        )
        self.extent_buffers = kernels.Extents(
            counts=np.zeros(3, dtype=np.int64),
            bearing=np.empty(capacity, dtype=np.float64),
            lo=np.empty(capacity, dtype=np.float64),
            hi=np.empty(capacity, dtype=np.float64),
        )
        self._extents = bind(kernels.extents, self.runs, self.strip, self.extent_buffers)

    def label(self, rgb: np.ndarray) -> Blobs:
        """Connected class blobs of stacked omni strips, with their pixel statistics.

        Args:
            rgb: (rows, width, 3) uint8 C-contiguous RGB, every robot's strip stacked.
        """
        # The image is an argument, not a bound buffer: MuJoCo's renderer returns a new array
        # every frame, and rebinding costs more than numba's dispatch on these named buffers.
        while True:
            n, k = kernels.label(rgb, self.table, self.strip, self.runs)
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
