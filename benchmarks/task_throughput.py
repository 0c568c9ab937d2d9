"""Control steps per second of the Survival world: raw physics, lean path, dm-control path.

The evolution runner steps :class:`~cyber_rodent.survival.SurvivalWorld` 1.2 million times per
run, so its overhead over the physics matters; the dm-control tasks pay for observations (vision,
sensor copies, spec checks) on every step. This script times, on the default Survival world
(4 robots, 5 packs) and one shared sequence of commands:

* ``raw mj_step``: only the physics: wheel speeds written into ``ctrl``, then ``mj_step`` for
  the control step's substeps (24 x 1/120 s by default);
* ``lean``: ``SurvivalWorld.step`` (validation, energy, docking and mating checks, reflexes,
  LEDs), no observations; its physics is ``SurvivalWorld.advance_physics`` (rangefinders
  evaluated in the last substep only, bit-identical results), so it can beat raw ``mj_step``;
* ``lean + geometric vision``: the lean step plus one ``GeometricVision.observe()``, what the
  evolution loop needs per step on top of the mechanics;
* ``dm-control``: ``env.step(action)`` of ``tasks.load("survival")`` (geometric vision, dict
  observations, action validation).

Each path's figure comes with its ratio to raw ``mj_step`` cost for the same substeps, measured
*inside the same run* (the ``mj_step`` calls of that path timed on their own), so the ratio is
independent of how many contacts the path's trajectory happened to produce. The raw loop's own
rate is printed for reference. Every path is timed ``--repeats`` times; the median is reported.
Energy decay is set to 0 so that no robot dies during the timing (a dead robot stands still,
which would make later steps cheaper than a real run's, where a new agent takes over at once).

Run: ``python -m benchmarks.task_throughput [--steps 2000] [--repeats 3] [--rendered]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import mujoco
import numpy as np

from cyber_rodent import commands, tasks
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.vision import make_provider
from cyber_rodent.world import World, WorldConfig

RULES = SurvivalConfig(energy_decay=0.0)


def command_sequence(n_steps: int, n_robots: int, seed: int) -> dict[str, np.ndarray]:
    """Behaviour-like commands: a random discrete command per robot, held 1-10 steps."""
    rng = np.random.default_rng(seed)
    idx = np.empty((n_steps, n_robots), dtype=np.int64)
    for i in range(n_robots):
        k = 0
        while k < n_steps:
            hold = int(rng.integers(1, 11))
            idx[k : k + hold, i] = rng.integers(commands.N_COMMANDS)
            k += hold
    return {
        "wheels": commands.wheel_speeds(idx),  # (steps, n, 2)
        "led": rng.random((n_steps, n_robots)) < 0.5,
        "mate": rng.random((n_steps, n_robots)) < 0.5,
        "recharge": rng.random((n_steps, n_robots)) < 0.9,
    }


def fresh_world(seed: int) -> SurvivalWorld:
    return SurvivalWorld(World(WorldConfig()), RULES, np.random.default_rng(seed))


def time_raw(seq: dict, seed: int) -> tuple[float, float]:
    """(total s, mj_step s): physics only."""
    sw = fresh_world(seed)
    m, d, n_sub = sw.world.model, sw.world.data, sw.n_substeps
    ctrl = d.ctrl
    scale = 1.0 / sw.world.wheel_radius
    wheels = seq["wheels"]
    start = time.perf_counter()
    for k in range(len(wheels)):
        ctrl[0::2] = wheels[k, :, 0] * scale
        ctrl[1::2] = wheels[k, :, 1] * scale
        mujoco.mj_step(m, d, nstep=n_sub)
    total = time.perf_counter() - start
    return total, total


def time_lean(seq: dict, seed: int, vision: bool) -> tuple[float, float]:
    """(total s, mj_step s) of SurvivalWorld.step (the same work, physics timed apart)."""
    sw = fresh_world(seed)
    provider = make_provider("geometric", sw.world) if vision else None
    wheels, led, mate, rech = seq["wheels"], seq["led"], seq["mate"], seq["recharge"]
    clock = time.perf_counter
    physics = 0.0
    start = clock()
    for k in range(len(wheels)):
        # SurvivalWorld.step(...) = begin_step + advance_physics + end_step; split to time it.
        sw.begin_step(wheels[k], led[k], mate[k], rech[k])
        t0 = clock()
        sw.advance_physics()  # the substeps, rangefinders evaluated in the last one only
        physics += clock() - t0
        sw.end_step()
        if provider is not None:
            provider.observe()
    return clock() - start, physics


def time_dm_control(seq: dict, seed: int, vision: str) -> tuple[float, float]:
    """(total s, mj_step s) of env.step on the Survival task."""
    env = tasks.load("survival", seed=seed, survival=RULES, episode_steps=10**9, vision=vision)
    env.reset()
    physics_obj = env.physics
    inner_step = physics_obj.step
    spent = [0.0]
    clock = time.perf_counter

    def timed_step(nstep: int = 1) -> None:
        t0 = clock()
        inner_step(nstep)
        spent[0] += clock() - t0

    physics_obj.step = timed_step  # instance override: time the physics inside env.step
    n = len(seq["wheels"])
    actions = [
        {
            "wheels": seq["wheels"][k],
            "led": seq["led"][k].astype(float),
            "mate": seq["mate"][k].astype(float),
            "recharge": seq["recharge"][k].astype(float),
        }
        for k in range(n)
    ]
    start = clock()
    for k in range(n):
        env.step(actions[k])
    total = clock() - start
    physics_obj.step = inner_step
    return total, spent[0]


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="control steps per timing")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--rendered", action="store_true", help="also time dm-control with rendered vision"
    )
    args = parser.parse_args(argv)
    if args.steps < 1 or args.repeats < 1:
        parser.error("--steps and --repeats must be >= 1")

    seq = command_sequence(args.steps, WorldConfig().n_robots, args.seed)
    paths = {
        "raw mj_step": lambda: time_raw(seq, args.seed),
        "lean (SurvivalWorld.step)": lambda: time_lean(seq, args.seed, vision=False),
        "lean + geometric vision": lambda: time_lean(seq, args.seed, vision=True),
        "dm-control Survival (geometric)": lambda: time_dm_control(seq, args.seed, "geometric"),
    }
    if args.rendered:
        paths["dm-control Survival (rendered)"] = lambda: time_dm_control(
            seq, args.seed, "rendered"
        )

    results = {}
    for name, run in paths.items():
        run()  # warm-up (allocations, caches, GL context)
        totals, ratios = [], []
        for _ in range(args.repeats):
            total, physics = run()
            totals.append(total)
            ratios.append(total / physics)
        total = statistics.median(totals)
        results[name] = {
            "steps_per_s": args.steps / total,
            "ms_per_step": 1e3 * total / args.steps,
            "ratio_to_mj_step": statistics.median(ratios),
        }

    sw = fresh_world(args.seed)
    print(
        f"Survival world: {sw.n_robots} robots, {sw.n_packs} packs, {sw.n_substeps} substeps of "
        f"{sw.world.model.opt.timestep * 1e3:g} ms per control step; {args.steps} steps, "
        f"median of {args.repeats}"
    )
    print(f"{'path':34s} {'steps/s':>9s} {'ms/step':>8s} {'x raw mj_step':>14s}")
    for name, r in results.items():
        print(
            f"{name:34s} {r['steps_per_s']:9.0f} {r['ms_per_step']:8.3f} "
            f"{r['ratio_to_mj_step']:14.3f}"
        )
    return results


if __name__ == "__main__":
    main()
