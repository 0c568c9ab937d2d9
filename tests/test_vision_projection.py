"""Omni projection and colour segmentation on hand-made images (no OpenGL needed).

Expected values are computed here from the geometry (pinhole views with a vertical image plane,
u = -y/x, v = z/x), independently of the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cyber_rodent.vision import BATTERY, FACE, LED, CameraConfig
from cyber_rodent.vision.projection import OmniProjection, wrap_angle
from cyber_rodent.vision.segmentation import OmniSegmenter
from cyber_rodent.vision.targets import TargetGeometry, TargetShape

SMALL = CameraConfig(n_views=4, view_width=4, height=8)
HC = 0.17  # camera height used in the hand cases
PACK = TargetShape(cls=BATTERY, plate=False, half_width=0.04, z_bottom=0.0, z_top=0.1)
FACE_PLATE = TargetShape(cls=FACE, plate=True, half_width=0.045, z_bottom=0.054, z_top=0.09)
LED_RING = TargetShape(cls=LED, plate=False, half_width=0.022, z_bottom=0.103, z_top=0.117)
GEOMETRY = TargetGeometry(camera_height=HC, shapes=(LED_RING, FACE_PLATE, PACK))


def test_frustum_covers_the_band_at_every_bearing() -> None:
    p = OmniProjection(CameraConfig())
    # 4 views: half-width tan 45° = 1; corner factor sqrt(2).
    assert p.half_tan == pytest.approx(1.0)
    assert p.v_top == pytest.approx(math.tan(math.radians(3.0)) * math.sqrt(2))
    assert p.v_bottom == pytest.approx(-1.0 * math.sqrt(2))
    assert p.px_per_u == pytest.approx(128 / 2.0)
    assert p.px_per_v == pytest.approx(192 / (p.v_top - p.v_bottom))
    # At a view's edge (u = ±1) the lowest elevation is exactly the configured -45°.
    assert math.degrees(math.atan(p.v_bottom / math.sqrt(2))) == pytest.approx(-45.0)


def test_column_bearings_hand_computed() -> None:
    p = OmniProjection(SMALL)
    # View k looks along 180°, 90°, 0°, -90°; its 4 columns sit at u = -0.75, -0.25, 0.25, 0.75
    # and see bearing centre - atan(u).
    offsets = [math.degrees(math.atan(u)) for u in (0.75, 0.25, -0.25, -0.75)]
    expected = [((c + o + 180) % 360) - 180 for c in (180, 90, 0, -90) for o in offsets]
    np.testing.assert_allclose(np.degrees(p.column_bearing), expected, atol=1e-9)
    # Columns run continuously from bearing +225° (= -135°) down to -135°.
    assert np.all(np.diff(np.unwrap(p.column_bearing)) < 0)


def test_view_coordinates_hand_cases() -> None:
    p = OmniProjection(SMALL)
    view, offset = p.view_coordinates(np.radians([0.0, 30.0, 100.0, -170.0, 180.0, -46.0]))
    np.testing.assert_array_equal(view, [2, 2, 1, 0, 0, 3])
    np.testing.assert_allclose(np.degrees(offset), [0.0, 30.0, 10.0, 10.0, 0.0, 44.0], atol=1e-9)


def test_horizontal_distance_from_depression() -> None:
    p = OmniProjection(SMALL)
    # A point 0.17 m below the camera seen at v = -0.17 straight along a view axis is 1 m away;
    # off-axis (u = 0.5) the same v means sqrt(1.25) m.
    assert p.horizontal_distance(0.17, -0.17, 0.0) == pytest.approx(1.0)
    assert p.horizontal_distance(0.17, -0.17, 0.5) == pytest.approx(math.sqrt(1.25))
    assert p.horizontal_distance(0.17, 0.01, 0.0) == math.inf  # above the horizon


def test_wrap_angle() -> None:
    np.testing.assert_allclose(
        wrap_angle(np.array([3 * math.pi / 2, -3 * math.pi / 2, math.pi])),
        [-math.pi / 2, math.pi / 2, math.pi],
    )


# --- segmentation ---------------------------------------------------------------------------
CFG = CameraConfig(n_views=4, view_width=64, height=64)


def _v_at(cfg: CameraConfig, y: float) -> float:
    corner = math.sqrt(2.0)
    v_top = math.tan(math.radians(cfg.elevation_max_deg)) * corner
    v_bot = math.tan(math.radians(cfg.elevation_min_deg)) * corner
    return v_top - y * (v_top - v_bot) / cfg.height


def _row_of(cfg: CameraConfig, v: float) -> float:
    """Continuous row coordinate of image height v (inverse of _v_at)."""
    corner = math.sqrt(2.0)
    v_top = math.tan(math.radians(cfg.elevation_max_deg)) * corner
    v_bot = math.tan(math.radians(cfg.elevation_min_deg)) * corner
    return (v_top - v) * cfg.height / (v_top - v_bot)


def test_blob_centred_in_the_front_view_is_at_bearing_zero_with_hand_distance() -> None:
    seg = OmniSegmenter(CFG, GEOMETRY)
    mask = np.zeros((CFG.height, CFG.strip_width), dtype=np.uint8)
    front_centre = 2 * CFG.view_width + CFG.view_width // 2  # column boundary at u = 0
    # A pack 1 m ahead: far top rim (0.1 m high, 1.04 m) at v = -0.07/1.04, near bottom rim
    # (floor, 0.96 m) at v = -0.17/0.96: rows 6 .. 10 at this resolution.
    y_top, y_bot = _row_of(CFG, -0.07 / 1.04), _row_of(CFG, -0.17 / 0.96)
    assert (round(y_top), math.ceil(y_bot)) == (6, 11)
    mask[6:11, front_centre - 3 : front_centre + 3] = 255
    bearing, distance, area = seg.measure_blobs(mask, BATTERY)
    assert len(bearing) == 1
    assert bearing[0] == pytest.approx(0.0, abs=1e-12)
    assert area[0] == 30
    # Edges y = 6 (top) and y = 11 (bottom), u = 0: each edge gives a distance, combined with
    # weights v² (the lower edge is the more precise).
    v_t, v_b = _v_at(CFG, 6), _v_at(CFG, 11)
    d_top = (HC - 0.1) / -v_t - 0.04
    d_bot = HC / -v_b + 0.04
    expected = (v_t**2 * d_top + v_b**2 * d_bot) / (v_t**2 + v_b**2)
    assert distance[0] == pytest.approx(expected, rel=1e-9)
    assert distance[0] == pytest.approx(1.0, rel=0.1)


def test_blob_whose_bottom_is_hidden_is_measured_by_its_top_edge() -> None:
    seg = OmniSegmenter(CFG, GEOMETRY)
    mask = np.zeros((CFG.height, CFG.strip_width), dtype=np.uint8)
    c = 2 * CFG.view_width + CFG.view_width // 2
    # The top edge (row 20) says 0.14 m, but the blob stops 2 rows lower (its bottom hidden
    # behind something): the bottom edge would put it 0.43 m away, three times farther, far
    # beyond what 1.5 px of quantisation on each edge explains; the top edge alone is used.
    mask[20:22, c - 3 : c + 3] = 255
    _, distance, _ = seg.measure_blobs(mask, BATTERY)
    d_top = (HC - 0.1) / -_v_at(CFG, 20) - 0.04
    assert HC / -_v_at(CFG, 22) + 0.04 > 3 * d_top
    assert distance[0] == pytest.approx(d_top, rel=1e-9)
    # Cut off by the bottom of the strip: the top edge alone, too.
    mask[:] = 0
    mask[40:, c - 3 : c + 3] = 255
    _, distance, _ = seg.measure_blobs(mask, BATTERY)
    assert distance[0] == pytest.approx((HC - 0.1) / -_v_at(CFG, 40) - 0.04, rel=1e-9)


def test_blob_cut_by_the_strip_seam_is_one_blob_at_the_seam_bearing() -> None:
    seg = OmniSegmenter(CFG, GEOMETRY)
    mask = np.zeros((CFG.height, CFG.strip_width), dtype=np.uint8)
    mask[10:14, :3] = 255
    mask[10:14, -3:] = 255
    bearing, _, area = seg.measure_blobs(mask, LED)
    assert len(bearing) == 1 and area[0] == 24
    # Symmetric about the seam between the last and the first column: bearing +225° = -135°.
    assert math.degrees(bearing[0]) == pytest.approx(-135.0, abs=1e-9)


def test_pack_bands_cut_by_the_electrode_ring_are_grouped_but_faces_are_not() -> None:
    seg = OmniSegmenter(CFG, GEOMETRY)
    mask = np.zeros((CFG.height, CFG.strip_width), dtype=np.uint8)
    c = 2 * CFG.view_width + CFG.view_width // 2
    # A pack 0.5 m ahead: blue from the far top rim (v = -0.07/0.54, row 8.8) down to the grey
    # ring's top (0.054 m, near side 0.455 m: row 14.1); the ring to its bottom (0.03 m: row
    # 16.4); blue again down to the floor (0.46 m: row 19.1).
    rows = [_row_of(CFG, v) for v in (-0.07 / 0.54, -0.116 / 0.455, -0.14 / 0.455, -0.17 / 0.46)]
    assert [round(r) for r in rows] == [9, 14, 16, 19]
    mask[9:14, c - 3 : c + 3] = 255  # upper band
    mask[17:19, c - 3 : c + 3] = 255  # lower band
    b_pack, d_pack, a_pack = seg.measure_blobs(mask, BATTERY)
    assert len(b_pack) == 1 and a_pack[0] == 30 + 12
    assert d_pack[0] == pytest.approx(0.5, rel=0.1)
    b_face, _, _ = seg.measure_blobs(mask, FACE)
    assert len(b_face) == 2


def test_a_far_narrow_pack_above_a_near_wide_one_stays_separate() -> None:
    seg = OmniSegmenter(CFG, GEOMETRY)
    mask = np.zeros((CFG.height, CFG.strip_width), dtype=np.uint8)
    c = 2 * CFG.view_width + CFG.view_width // 2
    mask[30:50, c - 8 : c + 8] = 255  # near pack: 16 px wide
    mask[20:26, c - 2 : c + 2] = 255  # far pack, same bearing: 4 px wide, gap of 4 rows
    bearing, distance, _ = seg.measure_blobs(mask, BATTERY)
    assert len(bearing) == 2
    assert distance.min() < distance.max()


def test_hsv_thresholds_separate_the_scene_colours() -> None:
    seg = OmniSegmenter(CameraConfig(), GEOMETRY)
    colours = {
        "led_on_lit": (30, 245, 30),
        "led_on_dim": (12, 115, 12),
        "led_off": (12, 40, 12),
        "face": (210, 12, 12),
        "face_dim": (95, 5, 5),
        "pack": (12, 36, 210),
        "pack_dim": (5, 15, 95),
        "wall": (195, 190, 179),
        "floor": (112, 112, 112),
        "chassis": (180, 180, 185),
        "black": (0, 0, 0),
    }
    img = np.array([list(colours.values())], dtype=np.uint8)
    masks = seg.masks(img) > 0
    names = list(colours)
    hits = {
        name: tuple(int(c) for c in np.flatnonzero(masks[:, 0, k])) for k, name in enumerate(names)
    }
    assert hits == {
        "led_on_lit": (LED,),
        "led_on_dim": (LED,),
        "led_off": (),
        "face": (FACE,),
        "face_dim": (FACE,),
        "pack": (BATTERY,),
        "pack_dim": (BATTERY,),
        "wall": (),
        "floor": (),
        "chassis": (),
        "black": (),
    }
