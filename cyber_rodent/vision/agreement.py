"""How well the geometric provider reproduces the rendered camera, target by target.

Both providers observe the same state. The geometric provider says, for every candidate target
of every robot (other robots' lit LEDs and faces, every pack), whether it is visible
(:meth:`GeometricVision.measure_targets`). The rendered provider's blobs are matched one-to-one
to targets of the same class by bearing: greedily, smallest bearing error first, visible
targets before hidden ones, within the target's angular half width plus max(2°, 2 px). A target
is "rendered-detected" when a blob matched it. For targets both providers detect, the bearing
error and the relative distance error are recorded.

Used by ``benchmarks/vision_agreement.py`` (many random scenes) and by the tests (a few).
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
        bearing_error_deg: |rendered − true bearing|, degrees (NaN unless both detected).
        distance_rel_error: |rendered − true distance| / true distance (NaN unless both).
    """

    robot: int
    target: int
    cls: int
    distance: float
    geometric: bool
    rendered: bool
    bearing_error_deg: float = math.nan
    distance_rel_error: float = math.nan


def compare_robot(
    geo: GeometricVision, meas: TargetMeasurements, frame: VisionFrame, robot: int
) -> tuple[list[TargetComparison], list[Blob]]:
    """Match one robot's rendered blobs to its candidate targets.

    Returns:
        The comparison of every candidate target, and the rendered blobs that matched none.
    """
    led_on = geo.world.led_on
    px_angle = 2.0 * math.pi / geo.config.strip_width
    candidates = [
        t
        for t in range(len(geo.target_geom))
        if geo.target_owner[t] != robot and (geo.target_cls[t] != LED or led_on[t])
    ]
    blobs = frame.blobs[robot]
    used = [False] * len(blobs)
    rows = []
    order = sorted(candidates, key=lambda t: (not meas.visible[robot, t], meas.distance[robot, t]))
    for t in order:
        cls = int(geo.target_cls[t])
        bearing = float(meas.bearing[robot, t])
        distance = float(meas.distance[robot, t])
        half = math.atan2(float(geo.half_width[t]), max(distance, 1e-6))
        tolerance = half + max(math.radians(2.0), 2.0 * px_angle)
        best, best_err = -1, math.inf
        for j, blob in enumerate(blobs):
            if used[j] or blob.cls != cls:
                continue
            err = abs(math.remainder(blob.bearing - bearing, 2.0 * math.pi))
            if err < best_err:
                best, best_err = j, err
        detected = best >= 0 and best_err <= tolerance
        extra = {}
        if detected:
            used[best] = True
            extra = {
                "bearing_error_deg": math.degrees(best_err),
                "distance_rel_error": abs(blobs[best].distance - distance) / distance,
            }
        rows.append(
            TargetComparison(
                robot=robot,
                target=t,
                cls=cls,
                distance=distance,
                geometric=bool(meas.visible[robot, t]),
                rendered=detected,
                **extra,
            )
        )
    unmatched = [b for j, b in enumerate(blobs) if not used[j]]
    return rows, unmatched


def compare_scene(
    geo: GeometricVision, ren: RenderedVision
) -> tuple[list[TargetComparison], list[Blob], VisionFrame, VisionFrame]:
    """Compare both providers on the world's current state (both bound to the same world).

    Returns:
        Per-target comparisons, unmatched rendered blobs, and both frames (geometric, rendered).
    """
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
    return rows, unmatched, f_geo, f_ren


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
