"""Agreement of the geometric and the rendered vision providers on hand-built hard scenes.

Each family of :mod:`cyber_rodent.vision.hard_scenes` (robots in a row, targets behind robots,
robots gathered on a pack, view seams, far corners, pack clusters, mating pairs) is built
``--scenes`` times, seeded; both providers observe every scene and
:func:`cyber_rodent.vision.agreement.compare_scene` matches the rendered blobs to the true
targets by class, bearing, distance and area. Per family it reports, for targets within
``--within`` m (default 2) and beyond:

* **per target**: the share of (observer, candidate target) pairs on which both providers agree
  (seen or not), over every pair and over the family's designed pairs;
* **controller inputs**: the share of (robot, class) nearest-target readings that agree (both
  see nothing, or both see one at distances within 10 %), for robots with a target of the
  class within range.

Every disagreement is written to ``--out``/disagreements.csv with the omni image of its robot
(``<family>_<scene>_robot<r>.png``: the rendered strip with white ticks where the geometric
provider sees targets, and the segmentation with the rendered blobs), and the worst ones, by the
larger of the two providers' areas, are listed.

    .venv/bin/python -m benchmarks.vision_hard_scenes --scenes 40
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from cyber_rodent.vision import CLASS_NAMES, CameraConfig
from cyber_rodent.vision.agreement import (
    NearestComparison,
    SceneComparison,
    TargetComparison,
    compare_scene,
)
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.hard_scenes import FAMILIES, Family, make_scenes, place
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.vision.snapshot import compose_omni_panels
from cyber_rodent.world import World


@dataclass
class FamilyResult:
    """Everything one family's scenes gave."""

    family: Family
    targets: list[tuple[int, TargetComparison, bool]] = field(default_factory=list)
    nearest: list[tuple[int, NearestComparison]] = field(default_factory=list)
    disagreements: list[dict] = field(default_factory=list)
    seconds: float = 0.0


def _share(flags: Sequence[bool]) -> float:
    return sum(flags) / len(flags) if flags else math.nan


def summary(result: FamilyResult, within: float) -> dict:
    """Per-family agreement figures (see the module docstring)."""
    near = [(r, d) for _, r, d in result.targets if r.distance <= within]
    far = [(r, d) for _, r, d in result.targets if r.distance > within]
    inputs = [n for _, n in result.nearest if n.closest <= within]
    close_both = [
        n for n in inputs if n.geometric and n.rendered and n.geometric_distance <= within
    ]
    return {
        "family": result.family.name,
        "scenes": len({s for s, _, _ in result.targets}),
        "targets_within": len(near),
        "agree_within": _share([r.geometric == r.rendered for r, _ in near]),
        "designed_within": sum(d for _, d in near),
        "agree_designed_within": _share([r.geometric == r.rendered for r, d in near if d]),
        "targets_beyond": len(far),
        "agree_beyond": _share([r.geometric == r.rendered for r, _ in far]),
        "inputs_within": len(inputs),
        "agree_inputs_within": _share([n.agree for n in inputs]),
        "agree_inputs_visibility": _share([n.geometric == n.rendered for n in inputs]),
        "input_distance_gap_median": float(
            np.median(
                [abs(n.rendered_distance / n.geometric_distance - 1.0) for n in close_both]
            )
        )
        if close_both
        else math.nan,
        "seconds": result.seconds,
    }


def _save_image(
    path: Path, ren: RenderedVision, comparison: SceneComparison, geo: GeometricVision, robot: int,
    title: str,
) -> None:  # fmt: skip
    strips, masks = ren.last_strips, ren.last_masks
    assert strips is not None and masks is not None
    meas = comparison.measurements
    expected = [
        (
            float(meas.bearing[robot, t]),
            int(geo.target_cls[t]),
            f"{CLASS_NAMES[int(geo.target_cls[t])][0].upper()}{t} {meas.distance[robot, t]:.2f}",
        )
        for t in np.flatnonzero(meas.visible[robot])
    ]
    image = compose_omni_panels(
        strips[robot], masks[:, robot], comparison.rendered, robot, ren, expected, title
    )
    cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))


def run_family(
    family: Family, count: int, seed: int, within: float, config: CameraConfig, out: Path | None
) -> FamilyResult:
    """Build and compare ``count`` scenes of ``family``; save disagreement images in ``out``."""
    world = World(family.world_config())
    geo = GeometricVision(world, config)
    result = FamilyResult(family)
    t0 = time.perf_counter()
    with RenderedVision(world, config) as ren:
        scenes = make_scenes(world, family, count, seed)
        for s, scene in enumerate(scenes):
            place(world, scene)
            comparison = compare_scene(geo, ren)
            designed = set(scene.designed)
            bad_robots: dict[int, list[str]] = {}
            for row in comparison.targets:
                is_designed = (row.robot, row.target) in designed
                result.targets.append((s, row, is_designed))
                if row.geometric != row.rendered:
                    score = max(row.geometric_area, row.blob_area)
                    kind = "geometric only" if row.geometric else "rendered only"
                    result.disagreements.append(
                        {
                            "family": family.name, "scene": s, "robot": row.robot,
                            "kind": "target", "class": CLASS_NAMES[row.cls],
                            "target": row.target, "distance": round(row.distance, 3),
                            "detail": kind, "designed": is_designed,
                            "geometric_area": round(row.geometric_area, 1),
                            "rendered_area": row.blob_area, "score": round(score, 1),
                        }
                    )  # fmt: skip
                    bad_robots.setdefault(row.robot, []).append(
                        f"{CLASS_NAMES[row.cls]} {row.target} at {row.distance:.2f} m: {kind}"
                    )
            for n in comparison.nearest:
                result.nearest.append((s, n))
                if not n.agree and n.closest <= within:
                    gap = (
                        abs(n.rendered_distance - n.geometric_distance)
                        if n.geometric and n.rendered
                        else math.inf
                    )
                    result.disagreements.append(
                        {
                            "family": family.name, "scene": s, "robot": n.robot,
                            "kind": "nearest", "class": CLASS_NAMES[n.cls], "target": -1,
                            "distance": round(n.closest, 3),
                            "detail": f"geometric {n.geometric_distance:.3f} m, "
                            f"rendered {n.rendered_distance:.3f} m",
                            "designed": False, "geometric_area": math.nan,
                            "rendered_area": math.nan,
                            "score": 1e4 if gap == math.inf else round(1e3 * gap, 1),
                        }
                    )  # fmt: skip
                    bad_robots.setdefault(n.robot, []).append(
                        f"nearest {CLASS_NAMES[n.cls]}: geometric {n.geometric_distance:.2f},"
                        f" rendered {n.rendered_distance:.2f}"
                    )
            if out is not None:
                for robot, notes in bad_robots.items():
                    name = f"{family.name}_{s:03d}_robot{robot}.png"
                    title = f"{family.name} scene {s} robot {robot}: " + "; ".join(notes[:3])
                    _save_image(out / name, ren, comparison, geo, robot, title)
                    for d in result.disagreements:
                        if (d["family"], d["scene"], d["robot"]) == (family.name, s, robot):
                            d["image"] = name
    result.seconds = time.perf_counter() - t0
    return result


def _rounded(value: object) -> object:
    return round(value, 4) if isinstance(value, float) else value


def _pct(x: float) -> str:
    return "   -  " if math.isnan(x) else f"{100 * x:5.1f}%"


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=40, help="scenes per family (default 40)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--within", type=float, default=2.0, help="m, the near range (default 2)")
    ap.add_argument(
        "--families", default=",".join(f.name for f in FAMILIES), help="comma-separated names"
    )
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/hard_scenes"))
    ap.add_argument("--worst", type=int, default=10, help="list this many worst disagreements")
    ap.add_argument(
        "--table", type=Path, default=None, help="also write the per-family table here (CSV)"
    )
    args = ap.parse_args(argv)
    names = args.families.split(",")
    chosen = [f for f in FAMILIES if f.name in names]
    unknown = set(names) - {f.name for f in FAMILIES}
    if unknown:
        ap.error(f"unknown families: {', '.join(sorted(unknown))}")
    args.out.mkdir(parents=True, exist_ok=True)
    for old in args.out.glob("*.png"):
        old.unlink()
    config = CameraConfig()
    print(
        f"{args.scenes} scenes per family (seed {args.seed}); camera {config.n_views} x "
        f"{config.view_width} x {config.height} px; near range {args.within} m"
    )
    print(
        f"\n  {'family':13s} {'targets':>7s} {'agree':>6s} {'designed':>8s} {'agree':>6s} "
        f"{'inputs':>6s} {'agree':>6s} {'(vis)':>6s} {'d gap':>6s} │ {'beyond':>6s} "
        f"{'agree':>6s}  {'s':>5s}"
    )
    results = []
    disagreements: list[dict] = []
    for family in chosen:
        r = run_family(family, args.scenes, args.seed, args.within, config, args.out)
        s = summary(r, args.within)
        results.append(s)
        disagreements += r.disagreements
        print(
            f"  {family.name:13s} {s['targets_within']:7d} {_pct(s['agree_within'])} "
            f"{s['designed_within']:8d} {_pct(s['agree_designed_within'])} "
            f"{s['inputs_within']:6d} {_pct(s['agree_inputs_within'])} "
            f"{_pct(s['agree_inputs_visibility'])} {_pct(s['input_distance_gap_median'])} │ "
            f"{s['targets_beyond']:6d} {_pct(s['agree_beyond'])}  {s['seconds']:5.1f}",
            flush=True,
        )
    print(
        "\n  targets/agree: every (observer, candidate target) pair within range; designed: "
        "the family's designed pairs;\n  inputs: (robot, class) nearest-target readings with "
        "a target of the class within range, agreeing\n  on visibility and distance (10 %); "
        "(vis): on visibility alone; d gap: median distance gap when both see one."
    )
    keys = [
        "family", "scene", "robot", "kind", "class", "target", "distance", "detail",
        "designed", "geometric_area", "rendered_area", "score", "image",
    ]  # fmt: skip
    with open(args.out / "disagreements.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        for d in disagreements:
            writer.writerow({k: d.get(k, "") for k in keys})
    table = [{k: _rounded(v) for k, v in r.items() if k != "seconds"} for r in results]
    for path in [args.out / "summary.csv"] + ([args.table] if args.table else []):
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(table[0]))
            writer.writeheader()
            writer.writerows(table)
    near = [d for d in disagreements if d["distance"] <= args.within]
    worst = sorted(near, key=lambda d: -d["score"])[: args.worst]
    print(f"\n{len(near)} disagreements within {args.within} m; the worst {len(worst)}:")
    for d in worst:
        print(
            f"  {d['family']:13s} scene {d['scene']:3d} robot {d['robot']} {d['kind']:7s} "
            f"{d['class']:7s} {d['distance']:5.2f} m  {d['detail']:32s} score {d['score']:7.1f}"
            f"  {d.get('image', '')}"
        )
    print(f"\nimages and CSVs in {args.out}")


if __name__ == "__main__":
    main()
