"""How well the geometric provider reproduces the rendered camera, target by target.

Both providers observe the same state. The geometric provider says, for every candidate target
of every robot (other robots' lit LEDs and faces, every pack), whether it is visible
(:meth:`GeometricVision.measure_targets`). The rendered provider's blobs are matched one-to-one
to true targets of the same colour class by bearing, distance *and* area (:func:`match_blobs`),
without regard to what the geometric provider said, so neither provider is favoured: a blob
that a target's whole projected footprint (with the farther targets of its class a merge could
join to it) cannot hold is not that target's, and among the possible pairs the closest in
bearing, distance and area are taken first. A target is "rendered-detected" when a blob matched
it. For targets both providers detect, the bearing error and the relative distance error are
recorded.

The controller and the behaviours read only the nearest target of each class, so
:func:`compare_nearest` compares that too: the two providers agree on a robot's input of one
class when both see nothing, or both see a nearest target at distances within
:data:`NEAREST_DISTANCE_TOLERANCE` of each other.

Used by ``benchmarks/vision_agreement.py`` (random scenes), ``benchmarks/vision_hard_scenes.py``
(:mod:`cyber_rodent.vision.hard_scenes`) and by the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cyber_rodent.vision.geometric import GeometricVision, TargetMeasurements
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.vision.types import CLASS_NAMES, LED, N_CLASSES, Blob, VisionFrame
from cyber_rodent.world import World


@dataclass(frozen=True)
class TargetComparison:
    """One candidate target of one robot, as both providers saw it.

    Attributes:
        robot, target: observer and target index (order of ``GeometricVision.target_geom``).
        cls: colour class.
        distance: m, true horizontal distance (camera axis to target axis).
        geometric, rendered: whether each provider detected it.
        geometric_area: px, the geometric provider's expected visible area.
        bearing_error_deg: |rendered − true bearing|, degrees (NaN unless rendered detected).
        distance_rel_error: |rendered − true distance| / true distance (NaN unless rendered).
        blob_area: px, the matched rendered blob's area (0 if none).
    """

    robot: int
    target: int
    cls: int
    distance: float
    geometric: bool
    rendered: bool
    geometric_area: float = 0.0
    bearing_error_deg: float = math.nan
    distance_rel_error: float = math.nan
    blob_area: float = 0.0


#: A blob is credited to a target only if its distance is within this fraction of the target's
#: true distance (besides the bearing window): a fragment of one robot's face is not another's.
DISTANCE_TOLERANCE = 0.5
#: Bearing window beyond a target's angular half width: max(2°, 2 pixels).
BEARING_MARGIN_DEG = 2.0
#: Relative distance error that costs as much as a bearing error of the whole window: a
#: rendered distance is good to a few percent, while a blob that holds several touching
#: targets has its bearing between them and the nearest one's distance.
DISTANCE_SCALE = 0.1
#: Relative area difference that costs as much as a bearing error of the whole window: a
#: blob smaller than the target's whole footprint (partly hidden) or larger than its
#: :func:`merge_room` differs by the gap over the larger; one in between (a merge) by nothing.
#: A partly hidden target's blob is smaller than its footprint, so area only breaks near ties
#: in bearing and distance.
AREA_SCALE = 1.0
#: A blob may hold at most this many times the pixels of the target's whole footprint grown by
#: a pixel in width and height (with the farther targets of its class whose blobs could merge
#: into it), plus :data:`AREA_MARGIN_PX`: rasterised outlines and a face plate's edge add
#: pixels (a plate seen edge-on at 0.16 m: 126 px for a 2 x 29 px footprint).
AREA_FACTOR = 2.0
#: px, see :data:`AREA_FACTOR`.
AREA_MARGIN_PX = 4.0


def merge_room(
    bearing: np.ndarray, distance: np.ndarray, half_width: np.ndarray, width_px: np.ndarray,
    height_px: np.ndarray, px_angle: float,
) -> np.ndarray:  # fmt: skip
    """Each target's grown footprint plus those of the farther targets its blob could swallow.

    A blob that joins touching targets of one colour is measured at the nearest one's
    distance, so a target's blob may hold the pixels of the targets of its class at least as
    far as it whose angular extents touch its own (within max(2°, 2 px)), but not a nearer
    one's. Each footprint is grown by a pixel in width and height. Poses only: what either
    provider saw plays no part.

    Args:
        bearing, distance, half_width: (T,) as for :func:`match_blobs`.
        width_px, height_px: (T,) px, each target's whole projected footprint.

    Returns:
        (T,) px, the most pixels a blob of each target can hold before :data:`AREA_FACTOR`.
    """
    grown = (width_px + 1.0) * (height_px + 1.0)
    safe = np.maximum(distance, 1e-6)
    reach = np.arctan2(half_width, safe)
    margin = max(math.radians(BEARING_MARGIN_DEG), 2 * px_angle)
    turn = bearing[None, :] - bearing[:, None] + math.pi
    gap = np.abs(np.remainder(turn, 2 * math.pi) - math.pi)
    touch = gap <= reach[:, None] + reach[None, :] + margin
    farther = distance[None, :] >= distance[:, None]
    others = touch & farther
    np.fill_diagonal(others, False)
    room: np.ndarray = grown + others.astype(float) @ grown
    return room


def match_blobs(
    bearing: np.ndarray,
    distance: np.ndarray,
    half_width: np.ndarray,
    blobs: list[Blob],
    px_angle: float,
    spread: np.ndarray | None = None,
    width_px: np.ndarray | None = None,
    height_px: np.ndarray | None = None,
) -> np.ndarray:
    """Pair one robot's blobs of one class with the true targets of that class, one to one.

    A (target, blob) pair is possible when the blob's bearing is within the target's angular
    half width plus max(2°, 2 px) of the target's bearing, its distance within
    :data:`DISTANCE_TOLERANCE` of the target's and, given the targets' footprints, its area
    at most :data:`AREA_FACTOR` × :func:`merge_room` + :data:`AREA_MARGIN_PX` (a blob of a
    nearer target is not credited to a small target hidden behind it). Pairs are taken
    greedily, the smallest ``(bearing error / window)² + (relative distance error /
    DISTANCE_SCALE)² + (relative area difference / AREA_SCALE)²`` first (the area difference:
    how far the blob falls short of the target's whole footprint ``width_px * height_px`` or
    exceeds its :func:`merge_room`, over the larger; ties: lower target, then lower blob
    index), whatever either provider said about visibility, so the matcher favours neither.

    Args:
        bearing, distance, half_width: (T,) each target's true bearing (rad), horizontal
            distance and half width (m).
        blobs: the detected blobs (all of the targets' class).
        px_angle: rad, one pixel column of the strip.
        spread: (T,) rad, how far each target's blob reaches beyond its own half width
            because touching targets of its colour merged into it (their blob's bearing is
            their centroid's); widens the bearing window.
        width_px, height_px: (T,) px, each target's whole projected footprint if nothing hid
            it (pixel columns and rows); None: area plays no part. A target with an empty
            footprint bounds nothing, and any blob differs from it by the whole.

    Returns:
        (T,) index into ``blobs`` of each target's blob, -1 where none matched.
    """
    matched = np.full(len(bearing), -1, dtype=np.int64)
    if not len(blobs) or not len(bearing):
        return matched
    b_bear = np.array([b.bearing for b in blobs])
    b_dist = np.array([b.distance for b in blobs])
    safe = np.maximum(distance, 1e-6)
    window = np.arctan2(half_width, safe) + max(math.radians(BEARING_MARGIN_DEG), 2 * px_angle)
    if spread is not None:
        window = window + spread
    turn = b_bear[None, :] - bearing[:, None] + math.pi
    err_b = np.abs(np.remainder(turn, 2 * math.pi) - math.pi)
    err_d = np.abs(b_dist[None, :] - distance[:, None]) / safe[:, None]
    ok = (err_b <= window[:, None]) & (err_d <= DISTANCE_TOLERANCE)
    cost = (err_b / window[:, None]) ** 2 + (err_d / DISTANCE_SCALE) ** 2
    if width_px is not None and height_px is not None:
        footprint = width_px * height_px
        b_area = np.array([b.area for b in blobs], dtype=float)
        room = merge_room(bearing, distance, half_width, width_px, height_px, px_angle)
        # The area a blob of the target should have: its footprint, or more up to its room
        # (a merge, credited to its nearest target as before); none without a footprint.
        expect = np.clip(b_area[None, :], footprint[:, None], room[:, None])
        expect = np.where(footprint[:, None] > 0.0, expect, 0.0)
        # A target without a footprint (edge-on beyond the outline's rule) has no bound: its
        # blob, if the camera sees one, still counts against the provider that missed it.
        room = np.where(footprint > 0.0, room, np.inf)
        ok &= b_area[None, :] <= AREA_FACTOR * room[:, None] + AREA_MARGIN_PX
        larger = np.maximum(np.maximum(b_area[None, :], expect), 1.0)
        err_a = np.abs(b_area[None, :] - expect) / larger
        cost = cost + (err_a / AREA_SCALE) ** 2
    t_idx, b_idx = np.nonzero(ok)
    order = np.lexsort((b_idx, t_idx, cost[t_idx, b_idx]))
    used = np.zeros(len(blobs), dtype=bool)
    for k in order:
        t, j = t_idx[k], b_idx[k]
        if matched[t] < 0 and not used[j]:
            matched[t] = j
            used[j] = True
    return matched


def compare_robot(
    geo: GeometricVision, meas: TargetMeasurements, frame: VisionFrame, robot: int
) -> tuple[list[TargetComparison], list[Blob]]:
    """Match one robot's rendered blobs to its candidate targets (:func:`match_blobs`): blobs
    of each colour class to that class's targets, by bearing, distance and area.

    Returns:
        The comparison of every candidate target (another robot's lit LED, another robot's
        face, every pack), and the rendered blobs that matched none.
    """
    led_on = geo.world.led_on
    px_angle = 2.0 * math.pi / geo.config.strip_width
    blobs = frame.blobs[robot]
    used = np.zeros(len(blobs), dtype=bool)
    rows = []
    for cls in range(N_CLASSES):
        targets = np.array(
            [
                t
                for t in range(len(geo.target_geom))
                if geo.target_cls[t] == cls
                and geo.target_owner[t] != robot
                and (cls != LED or led_on[t])
            ],
            dtype=np.int64,
        )
        of_class = [j for j, b in enumerate(blobs) if b.cls == cls]
        matched = match_blobs(
            meas.bearing[robot, targets],
            meas.distance[robot, targets],
            geo.half_width[targets],
            [blobs[j] for j in of_class],
            px_angle,
            meas.blob_spread[robot, targets],
            meas.width_px[robot, targets],
            meas.height_px[robot, targets],
        )
        for t, m in zip(targets.tolist(), matched.tolist(), strict=True):
            distance = float(meas.distance[robot, t])
            extra = {}
            if m >= 0:
                blob = blobs[of_class[m]]
                used[of_class[m]] = True
                err = abs(math.remainder(blob.bearing - float(meas.bearing[robot, t]), 2 * math.pi))
                extra = {
                    "bearing_error_deg": math.degrees(err),
                    "distance_rel_error": abs(blob.distance - distance) / distance,
                    "blob_area": float(blob.area),
                }
            rows.append(
                TargetComparison(
                    robot=robot,
                    target=t,
                    cls=cls,
                    distance=distance,
                    geometric=bool(meas.visible[robot, t]),
                    rendered=m >= 0,
                    geometric_area=float(meas.area[robot, t]),
                    **extra,
                )
            )
    rows.sort(key=lambda r: r.target)
    unmatched = [b for j, b in enumerate(blobs) if not used[j]]
    return rows, unmatched


@dataclass
class SceneComparison:
    """Both providers on one state.

    Attributes:
        targets: every robot's candidate targets (:func:`compare_robot`).
        unmatched: rendered blobs that matched no target.
        nearest: every robot's nearest target of each class (:func:`compare_nearest`).
        geometric, rendered: both frames.
        measurements: the geometric provider's per-target measurements.
    """

    targets: list[TargetComparison]
    unmatched: list[Blob]
    nearest: list[NearestComparison]
    geometric: VisionFrame
    rendered: VisionFrame
    measurements: TargetMeasurements


def compare_scene(geo: GeometricVision, ren: RenderedVision) -> SceneComparison:
    """Compare both providers on the world's current state (both bound to the same world)."""
    if geo.world is not ren.world:
        raise ValueError("both providers must observe the same world")
    meas = geo.measure_targets()
    f_geo = geo.observe()
    f_ren = ren.observe()
    rows: list[TargetComparison] = []
    unmatched: list[Blob] = []
    for i in range(geo.n_robots):
        r, u = compare_robot(geo, meas, f_ren, i)
        rows += r
        unmatched += u
    nearest = compare_nearest(geo, meas, f_geo, f_ren)
    return SceneComparison(rows, unmatched, nearest, f_geo, f_ren, meas)


#: Relative distance difference within which two nearest-target readings agree.
NEAREST_DISTANCE_TOLERANCE = 0.1


@dataclass(frozen=True)
class NearestComparison:
    """One robot's nearest target of one class (a controller input), as both providers saw it.

    Attributes:
        robot, cls: observer and colour class.
        closest: m, true distance of the closest target of the class that could be seen at
            all (another robot's lit LED or face, any pack), whatever occludes it; inf if none.
        geometric, rendered: whether each provider saw a target of the class.
        geometric_distance, rendered_distance: m, the nearest one's distance (inf if none).
        geometric_bearing, rendered_bearing: rad (0 if none).
    """

    robot: int
    cls: int
    closest: float
    geometric: bool
    rendered: bool
    geometric_distance: float
    rendered_distance: float
    geometric_bearing: float
    rendered_bearing: float

    @property
    def agree(self) -> bool:
        """Both see nothing, or both see one at distances within 10 % of each other."""
        if self.geometric != self.rendered:
            return False
        if not self.geometric:
            return True
        gap = abs(self.rendered_distance - self.geometric_distance)
        return gap <= NEAREST_DISTANCE_TOLERANCE * self.geometric_distance


def compare_nearest(
    geo: GeometricVision, meas: TargetMeasurements, f_geo: VisionFrame, f_ren: VisionFrame
) -> list[NearestComparison]:
    """Compare every robot's nearest LED, face and pack between the two frames."""
    out = []
    led_on = geo.world.led_on
    for i in range(geo.n_robots):
        for c in range(N_CLASSES):
            sel = (geo.target_cls == c) & (geo.target_owner != i)
            if c == LED:
                sel &= np.concatenate([led_on, np.zeros(len(sel) - len(led_on), dtype=bool)])
            d = meas.distance[i, sel]
            out.append(
                NearestComparison(
                    robot=i,
                    cls=c,
                    closest=float(d.min()) if len(d) else math.inf,
                    geometric=bool(f_geo.visible[i, c]),
                    rendered=bool(f_ren.visible[i, c]),
                    geometric_distance=float(f_geo.distance[i, c]),
                    rendered_distance=float(f_ren.distance[i, c]),
                    geometric_bearing=float(f_geo.bearing[i, c]),
                    rendered_bearing=float(f_ren.bearing[i, c]),
                )
            )
    return out


def random_scene(world: World, rng: np.random.Generator, led_probability: float = 0.5) -> None:
    """Random placement and headings (``World.reset``), every LED on with ``led_probability``."""
    world.reset(rng)
    world.set_led(rng.random(world.config.n_robots) < led_probability)


@dataclass(frozen=True)
class ClassAgreement:
    """Agreement statistics of one colour class (or of all, ``cls = -1``)."""

    cls: int
    targets: int
    agreement: float
    geometric_only: int
    rendered_only: int
    both: int
    bearing_error_median_deg: float
    bearing_error_p95_deg: float
    distance_error_median: float
    distance_error_p95: float

    @property
    def name(self) -> str:
        return CLASS_NAMES[self.cls] if self.cls >= 0 else "all"


def summarise(rows: list[TargetComparison], within: float | None = None) -> list[ClassAgreement]:
    """Per-class statistics (then all classes) of targets within ``within`` m (all if None)."""
    out = []
    for cls in [*range(N_CLASSES), -1]:
        sel = [
            r
            for r in rows
            if (cls < 0 or r.cls == cls) and (within is None or r.distance <= within)
        ]
        both = [r for r in sel if r.geometric and r.rendered]
        be = np.array([r.bearing_error_deg for r in both])
        de = np.array([r.distance_rel_error for r in both])

        def stat(a: np.ndarray, q: float) -> float:
            return float(np.percentile(a, q)) if len(a) else math.nan

        out.append(
            ClassAgreement(
                cls=cls,
                targets=len(sel),
                agreement=(sum(r.geometric == r.rendered for r in sel) / len(sel))
                if sel
                else math.nan,
                geometric_only=sum(r.geometric and not r.rendered for r in sel),
                rendered_only=sum(r.rendered and not r.geometric for r in sel),
                both=len(both),
                bearing_error_median_deg=stat(be, 50),
                bearing_error_p95_deg=stat(be, 95),
                distance_error_median=stat(de, 50),
                distance_error_p95=stat(de, 95),
            )
        )
    return out
