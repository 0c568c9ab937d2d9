"""Agreement of the geometric and the rendered vision providers on random scenes.

For each of ``--scenes`` random seeded scenes (4 robots, 5 packs, every LED on or off with
p = 0.5, random placement and headings by ``World.reset``), both providers observe the same
state. Every candidate target of every robot (other robots' lit LEDs and faces, all packs) is
then compared:

* the geometric provider says per target whether it is visible (``measure_targets``);
* the rendered provider's blobs are matched one-to-one to targets of the same class by bearing
  (greedy, smallest bearing error first; visible targets first), within the target's angular
  half width + max(2°, 2 px); a target is "rendered-detected" when a blob matched it.

Reported per class, for targets within ``--within`` m (default 1.5) and for all targets:
detection agreement (both see it or both do not), the disagreements each way, the bearing
error (median, 95th percentile) and relative distance error (median, 95th percentile) of
targets both detect; the number of rendered blobs that match no target; and the same
comparison for the nearest target of each class (what the controller reads).

    .venv/bin/python benchmarks/vision_agreement.py --scenes 200
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from cyber_rodent.vision import CLASS_NAMES, N_CLASSES, CameraConfig
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.world import World, WorldConfig


def match_targets(meas, frame, geo: GeometricVision, robot: int, px_angle: float) -> list[dict]:
    """Match one robot's rendered blobs to the geometric targets (see module docstring)."""
    led_on = geo.world.led_on
    candidates = []
    for t in range(len(geo.target_geom)):
        owner = int(geo.target_owner[t])
        if owner == robot:
            continue
        cls = int(geo.target_cls[t])
        if cls == 0 and not led_on[t]:
            continue  # a dark LED is not a target
        candidates.append(t)
    blobs = frame.blobs[robot]
    used = [False] * len(blobs)
    rows = []
    # Visible targets pick blobs first, nearest first; then hidden ones take what is left.
    order = sorted(candidates, key=lambda t: (not meas.visible[robot, t], meas.distance[robot, t]))
    for t in order:
        cls = int(geo.target_cls[t])
        b_t = float(meas.bearing[robot, t])
        d_t = float(meas.distance[robot, t])
        half = math.atan2(geo._half_width[t], max(d_t, 1e-6))
        tol = half + max(math.radians(2.0), 2.0 * px_angle)
        best, best_err = -1, math.inf
        for j, blob in enumerate(blobs):
            if used[j] or blob.cls != cls:
                continue
            err = abs(math.remainder(blob.bearing - b_t, 2 * math.pi))
            if err < best_err:
                best, best_err = j, err
        detected = best >= 0 and best_err <= tol
        row = {
            "cls": cls,
            "distance": d_t,
            "geo": bool(meas.visible[robot, t]),
            "ren": detected,
            "target": t,
            "robot": robot,
            "geo_area": float(meas.area[robot, t]),
            "ren_area": float(blobs[best].area) if detected else 0.0,
        }
        if detected:
            used[best] = True
            row["bearing_err"] = math.degrees(best_err)
            row["dist_rel_err"] = abs(blobs[best].distance - d_t) / d_t
        rows.append(row)
    unmatched = [b for j, b in enumerate(blobs) if not used[j]]
    return rows, unmatched


def summarise(rows: list[dict], within: float | None) -> dict:
    out = {}
    for c in range(N_CLASSES):
        sel = [r for r in rows if r["cls"] == c and (within is None or r["distance"] <= within)]
        both = [r for r in sel if r["geo"] and r["ren"]]
        agree = sum(r["geo"] == r["ren"] for r in sel)
        be = np.array([r["bearing_err"] for r in both]) if both else np.zeros(0)
        de = np.array([r["dist_rel_err"] for r in both]) if both else np.zeros(0)
        out[CLASS_NAMES[c]] = {
            "targets": len(sel),
            "agreement": agree / len(sel) if sel else float("nan"),
            "geo_only": sum(r["geo"] and not r["ren"] for r in sel),
            "rendered_only": sum(r["ren"] and not r["geo"] for r in sel),
            "both_seen": len(both),
            "bearing_err_median_deg": float(np.median(be)) if len(be) else float("nan"),
            "bearing_err_p95_deg": float(np.percentile(be, 95)) if len(be) else float("nan"),
            "dist_rel_err_median": float(np.median(de)) if len(de) else float("nan"),
            "dist_rel_err_p95": float(np.percentile(de, 95)) if len(de) else float("nan"),
        }
    both = [
        r for r in rows if r["geo"] and r["ren"] and (within is None or r["distance"] <= within)
    ]
    sel = [r for r in rows if within is None or r["distance"] <= within]
    be = np.array([r["bearing_err"] for r in both])
    de = np.array([r["dist_rel_err"] for r in both])
    out["all"] = {
        "targets": len(sel),
        "agreement": sum(r["geo"] == r["ren"] for r in sel) / max(len(sel), 1),
        "bearing_err_median_deg": float(np.median(be)),
        "bearing_err_p95_deg": float(np.percentile(be, 95)),
        "dist_rel_err_median": float(np.median(de)),
        "dist_rel_err_p95": float(np.percentile(de, 95)),
    }
    return out


def nearest_stats(pairs: list[tuple], within: float) -> dict:
    """Compare the nearest-target outputs (per robot and class) of the two providers."""
    out = {}
    for c in range(N_CLASSES):
        sel = [p for p in pairs if p[0] == c and (min(p[2], p[5]) <= within)]
        agree = sum(p[1] == p[4] for p in sel)
        both = [p for p in sel if p[1] and p[4]]
        be = [abs(math.degrees(math.remainder(p[3] - p[6], 2 * math.pi))) for p in both]
        de = [abs(p[5] - p[2]) / p[2] for p in both]
        out[CLASS_NAMES[c]] = {
            "pairs": len(sel),
            "visible_agreement": agree / len(sel) if sel else float("nan"),
            "bearing_err_median_deg": float(np.median(be)) if be else float("nan"),
            "dist_rel_err_median": float(np.median(de)) if de else float("nan"),
        }
    return out


def run(n_scenes: int, seed: int, within: float, config: CameraConfig) -> dict:
    world = World(WorldConfig(n_robots=4, n_packs=5))
    geo = GeometricVision(world, config)
    ren = RenderedVision(world, config)
    px_angle = 2.0 * math.pi / config.strip_width
    rows, unmatched, pairs = [], [], []
    t0 = time.perf_counter()
    for s in range(n_scenes):
        rng = np.random.default_rng([seed, s])
        world.reset(rng)
        world.set_led(rng.random(world.config.n_robots) < 0.5)
        meas = geo.measure_targets()
        f_geo = geo.observe()
        f_ren = ren.observe()
        for i in range(world.config.n_robots):
            r, u = match_targets(meas, f_ren, geo, i, px_angle)
            for row in r:
                row["scene"] = s
            rows += r
            unmatched += [(s, i, b) for b in u]
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
    ren.close()
    return {
        "scenes": n_scenes,
        "seed": seed,
        "within_m": within,
        "camera": {
            "view_width": config.view_width,
            "height": config.height,
            "n_views": config.n_views,
            "min_blob_area": config.min_blob_area,
        },
        "within": summarise(rows, within),
        "all_distances": summarise(rows, None),
        "unmatched_rendered_blobs": len(unmatched),
        "unmatched_examples": [
            {
                "scene": s,
                "robot": i,
                "cls": CLASS_NAMES[b.cls],
                "bearing_deg": round(math.degrees(b.bearing), 1),
                "distance": round(b.distance, 3),
                "area": b.area,
            }
            for s, i, b in unmatched[:10]
        ],
        "disagreements_within": [
            {
                "scene": r["scene"],
                "robot": r["robot"],
                "cls": CLASS_NAMES[r["cls"]],
                "target": r["target"],
                "distance": round(r["distance"], 3),
                "geo": r["geo"],
                "ren": r["ren"],
                "geo_area": round(r["geo_area"], 1),
                "ren_area": r["ren_area"],
            }
            for r in rows
            if r["distance"] <= within and r["geo"] != r["ren"]
        ][:200],
        "nearest": nearest_stats(pairs, within),
        "seconds": elapsed,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--within", type=float, default=1.5)
    ap.add_argument("--view-width", type=int, default=CameraConfig.view_width)
    ap.add_argument("--height", type=int, default=CameraConfig.height)
    ap.add_argument("--json", type=Path, default=None, help="also write the result here")
    args = ap.parse_args()
    config = CameraConfig(view_width=args.view_width, height=args.height)
    res = run(args.scenes, args.seed, args.within, config)
    print(
        f"{res['scenes']} scenes, camera {config.view_width}x{config.height} per view, "
        f"{res['seconds']:.1f} s"
    )
    for label, key in (
        (f"targets within {args.within} m", "within"),
        ("all targets", "all_distances"),
    ):
        print(f"\n{label}:")
        print(
            f"  {'class':8s} {'n':>5s} {'agree':>7s} {'geo-only':>8s} {'ren-only':>8s} "
            f"{'brg med':>8s} {'brg p95':>8s} {'dist med':>8s} {'dist p95':>8s}"
        )
        for name, v in res[key].items():
            if name == "all":
                print(
                    f"  {'all':8s} {v['targets']:5d} {100 * v['agreement']:6.1f}% "
                    f"{'':8s} {'':8s} {v['bearing_err_median_deg']:7.2f}° "
                    f"{v['bearing_err_p95_deg']:7.2f}° {100 * v['dist_rel_err_median']:7.1f}% "
                    f"{100 * v['dist_rel_err_p95']:7.1f}%"
                )
                continue
            print(
                f"  {name:8s} {v['targets']:5d} {100 * v['agreement']:6.1f}% "
                f"{v['geo_only']:8d} {v['rendered_only']:8d} "
                f"{v['bearing_err_median_deg']:7.2f}° {v['bearing_err_p95_deg']:7.2f}° "
                f"{100 * v['dist_rel_err_median']:7.1f}% {100 * v['dist_rel_err_p95']:7.1f}%"
            )
    print(f"\nrendered blobs matching no target: {res['unmatched_rendered_blobs']}")
    print(
        f"\nnearest target per robot and class (either provider's nearest within {args.within} m):"
    )
    for name, v in res["nearest"].items():
        print(
            f"  {name:8s} pairs {v['pairs']:4d}  visible agreement "
            f"{100 * v['visible_agreement']:5.1f}%  bearing err median "
            f"{v['bearing_err_median_deg']:.2f}°  dist err median "
            f"{100 * v['dist_rel_err_median']:.1f}%"
        )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
