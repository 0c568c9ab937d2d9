"""The compiled segmentation backend against the OpenCV reference, and on hand-made strips.

The compiled backend (``backend="numba"``, :mod:`cyber_rodent.vision.segmentation_kernels`) must
classify every pixel exactly as OpenCV's cvtColor + inRange do (``backend="numpy"``), and find
the same blobs with the same statistics, in the same order; on hand-made strips the blob counts
are known by construction. The pack grouping's pair test has a compiled kernel and a numpy
reference, which must join the same blobs.
"""

from __future__ import annotations

import numpy as np
import pytest

from cyber_rodent.vision import BATTERY, FACE, LED, CameraConfig
from cyber_rodent.vision import segmentation_kernels as kernels
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import TargetGeometry, TargetShape

CONFIG = CameraConfig(n_views=4, view_width=16, height=12)
PACK = TargetShape(cls=BATTERY, plate=False, half_width=0.04, z_bottom=0.0, z_top=0.1)
FACE_PLATE = TargetShape(cls=FACE, plate=True, half_width=0.045, z_bottom=0.054, z_top=0.09)
LED_RING = TargetShape(cls=LED, plate=False, half_width=0.022, z_bottom=0.103, z_top=0.117)
GEOMETRY = TargetGeometry(camera_height=0.17, shapes=(LED_RING, FACE_PLATE, PACK))
GREEN, RED, BLUE, GREY = (25, 230, 25), (230, 13, 13), (13, 38, 230), (140, 140, 140)
CONFIG_BEARING = OmniSegmenter(CONFIG, GEOMETRY, backend="numpy").projection.column_bearing


def _segmenters(config: CameraConfig = CONFIG) -> tuple[OmniSegmenter, OmniSegmenter]:
    return (
        OmniSegmenter(config, GEOMETRY, backend="numba"),
        OmniSegmenter(config, GEOMETRY, backend="numpy"),
    )


def _assert_same(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> None:
    for x, y in zip(a[:5], b[:5], strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a[5], b[5])


def test_every_pixel_classified_as_opencv_does() -> None:
    fast, ref = _segmenters()
    rng = np.random.default_rng(0)
    # Random colours, plus colours near each class's hue/saturation/value edges.
    rgb = rng.integers(0, 256, size=(400, 64, 3), dtype=np.uint8)
    for k, base in enumerate((GREEN, RED, BLUE)):
        jitter = rng.integers(-60, 61, size=(40, 64, 3))
        rgb[40 * k : 40 * (k + 1)] = np.clip(np.array(base) + jitter, 0, 255)
    strips = rgb.reshape(4, 100, 64, 3)
    config = CameraConfig(n_views=4, view_width=16, height=100)
    fast, ref = _segmenters(config)
    masks = ref.masks(rgb)
    classes = fast.detect(strips)[5].reshape(400, 64)
    for c in range(3):
        np.testing.assert_array_equal((classes >> c) & 1, masks[c] > 0)
    _assert_same(fast.detect(strips), ref.detect(strips))


def test_hand_made_blobs() -> None:
    """Counts known by construction: a blob across the seam is one; diagonal neighbours join
    (8-connectivity); a pack's two bands with a grey ring between them are one target."""
    fast, ref = _segmenters()
    strips = np.full((2, 12, 64, 3), GREY, dtype=np.uint8)
    # Robot 0: green across the strip's seam (columns 62-63 and 0-1), rows 3-4: one LED.
    strips[0, 3:5, 62:] = GREEN
    strips[0, 3:5, :2] = GREEN
    # Robot 0: two red squares touching at a corner: one face; a separate square: another.
    strips[0, 5:7, 18:20] = RED
    strips[0, 7:9, 20:22] = RED
    strips[0, 5:7, 40:42] = RED
    # Robot 1: one pack cut by its ring: blue rows 2-4 and 6-8, same columns, grey row 5.
    strips[1, 2:5, 30:34] = BLUE
    strips[1, 6:9, 30:34] = BLUE
    robot, cls, bearing, distance, area, classes = fast.detect(strips)
    np.testing.assert_array_equal(robot, [0, 0, 0, 1])
    np.testing.assert_array_equal(cls, [LED, FACE, FACE, BATTERY])
    np.testing.assert_array_equal(area, [8, 8, 4, 24])
    # The seam blob's bearing is the strip's edge bearing (columns 0 and 63 border it).
    edge = np.arctan2(np.sin(CONFIG_BEARING[[62, 63, 0, 1]]).sum(),
                      np.cos(CONFIG_BEARING[[62, 63, 0, 1]]).sum())  # fmt: skip
    assert bearing[0] == pytest.approx(edge)
    _assert_same((robot, cls, bearing, distance, area, classes), ref.detect(strips))


def test_worst_case_run_count_grows_the_buffers() -> None:
    """A checkerboard of class colours has more runs than the first allocation holds."""
    fast, ref = _segmenters()
    strips = np.full((4, 12, 64, 3), GREY, dtype=np.uint8)
    strips[:, ::2, ::2] = BLUE
    strips[:, 1::2, 1::2] = RED
    _assert_same(fast.detect(strips), ref.detect(strips))
    assert fast.labeller is not None and fast.labeller.capacity == fast.labeller.worst


def test_empty_strips() -> None:
    fast, ref = _segmenters()
    strips = np.full((3, 12, 64, 3), GREY, dtype=np.uint8)
    out = fast.detect(strips)
    assert all(len(a) == 0 for a in out[:5]) and not out[5].any()
    _assert_same(out, ref.detect(strips))


def test_backends_are_named_and_unknown_ones_refused() -> None:
    fast, ref = _segmenters()
    assert (fast.backend, ref.backend) == ("numba", "numpy")
    assert OmniSegmenter(CONFIG, GEOMETRY).backend == "numba"
    with pytest.raises(ValueError, match="backend must be one of"):
        OmniSegmenter(CONFIG, GEOMETRY, backend="gpu")  # type: ignore[arg-type]


def test_stacked_pair_test_kernel_matches_reference() -> None:
    """Random blob sets, many near the thresholds: the same pairs joined, the same roots."""
    rng = np.random.default_rng(3)
    n_joined = 0
    for _ in range(300):
        k = int(rng.integers(2, 9))
        bearing = rng.uniform(-np.pi, np.pi, k)
        bearing[1:] = np.where(rng.random(k - 1) < 0.6, bearing[0] + rng.normal(0, 0.02, k - 1),
                               bearing[1:])  # fmt: skip
        half = rng.uniform(0.01, 0.1, k)
        lo, hi = -half * rng.uniform(0.8, 1.2, k), half * rng.uniform(0.8, 1.2, k)
        top = rng.integers(0, 100, k)
        bottom = top + rng.integers(0, 20, k)
        parents = []
        joined = []
        for fn in (kernels.join_stacked, kernels.join_stacked_reference):
            parent = np.arange(k)
            joined.append(fn(bearing, lo, hi, top, bottom, parent))
            while not np.array_equal(parent[parent], parent):
                parent = parent[parent]
            parents.append(parent)
        assert joined[0] == joined[1]
        np.testing.assert_array_equal(parents[0], parents[1])
        n_joined += joined[0]
    assert 30 < n_joined < 270
