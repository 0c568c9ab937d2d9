"""The segmentation against OpenCV, and on hand-made strips whose blobs are known.

Either backend's segmenter (``backend="numba"``: the compiled kernels of
:mod:`cyber_rodent.vision.segmentation_kernels`; ``"numpy"``: their numpy references) must
classify every pixel exactly as OpenCV's cvtColor + inRange do, and find the blobs of OpenCV's
connected components (``connectedComponentsWithStats``, joined across the strip's seam), with
the same statistics, in the same order: checked on hand-made and on rendered strips. On
hand-made strips the blob counts are known by construction. (The kernels against their
references, buffer by buffer: ``test_kernel_parity.py``.)
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cyber_rodent.vision import BATTERY, FACE, LED, N_CLASSES, CameraConfig
from cyber_rodent.vision import segmentation_kernels as kernels
from cyber_rodent.vision.batch_rendering import BatchOmniRenderer
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import TargetGeometry, TargetShape, target_geometry
from cyber_rodent.world import World
from tests.conftest import Scenes

CONFIG = CameraConfig(n_views=4, view_width=16, height=12)
PACK = TargetShape(cls=BATTERY, plate=False, half_width=0.04, z_bottom=0.0, z_top=0.1)
FACE_PLATE = TargetShape(cls=FACE, plate=True, half_width=0.045, z_bottom=0.054, z_top=0.09)
LED_RING = TargetShape(cls=LED, plate=False, half_width=0.022, z_bottom=0.103, z_top=0.117)
GEOMETRY = TargetGeometry(camera_height=0.17, shapes=(LED_RING, FACE_PLATE, PACK))
CONFIG_BEARING = OmniSegmenter(CONFIG, GEOMETRY, backend="numpy").projection.column_bearing
Strips = dict[str, tuple[CameraConfig, np.ndarray]]


def _segmenters(
    config: CameraConfig = CONFIG, geometry: TargetGeometry = GEOMETRY
) -> tuple[OmniSegmenter, OmniSegmenter]:
    return (
        OmniSegmenter(config, geometry, backend="numba"),
        OmniSegmenter(config, geometry, backend="numpy"),
    )


def _roots(parent: np.ndarray) -> np.ndarray:
    root = parent.copy()
    while not np.array_equal(root[root], root):
        root = root[root]
    return root


def _opencv_blobs(seg: OmniSegmenter, mask: np.ndarray, cls: int) -> tuple[np.ndarray, ...]:
    """Bearing, distance and area of the blobs of one mask of one strip, with OpenCV.

    OpenCV's components (8-connectivity) and their area and bounding rows, joined across the
    strip's seam; pixel sums over ``findNonZero``'s list (raster order); blobs in the raster
    order of their first pixel; a pack's two bands grouped by the pair test's numpy reference;
    distances by the segmenter's edge rule.
    """
    height, width = mask.shape
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask, connectivity=8, ltype=cv2.CV_32S
    )
    parent = np.arange(count)
    for shift in (-1, 0, 1):  # the strip is a full circle: its first and last columns touch
        r = np.arange(max(0, -shift), min(height, height - shift))
        for a, b in zip(labels[r, 0].tolist(), labels[r + shift, width - 1].tolist(), strict=True):
            if a and b:
                ra, rb = _roots(parent)[[a, b]]
                parent[max(ra, rb)] = min(ra, rb)
    root = _roots(parent)
    points = cv2.findNonZero(mask).reshape(-1, 2)
    cols, rows = points[:, 0].astype(np.intp), points[:, 1].astype(np.intp)
    label = root[labels[rows, cols]]
    first = np.full(count, height * width)
    np.minimum.at(first, label, rows * width + cols)
    blobs = np.flatnonzero(first < height * width)
    rank = np.full(count, -1)
    rank[blobs[np.argsort(first[blobs])]] = np.arange(len(blobs))
    k = len(blobs)
    blob = rank[label]
    of_label = rank[root[1:]]
    area = np.zeros(k)
    np.add.at(area, of_label, stats[1:, cv2.CC_STAT_AREA])
    top = np.full(k, height)
    bottom = np.full(k, -1)
    np.minimum.at(top, of_label, stats[1:, cv2.CC_STAT_TOP])
    np.maximum.at(bottom, of_label, stats[1:, cv2.CC_STAT_TOP] + stats[1:, cv2.CC_STAT_HEIGHT] - 1)
    column_bearing = seg.projection.column_bearing
    sin_sum = np.bincount(blob, weights=np.sin(column_bearing)[cols], minlength=k)
    cos_sum = np.bincount(blob, weights=np.cos(column_bearing)[cols], minlength=k)
    bearing = np.arctan2(sin_sum, cos_sum)
    edge_bearing = []  # mean bearing of each blob's top row's pixels, then its bottom row's
    for edge in (top, bottom):
        on = rows == edge[blob]
        weights = (np.sin(column_bearing)[cols[on]], np.cos(column_bearing)[cols[on]])
        sums = [np.bincount(blob[on], weights=w, minlength=k) for w in weights]
        edge_bearing.append(np.arctan2(*sums))
    if cls == BATTERY and k > 1:
        dev = np.angle(np.exp(1j * (bearing[blob] - column_bearing[cols])))
        right, left = np.zeros(k), np.zeros(k)
        np.maximum.at(right, blob, dev)
        np.maximum.at(left, blob, -dev)
        half_px = math.pi / width
        pair = np.arange(k)
        if kernels.join_stacked_reference(
            bearing, -(right + half_px), left + half_px, top, bottom, pair, height, 2 * half_px
        ):
            _, group = np.unique(_roots(pair), return_inverse=True)
            m = int(group.max()) + 1
            area = np.bincount(group, weights=area, minlength=m)
            sin_sum = np.bincount(group, weights=sin_sum, minlength=m)
            cos_sum = np.bincount(group, weights=cos_sum, minlength=m)
            top_g, bottom_g = np.full(m, height), np.full(m, -1)
            np.minimum.at(top_g, group, top)
            np.maximum.at(bottom_g, group, bottom)
            top, bottom = top_g, bottom_g
            bearing = np.arctan2(sin_sum, cos_sum)
            edge_bearing = [bearing, bearing]
    distance = seg.distance_from_edges(
        cls, bearing, top.astype(float), bottom + 1.0, edge_bearing[0], edge_bearing[1]
    )
    return bearing, distance, area


def _assert_opencv_detections(seg: OmniSegmenter, strips: np.ndarray) -> int:
    """``seg.detect`` equals OpenCV's segmentation, bit for bit; returns the detections."""
    n, h, w, _ = strips.shape
    masks = seg.masks(strips.reshape(n * h, w, 3)).reshape(N_CLASSES, n, h, w)
    out: list[list[np.ndarray]] = [[], [], [], [], []]
    for i in range(n):
        for c in range(N_CLASSES):
            if not masks[c, i].any():
                continue
            bearing, distance, area = _opencv_blobs(seg, masks[c, i], c)
            keep = (area >= seg.config.min_blob_area[c]) & (distance <= seg.config.max_range)
            for j, v in enumerate((np.full(len(area), i), np.full(len(area), c))):
                out[j].append(v[keep])
            for j, v in enumerate((bearing, distance, area)):
                out[2 + j].append(v[keep])
    detections = seg.detect(strips)
    for got, want in zip(detections[:5], out, strict=True):
        np.testing.assert_array_equal(got, np.concatenate(want) if want else np.zeros(0))
    for c in range(N_CLASSES):
        np.testing.assert_array_equal((detections[5] >> c) & 1, masks[c] > 0)
    return len(detections[0])


def test_every_pixel_classified_as_opencv_does(segmentation_strips: Strips) -> None:
    """Random colours and colours near each class's edges: the same classes, the same blobs."""
    config, strips = segmentation_strips["colours"]
    for seg in _segmenters(config):
        classes = seg.detect(strips)[5].reshape(400, 64)
        masks = seg.masks(strips.reshape(400, 64, 3))
        for c in range(3):
            np.testing.assert_array_equal((classes >> c) & 1, masks[c] > 0)
        assert _assert_opencv_detections(seg, strips) > 0


def test_hand_made_blobs(segmentation_strips: Strips) -> None:
    """Counts known by construction: a blob across the seam is one; diagonal neighbours join
    (8-connectivity); a pack's two bands with a grey ring between them are one target."""
    config, strips = segmentation_strips["blobs"]
    assert config == CONFIG
    for seg in _segmenters():
        robot, cls, bearing, distance, area, classes = seg.detect(strips)
        np.testing.assert_array_equal(robot, [0, 0, 0, 1])
        np.testing.assert_array_equal(cls, [LED, FACE, FACE, BATTERY])
        np.testing.assert_array_equal(area, [8, 8, 4, 24])
        # The seam blob's bearing is the strip's edge bearing (columns 0 and 63 border it).
        edge = np.arctan2(np.sin(CONFIG_BEARING[[62, 63, 0, 1]]).sum(),
                          np.cos(CONFIG_BEARING[[62, 63, 0, 1]]).sum())  # fmt: skip
        assert bearing[0] == pytest.approx(edge)
        assert _assert_opencv_detections(seg, strips) == 4


def test_worst_case_run_count_grows_the_buffers(segmentation_strips: Strips) -> None:
    """A checkerboard of class colours has more runs than the first allocation holds."""
    config, strips = segmentation_strips["checkerboard"]
    for seg in _segmenters(config):
        _assert_opencv_detections(seg, strips)
        assert seg.labeller is not None and seg.labeller.capacity == seg.labeller.worst


def test_empty_strips(segmentation_strips: Strips) -> None:
    config, strips = segmentation_strips["empty"]
    for seg in _segmenters(config):
        out = seg.detect(strips)
        assert all(len(a) == 0 for a in out[:5]) and not out[5].any()
        assert _assert_opencv_detections(seg, strips) == 0


def test_detections_equal_opencv_components_on_rendered_strips(
    scene_world: World, scenes: Scenes, batch_renderer: BatchOmniRenderer
) -> None:
    """The crowded scenes rendered: either backend finds OpenCV's blobs, bit for bit."""
    segmenters = _segmenters(CameraConfig(), target_geometry(scene_world))
    found = 0
    for _ in scenes(3):
        strips = batch_renderer.render()
        for seg in segmenters:
            found += _assert_opencv_detections(seg, strips)
    assert found >= 2 * scene_world.config.n_robots  # both backends, a few blobs per robot


def test_backends_are_named_and_unknown_ones_refused() -> None:
    fast, ref = _segmenters()
    assert (fast.backend, ref.backend) == ("numba", "numpy")
    assert OmniSegmenter(CONFIG, GEOMETRY).backend == "numba"
    with pytest.raises(ValueError, match="backend must be one of"):
        OmniSegmenter(CONFIG, GEOMETRY, backend="gpu")  # type: ignore[arg-type]
