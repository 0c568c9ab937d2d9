"""Compiled (numba) colour segmentation: a class look-up table and run-based blob labelling.

The OpenCV path of :class:`~cyber_rodent.vision.segmentation.OmniSegmenter` converts the whole
stacked image to HSV, thresholds it four times and then, per robot and class, labels connected
components and gathers pixel statistics with a dozen numpy calls. At the default resolution
(4 robots × 4 views of 128 × 192 px) that is ~3 ms per control step, more than the rest of the
evolution loop together, and almost all of it is spent on pixels that belong to no class. Here
the same segmentation is two steps:

* :func:`class_lut`: a table over all 2²⁴ RGB colours whose bit ``c`` says "this colour is in
  class ``c``'s HSV box". It is computed once per threshold set *with OpenCV's own*
  ``cvtColor`` and ``inRange``, so a pixel's classes are exactly those of
  ``OmniSegmenter.masks`` (tested), whatever OpenCV's rounding.
* :meth:`Labeller.label`: one compiled pass over the stacked strips. Each row is classified
  through the table and cut into runs of same-class pixels; runs are joined with
  8-connectivity to runs of the row above and across the strip's left/right seam (union-find,
  roots = earliest run, so components come in raster order); then every component's pixel
  statistics are accumulated in the order numpy's ``bincount`` uses on OpenCV's
  ``findNonZero`` list, so the sums are bit-identical to the reference.

What is done per component afterwards (grouping a pack's two bands, distances) is shared with
the OpenCV path (:mod:`cyber_rodent.vision.segmentation`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from cyber_rodent import compiled
from cyber_rodent.compiled import jit as _jit

__all__ = ["AVAILABLE", "Labeller", "class_lut"]

AVAILABLE = compiled.AVAILABLE

#: Per threshold set (the tuple of ``_hsv_bounds`` of each class), its look-up table (16 MiB).
_LUT_CACHE: dict[tuple, tuple[np.ndarray, int]] = {}


def class_lut(bounds: list[list[tuple[np.ndarray, np.ndarray]]]) -> tuple[np.ndarray, int]:
    """The (2²⁴,) uint8 table: bit ``c`` of entry ``r << 16 | g << 8 | b`` is set when that RGB
    colour passes class ``c``'s HSV bounds (``OmniSegmenter``'s inRange intervals, OR-ed), and
    the smallest chroma ``max(r,g,b) − min(r,g,b)`` of any colour in a class.

    Greys (floor, walls, bodies) are most of every image; a pixel whose chroma is below that
    minimum is in no class, so the labelling pass skips the table for it. The minimum is
    measured on the table itself, so the shortcut never changes a pixel's classes.
    Built with OpenCV on an image holding every colour once (~0.3 s), cached per bounds.
    """
    key = tuple(tuple((tuple(lo.tolist()), tuple(hi.tolist())) for lo, hi in b) for b in bounds)
    cached = _LUT_CACHE.get(key)
    if cached is not None:
        return cached
    index = np.arange(1 << 24, dtype=np.uint32)
    rgb = np.empty((1 << 12, 1 << 12, 3), dtype=np.uint8)
    flat = rgb.reshape(-1, 3)
    flat[:, 0] = index >> 16
    flat[:, 1] = (index >> 8) & 0xFF
    flat[:, 2] = index & 0xFF
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    lut = np.zeros(1 << 24, dtype=np.uint8)
    for c, intervals in enumerate(bounds):
        mask = np.zeros(rgb.shape[:2], dtype=np.uint8)
        for lo, hi in intervals:
            cv2.bitwise_or(mask, cv2.inRange(hsv, lo, hi), dst=mask)
        lut |= (mask.reshape(-1) > 0).astype(np.uint8) << c
    lut.setflags(write=False)
    member = flat[lut > 0]
    chroma = member.max(axis=1).astype(np.int64) - member.min(axis=1) if len(member) else None
    min_chroma = int(chroma.min()) if chroma is not None else 256
    _LUT_CACHE[key] = (lut, min_chroma)
    return lut, min_chroma


@_jit
def _find(parent: np.ndarray, a: int) -> int:
    root = a
    while parent[root] != root:
        root = parent[root]
    while parent[a] != root:  # path compression
        nxt = parent[a]
        parent[a] = root
        a = nxt
    return root


@_jit
def _union(parent: np.ndarray, a: int, b: int) -> None:
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@_jit
def _label(
    rgb: np.ndarray,
    lut: np.ndarray,
    min_chroma: int,
    height: int,
    n_classes: int,
    sin_col: np.ndarray,
    cos_col: np.ndarray,
    bits: np.ndarray,
    run_row: np.ndarray,
    run_c0: np.ndarray,
    run_c1: np.ndarray,
    run_cls: np.ndarray,
    parent: np.ndarray,
    edge_left: np.ndarray,
    edge_right: np.ndarray,
    comp_stats: np.ndarray,
    comp_ints: np.ndarray,
) -> tuple[int, int]:
    """The labelling pass; see :meth:`Labeller.label`. Returns (runs, components), or (-1, 0)
    when a run array is full (the caller retries with room for the worst case)."""
    rows, width = rgb.shape[0], rgb.shape[1]
    cap = run_row.shape[0]
    n = 0
    prev_start = np.zeros(n_classes, dtype=np.int64)
    prev_end = np.zeros(n_classes, dtype=np.int64)
    for r in range(rows):
        any_bits = 0
        for x in range(width):
            red, green, blue = (
                np.int64(rgb[r, x, 0]),
                np.int64(rgb[r, x, 1]),
                np.int64(rgb[r, x, 2]),
            )
            if max(red, green, blue) - min(red, green, blue) < min_chroma:
                bits[r, x] = 0
            else:
                b = lut[(red << 16) | (green << 8) | blue]
                bits[r, x] = b
                any_bits |= b
        first_row = r % height == 0
        for c in range(n_classes):
            start = n
            edge_left[r, c] = -1
            edge_right[r, c] = -1
            x = 0 if (any_bits >> c) & 1 else width
            while x < width:
                if (bits[r, x] >> c) & 1:
                    x0 = x
                    while x < width and (bits[r, x] >> c) & 1:
                        x += 1
                    if n == cap:
                        return -1, 0
                    run_row[n] = r
                    run_c0[n] = x0
                    run_c1[n] = x - 1
                    run_cls[n] = c
                    parent[n] = n
                    if not first_row:
                        for q in range(prev_start[c], prev_end[c]):
                            if run_c0[q] <= x and x0 <= run_c1[q] + 1:
                                _union(parent, q, n)
                    if x0 == 0:
                        edge_left[r, c] = n
                    if x == width:
                        edge_right[r, c] = n
                    n += 1
                else:
                    x += 1
            prev_start[c] = start
            prev_end[c] = n
    # The strip is a full circle: pixels in its first and last columns touch (8-connectivity).
    for r in range(rows):
        top = r - r % height
        for c in range(n_classes):
            a = edge_left[r, c]
            if a < 0:
                continue
            for rr in range(max(top, r - 1), min(top + height, r + 2)):
                b = edge_right[rr, c]
                if b >= 0:
                    _union(parent, a, b)
    # Components in the order of their earliest run: per robot and class, OpenCV's raster order.
    comp_of_root = np.full(n, -1, dtype=np.int64)
    k = 0
    for i in range(n):
        root = _find(parent, i)
        if root == i:
            comp_of_root[i] = k
            # robot, class, top row, bottom row (rows within the strip)
            comp_ints[k, 0] = run_row[i] // height
            comp_ints[k, 1] = run_cls[i]
            comp_ints[k, 2] = run_row[i] % height
            comp_ints[k, 3] = run_row[i] % height
            comp_stats[k, 0] = 0.0  # area
            comp_stats[k, 1] = 0.0  # sum of sin(column bearing)
            comp_stats[k, 2] = 0.0  # sum of cos(column bearing)
            k += 1
        parent[i] = root
    # Pixel sums per component in the reference's order: per robot and class, pixels row by row,
    # left to right (OpenCV's findNonZero), i.e. runs by (robot, class, row, column).
    order = np.argsort(run_cls[:n] * rows + run_row[:n], kind="mergesort")
    for j in range(n):
        i = order[j]
        g = comp_of_root[parent[i]]
        row = run_row[i] % height
        if row < comp_ints[g, 2]:
            comp_ints[g, 2] = row
        if row > comp_ints[g, 3]:
            comp_ints[g, 3] = row
        for x in range(run_c0[i], run_c1[i] + 1):
            comp_stats[g, 0] += 1.0
            comp_stats[g, 1] += sin_col[x]
            comp_stats[g, 2] += cos_col[x]
    return n, k


@_jit
def _extents(
    n: int,
    run_c0: np.ndarray,
    run_c1: np.ndarray,
    run_comp: np.ndarray,
    run_cls: np.ndarray,
    cls: int,
    bearing: np.ndarray,
    column_bearing: np.ndarray,
    half_px: float,
    lo: np.ndarray,
    hi: np.ndarray,
) -> None:
    """The bearing interval relative to its mean of each component of class ``cls``
    (OmniSegmenter._angular_extent): the largest deviation of any of its pixels to either side,
    plus half a pixel. Within a run the columns' bearings fall steadily (a run never crosses
    the strip's seam, and a blob spans far less than 180°), so a run's extremes are at its two
    end pixels; only those are evaluated."""
    for i in range(n):
        if run_cls[i] != cls:
            continue
        g = run_comp[i]
        for x in (run_c0[i], run_c1[i]):
            d = bearing[g] - column_bearing[x]
            dev = math.atan2(math.sin(d), math.cos(d))
            if dev > lo[g]:
                lo[g] = dev
            if -dev > hi[g]:
                hi[g] = -dev
    for g in range(lo.shape[0]):
        lo[g] = -(lo[g] + half_px)
        hi[g] = hi[g] + half_px


class Labeller:
    """Reusable buffers for labelling strips of one shape.

    Args:
        rows, width: the stacked strips' shape (all robots' rows, strip width).
        height: rows per robot strip.
        n_classes: colour classes (bits of the look-up table).
        column_bearing: (width,) rad, each column's bearing.
    """

    def __init__(
        self, rows: int, width: int, height: int, n_classes: int, column_bearing: np.ndarray
    ):
        self.height = height
        self.n_classes = n_classes
        self.column_bearing = np.ascontiguousarray(column_bearing, dtype=np.float64)
        self.sin_col = np.sin(self.column_bearing)
        self.cos_col = np.cos(self.column_bearing)
        self.half_px = 0.5 * (2.0 * math.pi / width)
        self.bits = np.zeros((rows, width), dtype=np.uint8)
        self.edge_left = np.empty((rows, n_classes), dtype=np.int64)
        self.edge_right = np.empty((rows, n_classes), dtype=np.int64)
        self.worst = rows * n_classes * ((width + 1) // 2)
        self._allocate(min(self.worst, rows * n_classes * 8))

    def _allocate(self, capacity: int) -> None:
        self.capacity = capacity
        self.run_row = np.empty(capacity, dtype=np.int64)
        self.run_c0 = np.empty(capacity, dtype=np.int64)
        self.run_c1 = np.empty(capacity, dtype=np.int64)
        self.run_cls = np.empty(capacity, dtype=np.int64)
        self.parent = np.empty(capacity, dtype=np.int64)
        self.comp_stats = np.empty((capacity, 3), dtype=np.float64)
        self.comp_ints = np.empty((capacity, 4), dtype=np.int64)

    def label(self, rgb: np.ndarray, lut: tuple[np.ndarray, int]) -> dict[str, np.ndarray]:
        """Connected class blobs of stacked omni strips, with their pixel statistics.

        Args:
            rgb: (n_robots * height, strip_width, 3) uint8 C-contiguous RGB.
            lut: :func:`class_lut` of the classes' thresholds (table and minimum chroma).

        Returns:
            Per component (ordered by robot, then in each robot by first pixel in raster
            order): ``robot``, ``cls``, ``top``/``bottom`` (first/last row in the strip),
            ``area`` (pixels), ``sin_sum``/``cos_sum`` (sums over its pixels of the column
            bearing's sine and cosine), and ``n_runs`` for :meth:`extents`.
        """
        while True:
            n, k = _label(
                rgb, lut[0], lut[1], self.height, self.n_classes, self.sin_col, self.cos_col,
                self.bits, self.run_row, self.run_c0, self.run_c1, self.run_cls, self.parent,
                self.edge_left, self.edge_right, self.comp_stats, self.comp_ints,
            )  # fmt: skip
            if n >= 0:
                break
            self._allocate(self.worst)
        ints, stats = self.comp_ints[:k], self.comp_stats[:k]
        return {
            "robot": ints[:, 0].copy(),
            "cls": ints[:, 1].copy(),
            "top": ints[:, 2].copy(),
            "bottom": ints[:, 3].copy(),
            "area": stats[:, 0].copy(),
            "sin_sum": stats[:, 1].copy(),
            "cos_sum": stats[:, 2].copy(),
            "n_runs": n,
        }

    def extents(self, n_runs: int, bearing: np.ndarray, cls: int) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) bearing interval of every component of class ``cls`` of the last
        :meth:`label` call (other components: half a pixel either side)."""
        comp_of_run = self._run_components(n_runs)
        lo = np.zeros(len(bearing))
        hi = np.zeros(len(bearing))
        _extents(
            n_runs, self.run_c0, self.run_c1, comp_of_run, self.run_cls, cls,
            np.ascontiguousarray(bearing), self.column_bearing, self.half_px, lo, hi,
        )  # fmt: skip
        return lo, hi

    def _run_components(self, n_runs: int) -> np.ndarray:
        """Component index of each run (after :func:`_label`, ``parent`` holds each run's root
        and components are numbered in the order of their roots)."""
        roots = self.parent[:n_runs]
        is_root = roots == np.arange(n_runs)
        number = np.cumsum(is_root) - 1
        return number[roots]
