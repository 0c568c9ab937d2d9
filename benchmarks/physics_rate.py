"""Raw physics throughput of the default world, and what its contacts are.

Prints ``mj_step`` calls per second for the default 4-robot / 5-pack world while the robots drive
randomly (so there are wall hits and robot-robot contacts), the equivalent control steps per
second (24 substeps of 1/120 s per 0.2 s control step by default), and the mean number of
contacts split by kind. Every contact must be of an expected kind: packs and walls are static,
so they never touch the floor, and chassis never touch the floor.

Run: ``python -m benchmarks.physics_rate [--seconds 60]``
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import mujoco
import numpy as np

from cyber_rodent import constants as C
from cyber_rodent.survival import SurvivalConfig
from cyber_rodent.world import World, WorldConfig

#: The default control step (``survival.control_dt``).
CONTROL_DT = SurvivalConfig().control_dt


def classify(world: World) -> Counter:
    """Kinds of the current contacts, e.g. ``floor-wheel``, ``robot-robot``."""
    m = world.model
    kinds: Counter = Counter()
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, C.FLOOR_GEOM)
    walls = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n) for n in C.WALL_GEOMS}
    packs = set(world.pack_geom) | set(world.electrode_geom)
    for g1, g2 in world.data.contact.geom:
        r1, r2 = world.geom_robot[g1], world.geom_robot[g2]
        names = sorted(
            "floor"
            if g == floor
            else "wall"
            if g in walls
            else "pack"
            if g in packs
            else (
                "wheel"
                if "wheel" in (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "")
                else "caster"
                if "caster" in (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "")
                else "robot"
            )
            if r >= 0
            else "other"
            for g, r in ((g1, r1), (g2, r2))
        )
        kinds["-".join(names)] += 1
    return kinds


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds to time")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    world = World(WorldConfig(), np.random.default_rng(args.seed))
    rng = np.random.default_rng(args.seed + 1)
    dt = world.model.opt.timestep
    substeps = round(CONTROL_DT / dt)
    n_control = round(args.seconds / CONTROL_DT)
    commands = rng.uniform(-1.0, 1.3, size=(n_control, 2, world.config.n_robots))

    # Timed loop: raw physics only (commands written straight into ctrl, one slice).
    ctrl = world.data.ctrl
    scale = 1.0 / world.wheel_radius
    start = time.perf_counter()
    for k in range(n_control):
        ctrl[0::2] = commands[k, 0] * scale
        ctrl[1::2] = commands[k, 1] * scale
        mujoco.mj_step(world.model, world.data, nstep=substeps)
    elapsed = time.perf_counter() - start
    steps_per_s = n_control * substeps / elapsed

    # Untimed pass: what the contacts are.
    world.reset(np.random.default_rng(args.seed))
    kinds: Counter = Counter()
    ncon = []
    for k in range(n_control):
        world.set_wheel_speeds(commands[k, 0], commands[k, 1])
        world.step(substeps)
        ncon.append(world.data.ncon)
        kinds.update(classify(world))

    result = {
        "timestep_s": dt,
        "substeps_per_control_step": substeps,
        "mj_step_per_s": steps_per_s,
        "us_per_mj_step": 1e6 / steps_per_s,
        "control_steps_per_s": steps_per_s / substeps,
        "ms_per_control_step": 1e3 * substeps / steps_per_s,
        "realtime_factor": steps_per_s * dt,
        "mean_contacts": float(np.mean(ncon)),
        "contacts_by_kind_per_step": {k: v / n_control for k, v in sorted(kinds.items())},
    }
    print(
        f"default world: {world.config.n_robots} robots, {world.config.n_packs} packs, "
        f"dt = {dt} s, {substeps} substeps per control step"
    )
    print(f"  mj_step/s            {steps_per_s:12,.0f}   ({1e6 / steps_per_s:.1f} us/step)")
    print(
        f"  control steps/s      {steps_per_s / substeps:12,.0f}   "
        f"({1e3 * substeps / steps_per_s:.3f} ms/control step)"
    )
    print(f"  real-time factor     {steps_per_s * dt:12,.0f}x")
    print(f"  mean contacts        {np.mean(ncon):12.2f}")
    for kind, count in sorted(kinds.items()):
        print(f"    {kind:20s} {count / n_control:8.2f} per step")
    allowed = {"caster-floor", "floor-wheel", "robot-robot", "robot-wall", "pack-robot"}
    unexpected = set(kinds) - allowed
    print("  spurious contacts:  ", "none" if not unexpected else sorted(unexpected))
    return result


if __name__ == "__main__":
    main()
