"""The hand-built hard scenes, the agreement matcher, and the rules that make the geometric
provider follow the rendered image in clutter (footprints, edge-on faces, merges, a pack's
parts). The full suite is ``benchmarks/vision_hard_scenes.py``; here a few scenes per family.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from cyber_rodent.vision import BATTERY, FACE, Blob
from cyber_rodent.vision import segmentation_kernels as seg_kernels
from cyber_rodent.vision.agreement import compare_scene, match_blobs, merge_room
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.hard_scenes import (
    FAMILIES,
    MAX_PENETRATION,
    TEETH_TO_PACK,
    Scene,
    family,
    make_scenes,
    place,
    valid,
)
from cyber_rodent.vision.kernels import covered
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.world import World, WorldConfig

SCENES_PER_FAMILY = 6


# --- the scenes ---------------------------------------------------------------------------------
def test_scenes_are_seeded_valid_and_named() -> None:
    for fam in FAMILIES:
        world = World(fam.world_config())
        first = make_scenes(world, fam, 3, seed=5)
        again = make_scenes(world, fam, 3, seed=5)
        assert first == again, fam.name
        assert first != make_scenes(world, fam, 3, seed=6), fam.name
        for scene in first:
            assert valid(world, scene)
            assert all(c.dist >= -MAX_PENETRATION for c in world.data.contact[: world.data.ncon])
            assert scene.designed, fam.name
            n_targets = 2 * fam.n_robots + fam.n_packs
            assert all(0 <= t < n_targets and o < fam.n_robots for o, t in scene.designed)
    with pytest.raises(ValueError, match="unknown scene family 'x'; known: row"):
        family("x")
    with pytest.raises(ValueError, match="needs 4 robots and 1 packs"):
        make_scenes(World(WorldConfig(n_robots=2, n_packs=2)), family("row"), 1, 0)


def test_an_interpenetrating_scene_is_invalid() -> None:
    fam = family("touching")
    world = World(fam.world_config())
    scene = make_scenes(world, fam, 1, seed=0)[0]
    x, y, yaw = scene.robots[1]
    overlapping = Scene(
        robots=(scene.robots[0], (x, y, yaw), (x + 0.05, y, yaw), scene.robots[3]),
        packs=scene.packs,
        leds=scene.leds,
    )
    assert not valid(world, overlapping)
    outside = Scene(robots=((1.1, 0.0, 0.0),) + scene.robots[1:], packs=scene.packs,
                          leds=scene.leds)  # fmt: skip
    assert not valid(world, outside)


@pytest.fixture(scope="module")
def hard_comparisons() -> Iterator[dict[str, list]]:
    """Both providers on the first scenes of every family: per family, the comparisons."""
    out: dict[str, list] = {}
    for fam in FAMILIES:
        world = World(fam.world_config())
        geo = GeometricVision(world)
        with RenderedVision(world) as ren:
            out[fam.name] = []
            for scene in make_scenes(world, fam, SCENES_PER_FAMILY, seed=0):
                place(world, scene)
                out[fam.name].append(compare_scene(geo, ren))
    yield out


def test_providers_agree_on_the_hard_scenes(hard_comparisons: dict[str, list]) -> None:
    """A fast subset of the benchmark's families (targets within 2 m)."""
    targets = inputs = agree_targets = agree_inputs = 0
    for name, comparisons in hard_comparisons.items():
        rows = [r for c in comparisons for r in c.targets if r.distance <= 2.0]
        near = [n for c in comparisons for n in c.nearest if n.closest <= 2.0]
        share = sum(r.geometric == r.rendered for r in rows) / len(rows)
        assert share >= 0.97, name
        assert sum(n.agree for n in near) / len(near) >= 0.96, name
        targets += len(rows)
        inputs += len(near)
        agree_targets += sum(r.geometric == r.rendered for r in rows)
        agree_inputs += sum(n.agree for n in near)
    assert targets > 800 and inputs > 350
    assert agree_targets / targets >= 0.99
    assert agree_inputs / inputs >= 0.99


# --- the matcher --------------------------------------------------------------------------------
def _blob(bearing_deg: float, distance: float) -> Blob:
    return Blob(cls=BATTERY, bearing=math.radians(bearing_deg), distance=distance, area=50.0)


def test_matcher_uses_distance_and_bearing() -> None:
    px = 2 * math.pi / 512
    bearing = np.radians([10.0, 11.0])
    distance = np.array([0.5, 1.0])
    half = np.array([0.04, 0.04])
    # Each blob at the other's bearing but at its own distance: distance decides.
    blobs = [_blob(11.0, 0.5), _blob(10.0, 1.0)]
    np.testing.assert_array_equal(match_blobs(bearing, distance, half, blobs, px), [0, 1])
    # A blob twice as far as the only target at its bearing is not that target's.
    np.testing.assert_array_equal(
        match_blobs(bearing[:1], distance[:1], half[:1], [_blob(10.0, 1.05)], px), [-1]
    )
    # Outside the window (half width atan(0.04/0.5) = 4.57° + 2°): unmatched; inside: matched.
    for offset, want in ((6.5, 0), (6.6, -1)):
        got = match_blobs(bearing[:1], distance[:1], half[:1], [_blob(10 + offset, 0.5)], px)
        assert got[0] == want, offset
    # A merged blob's spread widens the window.
    spread = np.radians([3.0])
    got = match_blobs(bearing[:1], distance[:1], half[:1], [_blob(16.6, 0.5)], px, spread)
    assert got[0] == 0


def test_matcher_pairs_by_area_too() -> None:
    """A near face (0.60 m, 6 x 10 px footprint) and a far one hidden behind it (0.64 m,
    3 x 4 px), half a degree apart; one 55 px blob at 0.62 m between them. Bearing and
    distance alone give the blob to the far face; it cannot hold 55 px (at most 2 x 4 x 5 + 4),
    so area gives it to the near one, whose room includes the far face's pixels (a merge)."""
    px = 2 * math.pi / 512
    bearing = np.radians([10.0, 10.5])
    distance = np.array([0.60, 0.64])
    half = np.array([0.04, 0.04])
    blob = [Blob(cls=FACE, bearing=math.radians(10.4), distance=0.62, area=55.0)]
    np.testing.assert_array_equal(match_blobs(bearing, distance, half, blob, px), [-1, 0])
    width, height = np.array([6.0, 3.0]), np.array([10.0, 4.0])
    size = {"width_px": width, "height_px": height}
    np.testing.assert_array_equal(match_blobs(bearing, distance, half, blob, px, **size), [0, -1])
    room = merge_room(bearing, distance, half, width, height, px)
    np.testing.assert_array_equal(room, [7 * 11 + 4 * 5, 4 * 5])
    # A blob larger than the near face's own footprint but within its room (the far face
    # merged into it) is still the near face's.
    merged = [Blob(cls=FACE, bearing=math.radians(10.2), distance=0.60, area=70.0)]
    got = match_blobs(bearing, distance, half, merged, px, **size)
    np.testing.assert_array_equal(got, [0, -1])
    # Both could hold a 14 px blob: the closer area wins (the far face), where bearing and
    # distance alone pick the near one.
    small = [Blob(cls=FACE, bearing=math.radians(10.2), distance=0.615, area=14.0)]
    np.testing.assert_array_equal(match_blobs(bearing, distance, half, small, px), [0, -1])
    np.testing.assert_array_equal(match_blobs(bearing, distance, half, small, px, **size), [-1, 0])
    # A target without a footprint bounds nothing: the camera's blob still counts for it.
    got = match_blobs(
        bearing[1:], distance[1:], half[1:], blob, px, width_px=np.zeros(1), height_px=height[1:]
    )
    np.testing.assert_array_equal(got, [0])


# --- geometric: footprints, edge-on faces, merges ------------------------------------------------
def test_pixel_footprint_counts_covered_centres() -> None:
    """A rasteriser fills the pixels whose centre (k + 0.5) the shape covers."""
    np.testing.assert_array_equal(
        covered(np.array([0.4, 0.6, 0.5, 3.2, 2.0]), np.array([1.6, 1.4, 0.5, 3.2, 1.0])),
        [2, 0, 1, 0, 0],
    )


def _place(world: World, robots, packs) -> None:
    """Robots and packs where given, every LED on."""
    place(world, Scene(tuple(robots), tuple(packs), (True,) * world.config.n_robots))


@pytest.fixture(scope="module")
def pair_world() -> Iterator[tuple[World, GeometricVision, RenderedVision]]:
    world = World(WorldConfig(n_robots=2, n_packs=2))
    geo = GeometricVision(world)
    with RenderedVision(world) as ren:
        yield world, geo, ren


def test_a_face_seen_edge_on_by_both_providers(pair_world) -> None:
    """Robot 1 side-on, 0.25 m to robot 0's left, its face plate's front 1 mm ahead of robot 0's
    camera axis: the plate's red edge (3 mm, over a pixel wide at 0.2 m) stands out of the
    chassis, and both see it; 6 cm further forward the chassis hides it from both."""
    world, geo, ren = pair_world
    packs = [(0.9, -0.9), (-0.9, -0.9)]
    face_x = 0.111 + 0.002
    for shift, seen in ((-face_x + 0.001, True), (-face_x + 0.06, False)):
        _place(world, [(0.0, 0.0, 0.0), (shift, 0.25, 0.0)], packs)
        g, r = geo.observe(), ren.observe()
        assert g.visible[0, FACE] == seen and r.visible[0, FACE] == seen, shift
        if seen:
            assert g.bearing[0, FACE] == pytest.approx(r.bearing[0, FACE], abs=math.radians(1.5))
            assert r.distance[0, FACE] == pytest.approx(g.distance[0, FACE], rel=0.1)


def test_packs_touching_in_the_image_are_one_blob(pair_world) -> None:
    """0.6 m ahead, a pack 10 cm behind another and 5 cm aside peeks out beside it: one blue
    blob in the image, one target (the nearer) in the geometric provider, at its distance in
    both. Two packs side by side with their rings touching show a gap between their blue
    bodies (5 mm each side): two blobs and two targets."""
    world, geo, ren = pair_world
    robots = [(-0.6, 0.0, 0.0), (0.9, 0.9, 0.0)]
    packs = 2 * 2 + np.arange(2)
    _place(world, robots, [(0.0, 0.0), (0.1, 0.05)])
    meas = geo.measure_targets()
    np.testing.assert_array_equal(meas.visible[0, packs], [True, False])
    r = ren.observe()
    assert sum(b.cls == BATTERY for b in r.blobs[0]) == 1
    assert r.distance[0, BATTERY] == pytest.approx(meas.distance[0, packs[0]], rel=0.05)
    _place(world, robots, [(0.0, 0.045), (0.0, -0.045)])
    assert geo.measure_targets().visible[0, packs].all()
    assert sum(b.cls == BATTERY for b in ren.observe().blobs[0]) == 2


def test_a_pack_touching_the_robot_is_one_pack(pair_world) -> None:
    """A pack against robot 0's teeth: its lower band, cut off by the frame's bottom, stays part
    of it; the nearest pack is measured within 10 %."""
    world, geo, ren = pair_world
    for angle in (0.0, 0.5, -0.7):
        x, y = TEETH_TO_PACK * math.cos(angle), TEETH_TO_PACK * math.sin(angle)
        _place(world, [(0.0, 0.0, 0.0), (0.9, 0.9, 0.0)], [(x, y), (-0.9, -0.9)])
        r = ren.observe()
        near = [b for b in r.blobs[0] if b.cls == BATTERY and b.distance < 0.5]
        assert len(near) == 1, angle
        assert r.distance[0, BATTERY] == pytest.approx(TEETH_TO_PACK, rel=0.1), angle
        assert geo.observe().distance[0, BATTERY] == pytest.approx(TEETH_TO_PACK, rel=1e-6)


def test_stacked_parts_of_one_pack_join_others_stay_apart() -> None:
    """Hand-made blobs (bearing intervals in rad, rows) through the pack-grouping pair test."""
    px = 0.01

    def joined(lo_hi_top_bottom: list[tuple[float, float, int, int]], height: int = 100) -> bool:
        lo = np.array([v[0] for v in lo_hi_top_bottom])
        hi = np.array([v[1] for v in lo_hi_top_bottom])
        top = np.array([v[2] for v in lo_hi_top_bottom], dtype=np.int64)
        bottom = np.array([v[3] for v in lo_hi_top_bottom], dtype=np.int64)
        bearing = np.zeros(len(lo))
        results = []
        for kernel in (seg_kernels.join_stacked, seg_kernels.join_stacked_reference):
            parent = np.arange(len(lo))
            results.append(kernel(bearing, lo, hi, top, bottom, parent, height, px))
        assert results[0] == results[1]
        return bool(results[0])

    # Two bands of one width, a ring of 3 rows between them: one pack.
    assert joined([(-0.1, 0.1, 10, 30), (-0.1, 0.1, 34, 40)])
    # The lower band narrower and cut off by the frame's bottom row (99): still one.
    assert joined([(-0.1, 0.1, 10, 60), (-0.03, 0.0, 80, 99)])
    # The same narrow blob not touching the bottom, far below: another thing.
    assert not joined([(-0.1, 0.1, 10, 30), (-0.03, 0.0, 80, 90)])
    # One width, a chassis between them (gap taller than both): one pack.
    assert joined([(-0.05, 0.05, 10, 20), (-0.05, 0.045, 45, 50)])
    # A wider blob below is a nearer pack: apart, whatever the gap.
    assert not joined([(-0.05, 0.05, 10, 20), (-0.1, 0.1, 22, 60)])
