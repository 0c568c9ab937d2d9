"""Small, partly hidden targets are measured pixel by pixel (``CameraConfig.trace_below``).

The samples' estimate (footprint × seen share of 6 samples) is too coarse where a nearer body
hides most of a small target: it predicts a few pixels where the image shows none. A small
target one of whose samples is hidden before the estimate is certain, and one seen, is
measured by casting a ray through each pixel centre of its footprint (docs/design.md §6).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cyber_rodent.vision import CameraConfig, kernels
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.world import World, WorldConfig
from tests.conftest import crowd


def test_pixel_vector_points_through_its_pixel_centre() -> None:
    """Hand-computed: 4 views of 128 columns, so half_tan = 1 and 64 px per unit of u. Column
    320 is in view 2 (the front view, axis at bearing 0), 64.5 px from its left edge: tan of
    its bearing is 1 - 64.5 / 64 = -1/128. Row 0's centre is half a row below the top edge."""
    world = World(WorldConfig(n_robots=2, n_packs=0))
    vision = GeometricVision(world)
    camera = vision.camera
    out = np.zeros(3)
    rot = np.eye(3).ravel()
    v0 = camera.v_top - 0.5 / camera.px_per_v
    kernels._pixel_vector(camera, rot, 320, 0, 2.0, out)
    reach = 2.0 / math.sqrt(1.0 + (1 / 128) ** 2)
    np.testing.assert_allclose(out, [reach, -reach / 128, reach * v0], rtol=1e-12)
    # Every column's bearing is the projection's; the strip wraps.
    proj = vision.projection
    for column in (0, 63, 127, 128, 300, 511):
        for shifted in (column, column + 512, column - 512):
            kernels._pixel_vector(camera, rot, shifted, 10, 1.0, out)
            assert math.atan2(out[1], out[0]) == pytest.approx(proj.column_bearing[column])
            assert math.hypot(out[0], out[1]) == pytest.approx(1.0)
    # The compiled twin gives the same vector.
    compiled = np.zeros(3)
    kernels._pixel_vector_compiled(camera, rot, 320, 0, 2.0, compiled)
    kernels._pixel_vector(camera, rot, 320, 0, 2.0, out)
    np.testing.assert_array_equal(compiled, out)


@pytest.mark.parametrize(
    ("full", "hits", "traced"),
    [
        (12.0, (0, 1, 1, 1, 1, 1), True),  # the first sample hidden, others seen
        (12.0, (1, 0, 1, 1, 1, 1), True),  # 12/6 = 2 px < 3 after one hit: not yet certain
        (12.0, (1, 1, 0, 1, 1, 1), False),  # certain at the second hit (4 px), before the miss
        (20.0, (1, 0, 0, 0, 0, 0), False),  # 20/6 = 3.3 px >= 3 at the first hit
        (12.0, (0, 0, 0, 0, 0, 0), False),  # nothing seen: hidden, nothing to trace
        (12.0, (1, 1, 1, 1, 1, 1), False),  # nothing hidden
        (70.0, (0, 1, 0, 0, 0, 0), False),  # not small (trace_below 60 for a face)
        (5.0, (0, 1, 1, 1, 1, 1), True),  # a miss first; 5 px could reach 3 if all were seen
    ],
)
def test_which_targets_are_traced(full: float, hits: tuple[int, ...], traced: bool) -> None:
    """The full pass's rule, hand-computed for robot 0 and robot 1's face (6 samples, 3 px to
    be seen, traced below 60 px)."""
    world = World(WorldConfig(n_robots=2, n_packs=0))
    vision = GeometricVision(world, CameraConfig(trace_below=(24, 60, 60)))
    tt = vision.targets
    face = 3  # targets: LEDs 0-1, faces 2-3
    start, end = int(tt.sample_start[face]), int(tt.sample_end[face])
    assert end - start == len(hits)
    n_t, n_s = len(tt.target_cls), len(tt.sample_target)
    sample_ok = np.zeros((2, n_s), dtype=bool)
    hit = np.zeros((2, n_s), dtype=bool)
    sample_ok[0, start:end] = True
    hit[0, start:end] = np.array(hits, dtype=bool)
    full_area = np.zeros((2, n_t))
    full_area[0, face] = full
    result = vision._traced(sample_ok, hit, full_area)
    assert bool(result[0, face]) == traced
    assert result.sum() == int(traced)


def test_trace_below_is_validated() -> None:
    for bad in ((0, 0, -1), (0, 0), (0, 0, 10_001)):
        with pytest.raises(ValueError, match="trace_below"):
            CameraConfig(trace_below=bad)  # type: ignore[arg-type]
    assert CameraConfig(trace_below=(0, 0, 0)).trace_below == (0, 0, 0)


def _traced_pairs(vision: GeometricVision) -> tuple[np.ndarray, np.ndarray]:
    t = vision.measure_targets()
    estimate = t.width_px * t.height_px * t.visible_share
    return t.area, estimate


def test_traced_areas_in_crowds_on_both_backends() -> None:
    """In crowds, partly hidden small targets are traced: their area is a whole number of
    pixels, at most the footprint, the same on both backends; with tracing off every area is
    the samples' estimate; and the lazy nearest pass agrees with the full pass."""
    world = World(WorldConfig(n_robots=6, n_packs=6))
    compiled = GeometricVision(world, backend="numba")
    reference = GeometricVision(world, backend="numpy")
    off = GeometricVision(world, CameraConfig(trace_below=(0, 0, 0)))
    rng = np.random.default_rng(321)
    traced = changed = 0
    for _ in crowd(world, rng, 40):
        area_c, estimate = _traced_pairs(compiled)
        area_r, _ = _traced_pairs(reference)
        np.testing.assert_array_equal(area_c, area_r)
        differs = area_c != estimate
        assert (area_c[differs] == np.round(area_c[differs])).all()
        full = compiled.front.full_area
        assert (area_c <= full).all()
        traced += int(differs.sum())
        area_off, estimate_off = _traced_pairs(off)
        np.testing.assert_array_equal(area_off, estimate_off)
        for vision in (compiled, reference, off):
            frame = vision.observe()
            nearest = vision.nearest_targets()
            np.testing.assert_array_equal(nearest.visible, frame.visible)
            np.testing.assert_array_equal(nearest.distance, frame.distance)
        changed += int((compiled.nearest_targets().visible != off.nearest_targets().visible).sum())
    assert traced > 10  # not vacuous: crowds hide parts of small targets
    assert changed > 0  # and tracing changed what a robot sees
