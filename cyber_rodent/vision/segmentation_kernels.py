"""Colour segmentation kernels: a class look-up table, run-based blob labelling, pack grouping.

Segmenting with OpenCV (convert the whole stacked image to HSV, threshold it per class, then per
robot and class label connected components and gather pixel statistics) spends almost all its
work on pixels that belong to no class. These kernels do the same segmentation in two steps:

* :func:`class_lut`: a table over all 2²⁴ RGB colours whose bit ``c`` says "this colour is in
  class ``c``'s HSV box". It is computed once per threshold set *with OpenCV's own*
  ``cvtColor`` and ``inRange``, so a pixel's classes are exactly those of
  ``OmniSegmenter.masks`` (tested), whatever OpenCV's rounding. :func:`identity_table` is the
  table of images that already hold class bits (a segmenter measuring given masks).
* :func:`label`: one compiled pass over the stacked strips. Each row is classified through the
  table and cut into runs of same-class pixels; runs are joined with 8-connectivity to runs of
  the row above and across the strip's left/right seam (union-find, roots = earliest run, so
  components come in raster order); then every component's pixel statistics are accumulated in
  each component's raster order (pixels row by row, left to right), the order in which
  ``bincount`` sums a ``findNonZero`` or ``np.nonzero`` list, so the sums are bit-identical to
  those of a pixel list. :func:`extents` then gives the bearing interval of each
  component of one class (a pack's two bands are grouped by it).

Each kernel has a numpy reference with the same signature, written independently:
:func:`label_reference` (the table by fancy indexing, runs from ``np.diff``, runs joined where
their pixels touch and the components found by label propagation, the sums by ``bincount``),
:func:`extents_reference` and :func:`join_stacked_reference`; the segmenter picks one of each
pair by its ``backend`` (``tests/test_kernel_parity.py`` compares them buffer by buffer, and
``tests/test_vision_segmentation_kernel.py`` compares the detections with OpenCV's connected
components).

The kernels read and write named buffers owned by
:class:`~cyber_rodent.vision.segmentation.Labeller`: :class:`ClassTable`, :class:`StripBuffers`,
:class:`Runs` and :class:`Extents`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np
import numpy.typing as npt

from cyber_rodent.backend import jit

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Bytes = npt.NDArray[np.uint8]
#: ``OmniSegmenter``'s inRange intervals of one class: (low, high) HSV bounds, OR-ed.
HsvBounds = list[tuple[Bytes, Bytes]]

_TWO_PI = 2.0 * math.pi


class ClassTable(NamedTuple):
    """The colour classes of every RGB colour (:func:`class_lut`)."""

    lut: Bytes  #: (2²⁴,) bit c of entry ``r << 16 | g << 8 | b``: the colour is in class c
    min_chroma: int  #: smallest ``max(r,g,b) − min(r,g,b)`` of any colour in a class


class StripBuffers(NamedTuple):
    """The stacked strips' constants and per-row scratch (rows = robots × height)."""

    height: int  #: rows per robot strip
    n_classes: int  #: colour classes (bits of the table)
    column_bearing: Floats  #: (width,) rad, each column's bearing
    sin_col: Floats  #: (width,) its sine
    cos_col: Floats  #: (width,) its cosine
    half_px: float  #: rad, half a column
    bits: Bytes  #: (rows, width) output: class bits of every pixel
    edge_left: Ints  #: (rows, n_classes) run touching the left edge, or -1
    edge_right: Ints  #: (rows, n_classes) run touching the right edge, or -1


class Runs(NamedTuple):
    """Runs of same-class pixels and the components they form (``capacity`` of each)."""

    row: Ints  #: row of each run in the stacked strips
    c0: Ints  #: its first column
    c1: Ints  #: its last column
    cls: Ints  #: its class
    parent: Ints  #: union-find parent; after :func:`label`, its root run
    comp: Ints  #: after :func:`label`, its component
    #: (capacity, 7) per component: area, sums of sin and cos of bearing over its pixels, then
    #: the same two sums over its top row's pixels and over its bottom row's
    comp_stats: Floats
    comp_ints: Ints  #: (capacity, 4) per component: robot, class, top and bottom row


class Extents(NamedTuple):
    """Input and output of :func:`extents` (``capacity`` components at most)."""

    counts: Ints  #: (3,) runs and components of the last :func:`label`, and the class asked
    bearing: Floats  #: (capacity,) each component's mean bearing
    lo: Floats  #: (capacity,) output: low end of its bearing interval, relative to the mean
    hi: Floats  #: (capacity,) output: high end


#: Per threshold set (the tuple of the bounds of each class), its look-up table (16 MiB).
_LUT_CACHE: dict[tuple[object, ...], ClassTable] = {}


def class_lut(bounds: list[HsvBounds]) -> ClassTable:
    """The class of every RGB colour under ``bounds`` (each class's inRange intervals).

    Greys (floor, walls, bodies) are most of every image; a pixel whose chroma is below the
    table's minimum is in no class, so the labelling pass skips the table for it. The minimum
    is measured on the table itself, so the shortcut never changes a pixel's classes. Built
    with OpenCV on an image holding every colour once, cached per bounds.
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
    min_chroma = 256
    if len(member):
        min_chroma = int((member.max(axis=1).astype(np.int64) - member.min(axis=1)).min())
    table = _LUT_CACHE[key] = ClassTable(lut, min_chroma)
    return table


_IDENTITY: dict[int, ClassTable] = {}


def identity_table(n_classes: int) -> ClassTable:
    """The table of images whose blue channel already holds class bits: colour ``(0, 0, b)``
    is in the classes of the bits of ``b`` (``b < 2**n_classes``), every other colour in none.

    It lets the labelling measure given class masks (``OmniSegmenter.measure_blobs``). Cached
    per number of classes.
    """
    cached = _IDENTITY.get(n_classes)
    if cached is None:
        lut = np.zeros(1 << 24, dtype=np.uint8)
        lut[: 1 << n_classes] = np.arange(1 << n_classes, dtype=np.uint8)
        lut.setflags(write=False)
        cached = _IDENTITY[n_classes] = ClassTable(lut, 1)
    return cached


@jit
def _find(parent: Ints, a: int) -> int:
    root = a
    while parent[root] != root:
        root = parent[root]
    while parent[a] != root:  # path compression
        nxt = parent[a]
        parent[a] = root
        a = nxt
    return root


@jit
def _union(parent: Ints, a: int, b: int) -> None:
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@jit
def label(rgb: Bytes, table: ClassTable, strip: StripBuffers, runs: Runs) -> tuple[int, int]:
    """Label the connected class blobs of stacked strips and sum their pixel statistics.

    Args:
        rgb: (rows, width, 3) uint8 C-contiguous RGB, every robot's strip stacked.

    Returns:
        (runs, components), or (-1, 0) when the run buffers are full (the caller retries with
        room for the worst case; the buffers then hold no result). Components come ordered by
        robot, then in each robot by first pixel in raster order, in ``runs.comp_stats`` and
        ``runs.comp_ints``; runs by row, class, then column, each with its root run (its
        component's earliest) in ``runs.parent`` and its component in ``runs.comp``;
        ``strip.edge_left``/``edge_right`` hold the run of each row and class touching the
        strip's left/right edge, or -1.
    """
    lut, min_chroma = table
    height, n_classes, bits = strip.height, strip.n_classes, strip.bits
    sin_col, cos_col = strip.sin_col, strip.cos_col
    edge_left, edge_right = strip.edge_left, strip.edge_right
    run_row, run_c0, run_c1, run_cls, parent, run_comp, comp_stats, comp_ints = runs
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
            for q in range(3, 7):  # the same sums over the top row and the bottom row
                comp_stats[k, q] = 0.0
            k += 1
        parent[i] = root
        run_comp[i] = comp_of_root[root]
    # Pixel sums per component in raster order: per robot and class, pixels row by row,
    # left to right (OpenCV's findNonZero), i.e. runs by (robot, class, row, column).
    order = np.argsort(run_cls[:n] * rows + run_row[:n], kind="mergesort")
    for j in range(n):
        i = order[j]
        g = run_comp[i]
        row = run_row[i] % height
        # Rows come in increasing order per component: its first row is its top row.
        if row > comp_ints[g, 3]:
            comp_ints[g, 3] = row
            comp_stats[g, 5] = 0.0
            comp_stats[g, 6] = 0.0
        at_top, at_bottom = row == comp_ints[g, 2], row == comp_ints[g, 3]
        for x in range(run_c0[i], run_c1[i] + 1):
            comp_stats[g, 0] += 1.0
            comp_stats[g, 1] += sin_col[x]
            comp_stats[g, 2] += cos_col[x]
            if at_top:
                comp_stats[g, 3] += sin_col[x]
                comp_stats[g, 4] += cos_col[x]
            if at_bottom:
                comp_stats[g, 5] += sin_col[x]
                comp_stats[g, 6] += cos_col[x]
    return n, k


def label_reference(
    rgb: Bytes, table: ClassTable, strip: StripBuffers, runs: Runs
) -> tuple[int, int]:
    """:func:`label` in numpy: the same buffers filled with the same values.

    Classes by indexing the table with every pixel's colour; per class, runs where ``np.diff``
    of a row's membership rises and falls, numbered in :func:`label`'s order (row, class,
    column); pairs of runs whose pixels touch (8-connectivity: the row below within a strip,
    and across the seam), joined by label propagation until every run carries its component's
    smallest run; the pixel sums by ``bincount`` over the pixels in run order, which is each
    component's raster order.
    """
    rows, width = rgb.shape[0], rgb.shape[1]
    height, n_classes = strip.height, strip.n_classes
    colour = rgb.astype(np.int64)
    # The table's min_chroma only lets the kernel skip greys: the table puts them in no class.
    bits = table.lut[(colour[..., 0] << 16) | (colour[..., 1] << 8) | colour[..., 2]]
    strip.bits[:] = bits

    # Runs per class, in raster order within the class.
    member = [((bits >> c) & 1).astype(np.int8) for c in range(n_classes)]
    found = []
    for c in range(n_classes):
        step = np.diff(member[c], axis=1, prepend=0, append=0)  # +1 at a start, -1 past an end
        row, first = np.nonzero(step == 1)
        _, past = np.nonzero(step == -1)
        found.append((row, first, past - 1, np.full(len(row), c, dtype=np.int64)))
    run_row, run_c0, run_c1, run_cls = (np.concatenate(parts) for parts in zip(*found, strict=True))
    n = len(run_row)
    if n > len(runs.row):
        return -1, 0
    order = np.lexsort((run_c0, run_cls, run_row))  # the kernel's numbering
    number = np.empty(n, dtype=np.int64)
    number[order] = np.arange(n)  # run number of the j-th run found (class by class)
    run_row, run_c0, run_c1, run_cls = run_row[order], run_c0[order], run_c1[order], run_cls[order]
    runs.row[:n], runs.c0[:n], runs.c1[:n], runs.cls[:n] = run_row, run_c0, run_c1, run_cls
    strip.edge_left[:] = -1
    strip.edge_right[:] = -1
    at_left, at_right = run_c0 == 0, run_c1 == width - 1
    strip.edge_left[run_row[at_left], run_cls[at_left]] = np.flatnonzero(at_left)
    strip.edge_right[run_row[at_right], run_cls[at_right]] = np.flatnonzero(at_right)

    # Touching runs: a pixel and its three neighbours in the next row of the same strip, and a
    # first-column pixel and the last-column pixels of its own and the adjacent rows.
    below = (np.arange(1, rows) % height != 0)[:, None]  # the next row is in the same strip
    same_strip = np.arange(rows) // height
    first_of_class = 0
    touching = []
    for c in range(n_classes):
        inside = member[c] > 0
        run_of = np.full((rows, width), -1, dtype=np.int64)
        starts = np.diff(member[c], axis=1, prepend=0) == 1
        ordinal = np.cumsum(starts.ravel()).reshape(rows, width) - 1 + first_of_class
        run_of[inside] = number[ordinal[inside]]
        first_of_class += int(starts.sum())
        upper, lower = run_of[:-1], run_of[1:]
        for a, b in (
            (upper[:, 1:], lower[:, :-1]),  # down and left
            (upper, lower),  # straight down
            (upper[:, :-1], lower[:, 1:]),  # down and right
        ):
            both = (a >= 0) & (b >= 0) & below
            touching.append((a[both], b[both]))
        left, right = run_of[:, 0], run_of[:, -1]
        for shift in (-1, 0, 1):
            r = np.arange(max(0, -shift), min(rows, rows - shift))
            a, b = left[r], right[r + shift]
            both = (a >= 0) & (b >= 0) & (same_strip[r] == same_strip[r + shift])
            touching.append((a[both], b[both]))
    ends = np.concatenate([a for a, _ in touching]), np.concatenate([b for _, b in touching])
    pair = np.unique(ends[0] * n + ends[1]) if n else np.zeros(0, dtype=np.int64)
    a, b = pair // max(n, 1), pair % max(n, 1)
    root = np.arange(n)
    while True:
        while not np.array_equal(root[root], root):
            root = root[root]
        ra, rb = root[a], root[b]
        if np.array_equal(ra, rb):
            break
        low = np.minimum(ra, rb)
        np.minimum.at(root, ra, low)  # hook both roots under the smaller
        np.minimum.at(root, rb, low)
    runs.parent[:n] = root

    # Components in the order of their smallest run; their statistics.
    first_run = np.flatnonzero(root == np.arange(n))
    k = len(first_run)
    comp = np.searchsorted(first_run, root)
    runs.comp[:n] = comp
    in_strip = run_row % height
    top = np.full(k, height, dtype=np.int64)
    bottom = np.full(k, -1, dtype=np.int64)
    np.minimum.at(top, comp, in_strip)
    np.maximum.at(bottom, comp, in_strip)
    runs.comp_ints[:k] = np.stack(
        [run_row[first_run] // height, run_cls[first_run], top, bottom], axis=1
    )
    length = run_c1 - run_c0 + 1
    pixel_comp = np.repeat(comp, length)
    start = np.cumsum(length) - length  # each run's first pixel in the list of pixels
    pixel_col = np.arange(int(length.sum())) - np.repeat(start - run_c0, length)
    runs.comp_stats[:k, 0] = np.bincount(pixel_comp, minlength=k)
    runs.comp_stats[:k, 1] = np.bincount(pixel_comp, weights=strip.sin_col[pixel_col], minlength=k)
    runs.comp_stats[:k, 2] = np.bincount(pixel_comp, weights=strip.cos_col[pixel_col], minlength=k)
    pixel_row = np.repeat(in_strip, length)
    for q, edge in ((3, top), (5, bottom)):
        on_edge = pixel_row == edge[pixel_comp]
        comp, col = pixel_comp[on_edge], pixel_col[on_edge]
        runs.comp_stats[:k, q] = np.bincount(comp, weights=strip.sin_col[col], minlength=k)
        runs.comp_stats[:k, q + 1] = np.bincount(comp, weights=strip.cos_col[col], minlength=k)
    return n, k


@jit
def extents(runs: Runs, strip: StripBuffers, ext: Extents) -> None:
    """The bearing interval relative to its mean of each component of class ``ext.counts[2]``
    (``OmniSegmenter`` groups a pack's two bands by it): the largest deviation of any of its
    pixels to either side, plus half a pixel; other components get half a pixel either side.

    Within a run the columns' bearings fall steadily (a run never crosses the strip's seam, and
    a blob spans far less than 180°), so a run's extremes are at its two end pixels; only those
    are evaluated.
    """
    n, k, cls = ext.counts[0], ext.counts[1], ext.counts[2]
    bearing, lo, hi = ext.bearing, ext.lo, ext.hi
    column_bearing, half_px = strip.column_bearing, strip.half_px
    for g in range(k):
        lo[g] = 0.0
        hi[g] = 0.0
    for i in range(n):
        if runs.cls[i] != cls:
            continue
        g = runs.comp[i]
        for x in (runs.c0[i], runs.c1[i]):
            d = bearing[g] - column_bearing[x]
            dev = math.atan2(math.sin(d), math.cos(d))
            if dev > lo[g]:
                lo[g] = dev
            if -dev > hi[g]:
                hi[g] = -dev
    for g in range(k):
        lo[g] = -(lo[g] + half_px)
        hi[g] = hi[g] + half_px


#: An angle wrapped to [-π, π] as ``atan2(sin, cos)`` of the C library (elementwise).
_wrap = np.vectorize(lambda d: math.atan2(math.sin(d), math.cos(d)), otypes=[np.float64])


def extents_reference(runs: Runs, strip: StripBuffers, ext: Extents) -> None:
    """:func:`extents` in numpy: the deviations of every run's two end pixels at once.

    The end pixels are the ones the rule needs (see :func:`extents`); evaluating exactly them
    keeps the two equal on any strip, a blob wider than half the circle included. The
    deviation is wrapped with the C library's ``atan2`` (as the compiled kernel's), since
    numpy's vectorised ``arctan2`` may round the last bit differently.
    """
    n, k, cls = (int(v) for v in ext.counts)
    mine = np.flatnonzero(runs.cls[:n] == cls)
    comp = np.concatenate([runs.comp[mine], runs.comp[mine]])
    column = np.concatenate([runs.c0[mine], runs.c1[mine]])
    dev = _wrap(ext.bearing[comp] - strip.column_bearing[column])
    # dev > 0: the pixel is to the right of (at a smaller bearing than) the mean.
    right = np.zeros(k)
    left = np.zeros(k)
    np.maximum.at(right, comp, dev)
    np.maximum.at(left, comp, -dev)
    ext.lo[:k] = -(right + strip.half_px)
    ext.hi[:k] = left + strip.half_px


@jit
def join_stacked(
    bearing: Floats, lo: Floats, hi: Floats, top: Ints, bottom: Ints, parent: Ints,
    height: int, pixel: float,
) -> bool:  # fmt: skip
    """Union, in ``parent``, every pair of blobs that are parts of one pack; says whether any
    pair was joined (compiled: it is O(k²) in the blobs).

    Of two blobs, the upper one (smaller ``top``) and the lower one are parts of one pack when
    their bearing intervals (``lo``/``hi`` relative to the mean ``bearing``) overlap by at least
    70 % of the narrower one's width, the lower one is no wider than the upper one (by 20 % and
    a ``pixel``: a wider blob below is a nearer pack), and either

    * the vertical gap between their rows is smaller than the taller one's height (the pack's
      own electrode ring between its bands; the upper one may be wider when packs that touch
      in the image merged above their rings),
    * the lower one is at least 70 % as wide, whatever the gap (something nearer, a chassis,
      hides the pack's middle: the bands of one pack have one width, while two packs at one
      bearing and one width would stand in one place), or
    * the lower one touches the strip's bottom row (``height`` rows): a pack touching the
      robot shows its lower band cut off by the frame.

    Unions link the larger root under the smaller, so a set's root is its smallest blob
    whatever the order of the unions.
    """
    k = bearing.shape[0]
    joined = False
    for a in range(k):
        for b in range(a + 1, k):
            d = bearing[b] - bearing[a]
            shift = d - _TWO_PI * np.rint(d / _TWO_PI)  # wrapped to [-π, π]
            overlap = min(hi[a], shift + hi[b]) - max(lo[a], shift + lo[b])
            wa, wb = hi[a] - lo[a], hi[b] - lo[b]
            if overlap < 0.7 * min(wa, wb):
                continue
            up, w_up, w_low = a, wa, wb
            low = b
            if top[b] < top[a]:
                up, low, w_up, w_low = b, a, wb, wa
            if w_low > 1.2 * w_up + pixel:
                continue
            gap = max(top[a], top[b]) - min(bottom[a], bottom[b]) - 1
            tall = max(bottom[a] - top[a] + 1, bottom[b] - top[b] + 1)
            ring = gap < tall
            hidden_middle = w_low >= 0.7 * w_up
            cut = bottom[low] >= height - 1
            if ring or hidden_middle or cut:
                ra, rb = up, low
                while parent[ra] != ra:
                    ra = parent[ra]
                while parent[rb] != rb:
                    rb = parent[rb]
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
                joined = True
    return joined


def join_stacked_reference(
    bearing: Floats, lo: Floats, hi: Floats, top: Ints, bottom: Ints, parent: Ints,
    height: int, pixel: float,
) -> bool:  # fmt: skip
    """:func:`join_stacked` in numpy (the reference): the pair test on all pairs at once."""
    d = bearing[None, :] - bearing[:, None]  # [a, b]: bearing[b] - bearing[a]
    shift = d - _TWO_PI * np.rint(d / _TWO_PI)
    overlap = np.minimum(hi[:, None], shift + hi[None, :]) - np.maximum(
        lo[:, None], shift + lo[None, :]
    )
    width = hi - lo
    narrow = np.minimum(width[:, None], width[None, :])
    b_up = top[None, :] < top[:, None]  # [a, b]: b is the upper one
    w_up = np.where(b_up, width[None, :], width[:, None])
    w_low = np.where(b_up, width[:, None], width[None, :])
    bottom_low = np.where(b_up, bottom[:, None], bottom[None, :])
    gap = np.maximum(top[:, None], top[None, :]) - np.minimum(bottom[:, None], bottom[None, :]) - 1
    tall = bottom - top + 1
    ring = gap < np.maximum(tall[:, None], tall[None, :])
    hidden_middle = w_low >= 0.7 * w_up
    cut = bottom_low >= height - 1
    ok = ~(overlap < 0.7 * narrow) & ~(w_low > 1.2 * w_up + pixel)
    pairs = np.triu(ok & (ring | hidden_middle | cut), 1)
    first, second = np.nonzero(pairs)
    for a, b in zip(first.tolist(), second.tolist(), strict=True):
        ra, rb = a, b
        while parent[ra] != ra:
            ra = int(parent[ra])
        while parent[rb] != rb:
            rb = int(parent[rb])
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    return bool(len(first))
