"""The performance table of the whole package: ``python -m benchmarks``.

One entry point for the question "how much science fits in a night on this machine". It runs
the focused benchmark modules of this package (reusing their timing code, not copying it) and
prints one table, also written as JSON (``--json``, default
``benchmarks/results/performance.json``):

* **raw physics**: ``mj_step`` calls per second and per control step for the default world
  (:mod:`benchmarks.physics_rate`);
* **paths**: control steps per second of the lean ``SurvivalWorld`` step (without and with
  geometric vision) and of the dm-control Survival task (geometric and rendered vision), each
  with its ratio to the raw ``mj_step`` calls made inside the same run
  (:mod:`benchmarks.task_throughput`);
* **full evolution loop**: control steps per second of a full EE and a full CE run
  (:class:`evolution.runner.EvolutionRunner`: sensing, controller, behaviours, survival
  mechanics, scheduler) with geometric and with rendered vision, and of EE in learning mode
  (every agent learning its behaviours in its life, from the shipped values and from zero),
  each with its ratio to the *same* physics replayed raw
  (:func:`benchmarks.evolution_throughput.measure`);
* **projections**: one 120-generation run on one core, and the paper's Fig. 6 experiment
  (20 seeds x EE and CE x 120 generations) with 1 and 2 worker processes;
* **peak memory** of this process (``ru_maxrss``) and of the worker processes, plus the peak
  of Python allocations of one full EE runner (``tracemalloc``);
* **scaling** with the number of robots (1, 2, 4, 8, 16) and of packs: raw physics and the
  lean step plus geometric sensing (what the loop pays per step besides its controllers);
* **workers**: aggregate throughput of full EE loops in 1 and 2 processes
  (``OMP_NUM_THREADS=1``; each process steps its own runner).

Numbers are wall-clock timings on a shared machine: they vary by some percent between runs; the
benchmark reports and asserts nothing. Run: ``python -m benchmarks [--quick]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import mujoco
import numpy as np

from benchmarks import evolution_throughput, physics_rate, task_throughput
from cyber_rodent.survival import SurvivalConfig, SurvivalWorld
from cyber_rodent.vision import GeometricVision
from cyber_rodent.world import World, WorldConfig

#: The paper's Fig. 6: runs per method, methods, generations.
FIG6_SEEDS, FIG6_METHODS, GENERATIONS = 20, 2, 120
DEFAULT_JSON = Path(__file__).parent / "results" / "performance.json"


def _quiet(fn, *args, **kwargs):
    """Call a benchmark module's function without its own printout (the table is ours)."""
    with contextlib.redirect_stdout(io.StringIO()):
        return fn(*args, **kwargs)


def _peak_rss_mb(who: int = resource.RUSAGE_SELF) -> float:
    return resource.getrusage(who).ru_maxrss / 1024.0  # Linux: kilobytes


def runner_rates(
    method: str, vision: str, steps: int, warmup: int, seed: int, learning_init: str | None = None
) -> dict:
    """Full evolution loop vs the same physics replayed raw (evolution_throughput.measure).

    With ``learning_init`` the run is in learning mode (every agent learns its behaviours
    during its life, from ``"zero"`` or ``"shipped"`` values).
    """
    from evolution.config import EvolutionConfig, LearningConfig
    from evolution.runner import EvolutionRunner, RunConfig

    policies, _ = evolution_throughput.choose_policies("auto")
    evolution = EvolutionConfig()
    if learning_init is not None:
        evolution = EvolutionConfig(learning=LearningConfig(enabled=True, init=learning_init))
    config = RunConfig(method=method, vision=vision, evolution=evolution)
    runner = EvolutionRunner(config, seed, policies)
    try:
        for _ in range(warmup):
            runner.step()
        block = max(1, min(200, steps))
        t = evolution_throughput.measure(runner, steps, block)
    finally:
        runner.close()
    return {
        "steps_per_s": steps / t["runner_s"],
        "ms_per_step": 1e3 * t["runner_s"] / steps,
        "raw_ms_per_step": 1e3 * t["raw_s"] / steps,
        "ratio_to_raw_physics": t["runner_s"] / t["raw_s"],
    }


def _scaling_world(n_robots: int, n_packs: int, steps: int, seed: int) -> dict:
    """Raw physics and lean step + nearest-target sensing for one world size."""
    try:
        world = World(WorldConfig(n_robots=n_robots, n_packs=n_packs), np.random.default_rng(seed))
    except Exception as error:  # noqa: BLE001 - reported in the table, not hidden
        return {"error": f"{type(error).__name__}: {str(error).splitlines()[0]}"}
    survival = SurvivalWorld(world, SurvivalConfig(energy_decay=0.0), np.random.default_rng(seed))
    seq = task_throughput.command_sequence(steps, n_robots, seed)
    m, d, n_sub = world.model, world.data, survival.n_substeps
    start_state = mujoco.MjData(m)
    mujoco.mj_copyData(start_state, m, d)
    vision = GeometricVision(world)
    clock = time.perf_counter
    physics = 0.0
    t0 = clock()
    for k in range(steps):
        survival.begin_step(seq["wheels"][k], seq["led"][k], seq["mate"][k], seq["recharge"][k])
        t1 = clock()
        survival.advance_physics()  # rangefinders in the last substep only
        physics += clock() - t1
        survival.end_step()
        vision.nearest_targets()
        world.range_readings()
    lean = clock() - t0
    # Raw physics alone from the same start (its own trajectory: same commands, no mechanics),
    # plain mj_step with the sensors evaluated in every substep: the naive baseline.
    mujoco.mj_copyData(d, m, start_state)
    ctrl, scale, wheels = d.ctrl, 1.0 / world.wheel_radius, seq["wheels"]
    t0 = clock()
    for k in range(steps):
        ctrl[0::2] = wheels[k, :, 0] * scale
        ctrl[1::2] = wheels[k, :, 1] * scale
        mujoco.mj_step(m, d, nstep=n_sub)
    raw = clock() - t0
    return {
        "raw_steps_per_s": steps / raw,
        "lean_vision_steps_per_s": steps / lean,
        "lean_vision_ratio_to_its_physics": lean / physics,
        "mean_contacts_end": int(d.ncon),
    }


def run_worker(method: str, seed: int, steps: int, warmup: int) -> float:
    """One worker process: step a full runner, return its wall seconds."""
    from evolution.runner import EvolutionRunner, RunConfig

    policies, _ = evolution_throughput.choose_policies("auto")
    with EvolutionRunner(RunConfig(method=method), seed, policies) as runner:
        for _ in range(warmup):
            runner.step()
        start = time.perf_counter()
        for _ in range(steps):
            runner.step()
        return time.perf_counter() - start


def worker_throughput(n_workers: int, steps: int, warmup: int) -> dict:
    """Aggregate control steps per second of ``n_workers`` processes, each a full EE runner.

    Plain subprocesses (one interpreter each, BLAS/OpenMP pinned to one thread), started
    together; each reports its own wall time for the same number of steps.
    """
    env = dict(os.environ, OMP_NUM_THREADS="1", LP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    code = (
        "import sys; from benchmarks.__main__ import run_worker; "
        "print(run_worker('ee', int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])))"
    )
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code, str(seed), str(steps), str(warmup)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        for seed in range(n_workers)
    ]
    seconds = []
    for proc in procs:
        out, _ = proc.communicate()
        if proc.returncode != 0:
            raise RuntimeError(f"worker failed with exit code {proc.returncode}")
        seconds.append(float(out.strip().splitlines()[-1]))
    # Every worker ran the same number of steps; the slowest sets the pace of the batch.
    return {
        "workers": n_workers,
        "steps_per_s_per_worker": [steps / s for s in seconds],
        "aggregate_steps_per_s": n_workers * steps / max(seconds),
        "peak_rss_children_mb": _peak_rss_mb(resource.RUSAGE_CHILDREN),
    }


def runner_python_peak_mb(seed: int, steps: int) -> float:
    """Peak of Python-level allocations (tracemalloc) of building and stepping one EE runner."""
    from evolution.runner import EvolutionRunner, RunConfig

    policies, _ = evolution_throughput.choose_policies("auto")
    tracemalloc.start()
    with EvolutionRunner(RunConfig(method="ee"), seed, policies) as runner:
        for _ in range(steps):
            runner.step()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short timings (a smoke run)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=str(DEFAULT_JSON), help="where to write the table")
    parser.add_argument("--no-rendered", action="store_true", help="skip rendered vision")
    parser.add_argument("--no-workers", action="store_true", help="skip the worker scaling")
    args = parser.parse_args(argv)
    quick = args.quick
    loop_steps, warmup = (300, 50) if quick else (3000, 300)
    rendered_steps = 100 if quick else 600
    path_steps, path_repeats = (300, 1) if quick else (1000, 2)
    scale_steps = 100 if quick else 500
    worker_steps = 300 if quick else 3000
    # Other processes on a shared machine slow every figure; the load is part of the record.
    results: dict = {"quick": quick, "seed": args.seed, "load_average_start": os.getloadavg()}

    # --- raw physics -----------------------------------------------------------------
    phys = _quiet(physics_rate.main, ["--seconds", "20" if quick else "120", "--seed", "0"])
    results["raw_physics"] = phys
    raw_ms = phys["ms_per_control_step"]

    # --- paths -----------------------------------------------------------------------
    path_args = ["--steps", str(path_steps), "--repeats", str(path_repeats)]
    if not args.no_rendered:
        path_args.append("--rendered")
    results["paths"] = _quiet(task_throughput.main, path_args)

    # --- full loop ---------------------------------------------------------------------
    loops = {}
    for method in ("ee", "ce"):
        loops[f"{method} geometric"] = runner_rates(method, "geometric", loop_steps, warmup, 0)
        if not args.no_rendered:
            loops[f"{method} rendered"] = runner_rates(
                method, "rendered", rendered_steps, min(warmup, 50), 0
            )
    for init in ("shipped", "zero"):
        loops[f"ee geometric, learning from {init}"] = runner_rates(
            "ee", "geometric", loop_steps, warmup, 0, learning_init=init
        )
    results["evolution_loop"] = loops
    steps_per_run = GENERATIONS * 25 * 400  # 25 agents x 400 steps per generation (no deaths)
    one_run_min = steps_per_run / loops["ee geometric"]["steps_per_s"] / 60
    results["projection"] = {
        "control_steps_per_run": steps_per_run,
        "ee_run_minutes_1core": one_run_min,
    }

    # --- memory ------------------------------------------------------------------------
    results["memory"] = {
        "peak_rss_mb_this_process": _peak_rss_mb(),
        "python_alloc_peak_mb_one_ee_runner": runner_python_peak_mb(0, 200 if quick else 1000),
    }

    # --- scaling -----------------------------------------------------------------------
    robots = {n: _scaling_world(n, 5, scale_steps, args.seed) for n in (1, 2, 4, 8, 16)}
    packs = {k: _scaling_world(4, k, scale_steps, args.seed) for k in (0, 5, 10, 15)}
    results["scaling"] = {"robots (5 packs)": robots, "packs (4 robots)": packs}

    # --- workers -----------------------------------------------------------------------
    if not args.no_workers:
        workers = {w: worker_throughput(w, worker_steps, 100) for w in (1, 2)}
        results["workers"] = workers
        agg = workers[2]["aggregate_steps_per_s"]
        runs = FIG6_SEEDS * FIG6_METHODS
        results["projection"]["fig6_hours_2_workers"] = runs * steps_per_run / agg / 3600
        results["projection"]["fig6_hours_1_worker"] = (
            runs * steps_per_run / workers[1]["aggregate_steps_per_s"] / 3600
        )
    results["memory"]["peak_rss_mb_this_process"] = _peak_rss_mb()
    results["load_average_end"] = os.getloadavg()

    print_table(results, raw_ms)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    with open(args.json, "w") as handle:
        json.dump(results, handle, indent=2, default=str)
    print(f"\nwritten: {args.json}")
    return results


def print_table(r: dict, raw_ms: float) -> None:
    """The human-readable table (every number is also in the JSON)."""
    start, end = r["load_average_start"], r.get("load_average_end", r["load_average_start"])
    print(f"machine load average (1 min) at start {start[0]:.2f}, at end {end[0]:.2f} "
          f"on {os.cpu_count()} cores")  # fmt: skip
    p = r["raw_physics"]
    print(f"== raw physics, default world ({p['substeps_per_control_step']} substeps of "
          f"{p['timestep_s']} s, {p['mean_contacts']:.1f} contacts on average)")  # fmt: skip
    print(f"  mj_step/s {p['mj_step_per_s']:10,.0f}   ({p['us_per_mj_step']:.1f} us)")
    print(f"  control steps/s {p['control_steps_per_s']:8,.0f}   ({raw_ms:.3f} ms/control step)")
    print("\n== paths (ratio: to the raw mj_step calls inside the same run)")
    print(f"  {'path':40s} {'steps/s':>8s} {'ms/step':>8s} {'x raw':>7s}")
    for name, v in r["paths"].items():
        print(f"  {name:40s} {v['steps_per_s']:8.0f} {v['ms_per_step']:8.3f} "
              f"{v['ratio_to_mj_step']:7.2f}")  # fmt: skip
    print("\n== full evolution loop (ratio: to the same physics replayed raw)")
    for name, v in r["evolution_loop"].items():
        print(f"  {name:40s} {v['steps_per_s']:8.0f} {v['ms_per_step']:8.3f} "
              f"{v['ratio_to_raw_physics']:7.2f}")  # fmt: skip
    loops = r["evolution_loop"]
    for init in ("shipped", "zero"):
        name = f"ee geometric, learning from {init}"
        if name in loops:
            rel = loops[name]["ms_per_step"] / loops["ee geometric"]["ms_per_step"]
            print(f"  learning mode ({init}) / fixed behaviours (EE): {rel:.2f}x per control step")
    if "ee rendered" in loops:
        rel = loops["ee rendered"]["ms_per_step"] / loops["ee geometric"]["ms_per_step"]
        print(f"  rendered / geometric (EE): {rel:.2f}x per control step")
    proj = r["projection"]
    print(f"\n== projections ({proj['control_steps_per_run']:,} control steps per run, "
          "no deaths)")  # fmt: skip
    print(f"  one 120-generation EE run, one core: {proj['ee_run_minutes_1core']:.1f} min")
    if "fig6_hours_2_workers" in proj:
        print(f"  Fig. 6 (20 seeds x EE, CE): {proj['fig6_hours_1_worker']:.1f} h with 1 worker, "
              f"{proj['fig6_hours_2_workers']:.1f} h with 2 workers")  # fmt: skip
    mem = r["memory"]
    print(f"\n== memory: peak RSS {mem['peak_rss_mb_this_process']:.0f} MB (this process), "
          "Python allocations of one EE runner "
          f"{mem['python_alloc_peak_mb_one_ee_runner']:.1f} MB")  # fmt: skip
    print("\n== scaling (lean step + nearest-target vision + range sensors)")
    print(f"  {'world':22s} {'raw st/s':>9s} {'lean+vis st/s':>14s} {'x its physics':>14s}")
    for axis, rows in r["scaling"].items():
        for key, v in rows.items():
            label = f"{key} {axis}"
            if "error" in v:
                print(f"  {label:22s} fails: {v['error']}")
                continue
            print(f"  {label:22s} {v['raw_steps_per_s']:9.0f} {v['lean_vision_steps_per_s']:14.0f} "
                  f"{v['lean_vision_ratio_to_its_physics']:14.2f}")  # fmt: skip
    if "workers" in r:
        print("\n== worker processes (full EE loops, OMP_NUM_THREADS=1)")
        for w, v in r["workers"].items():
            per = ", ".join(f"{x:.0f}" for x in v["steps_per_s_per_worker"])
            print(f"  {w} worker(s): {v['aggregate_steps_per_s']:.0f} steps/s aggregate "
                  f"(per worker {per}); children peak RSS "
                  f"{v['peak_rss_children_mb']:.0f} MB")  # fmt: skip


if __name__ == "__main__":
    main()
