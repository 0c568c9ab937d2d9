"""Cost of the vision providers per control step, and the rendered camera's LED detection range.

Part 1, cost: a 4-robot, 5-pack world in ``--states`` random states (``World.reset``, all LEDs
on); each state is observed ``--repeats`` times by each provider. Reported per control step (one
observation of all 4 robots): the geometric provider (``observe``, its full pass
``measure_targets``, and the lazy ``nearest_targets`` the evolution runner uses), the rendered
provider split into rendering (one
scene update, 16 tiles, one pixel read) and segmentation, and, for scale, 10 physics substeps.

Part 2, detection range: two robots alone in the field, the target's LED on. The observer sits
near one corner; the target is placed at distance d along the field's diagonal (±15°), the
observer's heading is random, so the LED appears at a random bearing (any view, any sub-pixel
phase). ``--trials`` placements per distance; the rate at which each provider reports the LED
is printed for each camera resolution. The reliable range is the largest distance up to which
every trial detected it.

    .venv/bin/python benchmarks/vision_cost.py
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
import numpy as np

from cyber_rodent.vision import LED, CameraConfig
from cyber_rodent.vision.geometric import GeometricVision
from cyber_rodent.vision.rendered import RenderedVision
from cyber_rodent.world import World, WorldConfig

RESOLUTIONS = ((64, 96), (96, 144), (128, 192), (128, 256), (192, 288), (256, 384))


def _per_call_ms(fn, repeats: int) -> float:
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t0) / repeats * 1e3


def cost(config: CameraConfig, n_states: int, repeats: int, seed: int) -> dict:
    world = World(WorldConfig(n_robots=4, n_packs=5))
    geo = GeometricVision(world, config)
    totals = {
        "geometric_observe": 0.0,
        "geometric_measure": 0.0,
        "geometric_nearest": 0.0,
        "render": 0.0,
        "segment": 0.0,
        "rendered_observe": 0.0,
        "physics_10_substeps": 0.0,
    }
    with RenderedVision(world, config) as ren:
        for s in range(n_states):
            world.reset(np.random.default_rng([seed, s]))
            world.set_led(True)
            ren.observe()  # warm up
            totals["geometric_observe"] += _per_call_ms(geo.observe, repeats * 20)
            totals["geometric_measure"] += _per_call_ms(geo.measure_targets, repeats * 20)
            totals["geometric_nearest"] += _per_call_ms(geo.nearest_targets, repeats * 200)
            totals["render"] += _per_call_ms(ren.renderer.render, repeats)
            strips = ren.renderer.render().copy()
            totals["segment"] += _per_call_ms(lambda s=strips: ren.segmenter.detect(s), repeats)
            totals["rendered_observe"] += _per_call_ms(ren.observe, repeats)
        state = mujoco.MjData(world.model)
        mujoco.mj_copyData(state, world.model, world.data)
        totals["physics_10_substeps"] = n_states * _per_call_ms(lambda: world.step(10), 200)
    return {k: v / n_states for k, v in totals.items()}


def led_detection(config: CameraConfig, distances: np.ndarray, trials: int, seed: int) -> dict:
    world = World(WorldConfig(n_robots=2, n_packs=0))
    geo = GeometricVision(world, config)
    rng = np.random.default_rng(seed)
    lim = 1.15 - 0.2  # robot centres stay this far inside the walls
    corner = np.array([-lim, -lim])
    rates: dict[str, list[float]] = {"rendered": [], "geometric": []}
    errors: list[float] = []
    with RenderedVision(world, config) as ren:
        for d in distances:
            hits = {"rendered": 0, "geometric": 0}
            n_done = 0
            for _ in range(trials):
                for _attempt in range(200):
                    heading = math.radians(45.0) + rng.uniform(-0.26, 0.26)
                    target = corner + d * np.array([math.cos(heading), math.sin(heading)])
                    if np.all(np.abs(target) <= lim):
                        break
                else:
                    continue
                bearing_in_image = rng.uniform(-math.pi, math.pi)
                world.set_robot_pose(0, corner[0], corner[1], heading - bearing_in_image)
                world.set_robot_pose(1, target[0], target[1], rng.uniform(-math.pi, math.pi))
                world.set_led(True, robot=1)
                mujoco.mj_forward(world.model, world.data)
                n_done += 1
                f_ren = ren.observe()
                f_geo = geo.observe()
                hits["rendered"] += bool(f_ren.visible[0, LED])
                hits["geometric"] += bool(f_geo.visible[0, LED])
                if f_ren.visible[0, LED]:
                    errors.append(abs(f_ren.distance[0, LED] - d) / d)
            for k in rates:
                rates[k].append(hits[k] / n_done if n_done else math.nan)
    reliable = 0.0
    for d, r in zip(distances, rates["rendered"], strict=True):
        if not r >= 1.0:
            break
        reliable = float(d)
    return {
        "rates": rates,
        "reliable_range_m": reliable,
        "distance_error_median": float(np.median(errors)) if errors else math.nan,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--states", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--trials", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--resolutions",
        type=str,
        default=None,
        help="comma-separated WxH per view, e.g. 128x192,256x384",
    )
    ap.add_argument(
        "--cost-only", action="store_true", help="skip part 2 (the LED detection range)"
    )
    args = ap.parse_args()
    resolutions = RESOLUTIONS
    if args.resolutions:
        resolutions = tuple(
            tuple(int(v) for v in r.split("x")) for r in args.resolutions.split(",")
        )
    distances = np.round(np.arange(0.5, 2.61, 0.25), 2)
    default = CameraConfig()
    print("cost per control step, 4 robots + 5 packs, ms (mean over states):")
    print(
        f"  {'camera (per view)':18s} {'render':>7s} {'segment':>8s} {'rendered':>9s} "
        f"{'geo observe':>12s} {'geo measure':>12s} {'geo nearest':>12s} {'physics':>8s}"
    )
    for w, h in resolutions:
        config = CameraConfig(view_width=w, height=h)
        c = cost(config, args.states, args.repeats, args.seed)
        mark = " (default)" if (w, h) == (default.view_width, default.height) else ""
        print(
            f"  {f'{w} x {h}{mark}':18s} {c['render']:7.2f} {c['segment']:8.2f} "
            f"{c['rendered_observe']:9.2f} {c['geometric_observe']:12.3f} "
            f"{c['geometric_measure']:12.3f} {c['geometric_nearest']:12.4f} "
            f"{c['physics_10_substeps']:8.3f}"
        )
    if args.cost_only:
        return
    print(
        f"\nLED detection rate by distance (m), rendered provider ({args.trials} random "
        "placements each; geometric in brackets):"
    )
    print(
        "  "
        + f"{'camera':18s}"
        + "".join(f"{d:>9.2f}" for d in distances)
        + "   reliable to   dist err med"
    )
    for w, h in resolutions:
        config = CameraConfig(view_width=w, height=h)
        r = led_detection(config, distances, args.trials, args.seed)
        cells = "".join(
            f"{100 * a:5.0f}({100 * b:3.0f})"[-9:].rjust(9)
            for a, b in zip(r["rates"]["rendered"], r["rates"]["geometric"], strict=True)
        )
        print(
            f"  {f'{w} x {h}':18s}{cells}   {r['reliable_range_m']:5.2f} m"
            f"   {100 * r['distance_error_median']:6.1f}%"
        )


if __name__ == "__main__":
    main()
