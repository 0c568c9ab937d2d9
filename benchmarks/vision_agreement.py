"""Agreement of the geometric and the rendered vision providers on random scenes.

For each of ``--scenes`` random seeded scenes (4 robots, 5 packs, random placement and headings
by ``World.reset``, every LED on or off with p = 0.5), both providers observe the same state and
every candidate target of every robot is compared (:mod:`cyber_rodent.vision.agreement`):
detection agreement per class, the disagreements each way, and for targets both detect the
bearing error (median, 95th percentile) and relative distance error (median, 95th
percentile); for targets within ``--within`` m (default 1.5) and for all targets. Also: the
rendered blobs that match no target, and the same comparison for the nearest target of each
class, which is what the controller reads.

    .venv/bin/python benchmarks/vision_agreement.py --scenes 200
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np

from cyber_rodent.vision import CLASS_NAMES, N_CLASSES, CameraConfig
from cyber_rodent.vision.agreement import compare_scene, random_scene, summarise
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.world import World, WorldConfig


def nearest_stats(pairs: list[tuple], within: float) -> dict:
    """Compare the nearest-target outputs (per robot and class) of the two providers."""
    out = {}
    for c in range(N_CLASSES):
        sel = [p for p in pairs if p[0] == c and min(p[2], p[5]) <= within]
        both = [p for p in sel if p[1] and p[4]]
        be = [abs(math.degrees(math.remainder(p[3] - p[6], 2 * math.pi))) for p in both]
        de = [abs(p[5] - p[2]) / p[2] for p in both]
        out[CLASS_NAMES[c]] = {
            "pairs": len(sel),
            "visible_agreement": sum(p[1] == p[4] for p in sel) / len(sel) if sel else math.nan,
            "bearing_err_median_deg": float(np.median(be)) if be else math.nan,
            "dist_rel_err_median": float(np.median(de)) if de else math.nan,
        }
    return out


def run(n_scenes: int, seed: int, within: float, config: CameraConfig) -> dict:
    world = World(WorldConfig(n_robots=4, n_packs=5))
    geo = GeometricVision(world, config)
    rows, unmatched, pairs = [], [], []
    t0 = time.perf_counter()
    with RenderedVision(world, config) as ren:
        for s in range(n_scenes):
            random_scene(world, np.random.default_rng([seed, s]))
            scene = compare_scene(geo, ren)
            f_geo, f_ren = scene.geometric, scene.rendered
            rows += [(s, x) for x in scene.targets]
            unmatched += [(s, b) for b in scene.unmatched]
            for i in range(world.config.n_robots):
                for c in range(N_CLASSES):
                    pairs.append(
                        (
                            c,
                            f_geo.visible[i, c],
                            f_geo.distance[i, c],
                            f_geo.bearing[i, c],
                            f_ren.visible[i, c],
                            f_ren.distance[i, c],
                            f_ren.bearing[i, c],
                        )
                    )
    elapsed = time.perf_counter() - t0
    plain = [x for _, x in rows]
    return {
        "scenes": n_scenes,
        "seed": seed,
        "within_m": within,
        "camera": dataclasses.asdict(config),
        "within": [dataclasses.asdict(a) | {"name": a.name} for a in summarise(plain, within)],
        "all_distances": [dataclasses.asdict(a) | {"name": a.name} for a in summarise(plain)],
        "unmatched_rendered_blobs": len(unmatched),
        "unmatched_examples": [
            {
                "scene": s,
                "cls": CLASS_NAMES[b.cls],
                "bearing_deg": round(math.degrees(b.bearing), 1),
                "distance": round(b.distance, 3),
                "area": b.area,
            }
            for s, b in unmatched[:20]
        ],
        "disagreements_within": [
            {
                "scene": s,
                "robot": x.robot,
                "target": x.target,
                "cls": CLASS_NAMES[x.cls],
                "distance": round(x.distance, 3),
                "geometric": x.geometric,
                "rendered": x.rendered,
            }
            for s, x in rows
            if x.distance <= within and x.geometric != x.rendered
        ],
        "nearest": nearest_stats(pairs, within),
        "seconds": elapsed,
    }


def _print_table(title: str, stats: list[dict]) -> None:
    print(f"\n{title}:")
    print(
        f"  {'class':8s} {'n':>5s} {'agree':>7s} {'geo-only':>8s} {'ren-only':>8s} "
        f"{'brg med':>8s} {'brg p95':>8s} {'dist med':>8s} {'dist p95':>8s}"
    )
    for a in stats:
        print(
            f"  {a['name']:8s} {a['targets']:5d} {100 * a['agreement']:6.1f}% "
            f"{a['geometric_only']:8d} {a['rendered_only']:8d} "
            f"{a['bearing_error_median_deg']:7.2f}° {a['bearing_error_p95_deg']:7.2f}° "
            f"{100 * a['distance_error_median']:7.1f}% {100 * a['distance_error_p95']:7.1f}%"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--within", type=float, default=1.5)
    ap.add_argument("--view-width", type=int, default=CameraConfig.view_width)
    ap.add_argument("--height", type=int, default=CameraConfig.height)
    ap.add_argument("--json", type=Path, default=None, help="also write the full result here")
    args = ap.parse_args()
    config = CameraConfig(view_width=args.view_width, height=args.height)
    res = run(args.scenes, args.seed, args.within, config)
    print(
        f"{res['scenes']} scenes (seed {args.seed}), 4 robots, 5 packs; camera "
        f"{config.n_views} x {config.view_width} x {config.height} px; {res['seconds']:.1f} s"
    )
    _print_table(f"targets within {args.within} m", res["within"])
    _print_table("all targets", res["all_distances"])
    print(f"\nrendered blobs matching no target: {res['unmatched_rendered_blobs']}")
    print(f"\nnearest target of each class per robot (either provider's within {args.within} m):")
    for name, v in res["nearest"].items():
        print(
            f"  {name:8s} pairs {v['pairs']:4d}  visible agreement "
            f"{100 * v['visible_agreement']:5.1f}%  bearing error median "
            f"{v['bearing_err_median_deg']:.2f}°  distance error median "
            f"{100 * v['dist_rel_err_median']:.1f}%"
        )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=2, default=str))


if __name__ == "__main__":
    main()
