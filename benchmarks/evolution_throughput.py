"""Throughput of the evolution runner, as a ratio to the raw physics it steps.

For EE and CE on the paper's default world (4 robots x 25 agents, 5 packs, geometric vision),
this prints control steps per second of the whole loop (sensing, controller, behaviours,
survival mechanics, scheduler) and the cost of the *same physics* stepped raw: every block of
runner steps is replayed with bare ``mj_step`` calls (same model, same substeps, from the same
start state, with the wheel commands and docking welds each call of the runner integrated
from; the replay is checked to end in the runner's exact state), interleaved with the runner's
blocks so machine load affects both alike. Their ratio is the runner's overhead; the target is
at most 1.25x. The time the loop spends inside its own ``mj_step`` calls is printed too.

It also times the watchdog (tipped and stuck robots, docs/design.md §9.35) in place, as a share
of the whole loop (budget: 5 %), and the loop's own cost directly: each control step's
physics is timed and subtracted, leaving what the runner adds (blocks of steps, minimum and
median). It also projects the wall time of one 120-generation run on one core (120 generations x 25
agents x 400 steps = 1.2 M control steps if no agent dies; deaths lengthen EE runs, which need
every slot to complete each generation), and profiles the loop with cProfile: where time goes by
component, then the top functions.

Run: ``python -m benchmarks.evolution_throughput [--steps 4000] [--policies auto]
[--backend numba|numpy] [--controller paper|mlp|ctrnn]``
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import json
import pstats
import time
from collections.abc import Iterator
from typing import Any

import mujoco
import numpy as np

from behaviours import BehaviourPolicies
from evolution.config import EvolutionConfig
from evolution.runner import EvolutionRunner, RunConfig

#: (label, function name patterns) of the components reported by the profile; cumulative time
#: of the first matching function, "other" is the rest.
COMPONENTS = (
    ("physics (mj_step)", ("mj_step",)),
    ("sense, decide, act (one compiled call)", ("sense_decide_act_fused",)),
    ("sense, decide, act (stage by stage)", ("sense_decide_act_stepwise",)),
    ("survival mechanics (begin_step, end_step)", ("begin_step", "end_step")),
    ("scheduler (on_step)", ("on_step",)),
)


def choose_policies(name: str) -> tuple[BehaviourPolicies, str]:
    """The behaviours to benchmark with, and a label saying which they are."""
    if name in ("auto", "trained"):
        try:
            return BehaviourPolicies.load_default(), "trained (shipped values)"
        except FileNotFoundError:
            if name == "trained":
                raise
    return BehaviourPolicies.reactive(), "reactive (hand-written; trained values not installed)"


class _PhysicsRecorder:
    """Stands in for ``mujoco.mj_step`` during a block of runner steps: records what each call
    integrates from (wheel commands, docking welds on/off and their poses, which live in the
    model, the number of substeps and the model's disable flags: the runner evaluates its
    rangefinders only in a control step's last substep) for the replay, and times the call."""

    def __init__(self, real_step, block: int, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        self.real_step = real_step
        self.calls: list[tuple[np.ndarray, np.ndarray, np.ndarray, int, int]] = []
        self.seconds = 0.0

    def __call__(self, m: mujoco.MjModel, d: mujoco.MjData, nstep: int = 1) -> None:
        self.calls.append(
            (d.ctrl.copy(), d.eq_active.copy(), m.eq_data.copy(), nstep, m.opt.disableflags)
        )
        start = time.perf_counter()
        self.real_step(m, d, nstep=nstep)
        self.seconds += time.perf_counter() - start


def measure(runner: EvolutionRunner, steps: int, block: int) -> dict[str, float]:
    """Time ``steps`` runner steps, the physics inside them, and the same physics replayed raw.

    Returns:
        ``runner_s`` (whole loop), ``inside_s`` (its ``mj_step`` calls), ``raw_s`` (the same
        calls replayed alone from the same states), ``substeps``.
    """
    world = runner.world
    m, d = world.model, world.data
    substeps = runner.survival.n_substeps
    scratch = mujoco.MjData(m)
    real_step = mujoco.mj_step
    totals = {"runner_s": 0.0, "inside_s": 0.0, "raw_s": 0.0, "substeps": substeps}
    done = 0
    try:
        while done < steps:
            k = min(block, steps - done)
            recorder = _PhysicsRecorder(real_step, k, m, d)
            mujoco.mj_copyData(scratch, m, d)
            eq_now = m.eq_data.copy()
            flags_now = m.opt.disableflags
            mujoco.mj_step = recorder
            start = time.perf_counter()
            for _ in range(k):
                runner.step()
            totals["runner_s"] += time.perf_counter() - start
            mujoco.mj_step = real_step
            calls = recorder.calls
            if sum(c[3] for c in calls) != k * substeps:
                raise RuntimeError(f"expected {k * substeps} substeps, recorded {len(calls)} calls")
            totals["inside_s"] += recorder.seconds
            eq_after = m.eq_data.copy()
            m.eq_data[:] = eq_now
            opt = m.opt
            start = time.perf_counter()
            for ctrl, eq_active, eq_data, nstep, flags in calls:
                scratch.ctrl[:] = ctrl
                scratch.eq_active[:] = eq_active
                m.eq_data[:] = eq_data
                opt.disableflags = flags
                real_step(m, scratch, nstep=nstep)
            totals["raw_s"] += time.perf_counter() - start
            # The model is the runner's: leave it as the runner left it.
            m.eq_data[:] = eq_after
            opt.disableflags = flags_now
            if not np.array_equal(scratch.qpos, d.qpos):
                raise RuntimeError("the replay diverged from the runner's physics")
            done += k
    finally:
        mujoco.mj_step = real_step
    return totals


@contextlib.contextmanager
def timing(owner: Any, name: str) -> Iterator[list[float]]:
    """Time every call of ``owner.name`` in place while the block runs: yields a one-item list
    holding the seconds spent in it so far (the caller may reset it), then restores the
    method."""
    method = getattr(owner, name)
    clock = time.perf_counter
    spent = [0.0]

    def timed(*args: Any) -> Any:
        start = clock()
        result = method(*args)
        spent[0] += clock() - start
        return result

    setattr(owner, name, timed)
    try:
        yield spent
    finally:
        delattr(owner, name)  # the class's method again


def outside_physics(runner: EvolutionRunner, steps: int, blocks: int = 8) -> list[float]:
    """Seconds per control step spent outside the physics, for ``blocks`` blocks of ``steps``.

    The step's physics (``SurvivalWorld.advance_physics``: the control step's ``mj_step``
    calls) is timed and subtracted from the whole step: what is left is the runner's own cost
    (sensing, deciding, acting, the survival mechanics, the schedule), with no recorder in the
    loop. The spread between blocks shows the machine's noise; the minimum is the cleanest.
    """
    per_step = []
    with timing(runner.survival, "advance_physics") as physics:
        for _ in range(blocks):
            physics[0] = 0.0
            start = time.perf_counter()
            for _ in range(steps):
                runner.step()
            per_step.append((time.perf_counter() - start - physics[0]) / steps)
    return sorted(per_step)


def watchdog_cost(runner: EvolutionRunner, steps: int) -> tuple[float, float]:
    """Seconds per control step of the whole loop and of the watchdog in it (its
    ``observe``, which runs once per step, timed in place) over ``steps`` steps."""
    with timing(runner.watchdog, "observe") as spent:
        start = time.perf_counter()
        for _ in range(steps):
            runner.step()
        total = time.perf_counter() - start
    return total / steps, spent[0] / steps


def profile(runner: EvolutionRunner, steps: int, top: int) -> tuple[list[tuple[str, float]], str]:
    """cProfile ``steps`` runner steps: component shares (of total time) and the top table."""
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(steps):
        runner.step()
    profiler.disable()
    stats = pstats.Stats(profiler)
    total = stats.total_tt  # type: ignore[attr-defined]
    raw = stats.stats  # type: ignore[attr-defined]
    shares = []
    accounted = 0.0
    for label, names in COMPONENTS:
        seconds = 0.0
        for (_, _, func), (_, _, _, cumtime, _) in raw.items():
            if any(func == n or func.endswith(f"{n}>") or func == f"<built-in method {n}>"
                   or func.split(".")[-1] == n for n in names):  # fmt: skip
                seconds += cumtime
        shares.append((label, seconds / total))
        accounted += seconds
    shares.append(("other (event logging, agent switches, the loop)", 1 - accounted / total))
    buffer = io.StringIO()
    pstats.Stats(profiler, stream=buffer).sort_stats("tottime").print_stats(top)
    return shares, buffer.getvalue()


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=4000, help="timed control steps per method")
    parser.add_argument("--block", type=int, default=200, help="steps per interleaved block")
    parser.add_argument("--warmup", type=int, default=300, help="untimed steps first")
    parser.add_argument("--profile-steps", type=int, default=2000)
    parser.add_argument("--top", type=int, default=15, help="profile rows to print")
    parser.add_argument("--policies", choices=("auto", "trained", "reactive"), default="auto")
    parser.add_argument("--methods", default="ee,ce")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--backend", choices=("numba", "numpy"), default="numba",
        help="the runner's kernels: compiled, or their numpy references",
    )  # fmt: skip
    parser.add_argument(
        "--controller", default="paper",
        help="the evolved controller (evolution.controller; default the paper's)",
    )  # fmt: skip
    parser.add_argument("--json", help="also write the numbers to this JSON file")
    args = parser.parse_args(argv)

    policies, label = choose_policies(args.policies)
    print(f"behaviours: {label}")
    print(f"controller: {args.controller}")
    results: dict = {"policies": label, "controller": args.controller, "methods": {}}
    for method in args.methods.split(","):
        config = RunConfig(method=method, evolution=EvolutionConfig(controller=args.controller))
        runner = EvolutionRunner(config, args.seed, policies, backend=args.backend)
        for _ in range(args.warmup):
            runner.step()
        times = measure(runner, args.steps, args.block)
        runner_s, raw_s, substeps = times["runner_s"], times["raw_s"], times["substeps"]
        rate = args.steps / runner_s
        ratio = runner_s / raw_s
        evo = config.evolution
        paper_steps = 120 * evo.subpopulation_size * evo.lifetime_steps
        hours = paper_steps / rate / 3600
        print(f"\n== {method.upper()}: {evo.n_robots} robots x {evo.subpopulation_size} agents, "
              f"{config.world.n_packs} packs, {config.vision} vision, {substeps} substeps of "
              f"{runner.world.model.opt.timestep} s per control step")  # fmt: skip
        print(f"runner:       {rate:8.0f} control steps/s ({1e3 * runner_s / args.steps:.3f} ms)")
        print(f"raw mj_step:  {args.steps / raw_s:8.0f} control steps/s "
              f"({1e3 * raw_s / args.steps:.3f} ms)")  # fmt: skip
        print(f"ratio runner / raw physics: {ratio:.2f}x (target <= 1.25x)")
        inside = times["inside_s"]
        print(f"  (mj_step inside the loop: {1e3 * inside / args.steps:.3f} ms per control "
              f"step, {100 * inside / runner_s:.0f} % of the loop; ratio to it "
              f"{runner_s / inside:.2f}x)")  # fmt: skip
        print(f"projected 120-generation run ({paper_steps:,} control steps, no deaths): "
              f"{hours:.2f} h on one core")  # fmt: skip
        outside = outside_physics(runner, max(1, args.steps // 4))
        print(f"outside mj_step, per control step: min {1e6 * outside[0]:.1f} us, median "
              f"{1e6 * outside[len(outside) // 2]:.1f} us ({len(outside)} blocks of "
              f"{max(1, args.steps // 4)} steps)")  # fmt: skip
        loop_s, watch_s = watchdog_cost(runner, args.steps)
        print(f"watchdog (tipped and stuck robots): {1e6 * watch_s:.1f} us per control step, "
              f"{100 * watch_s / loop_s:.2f} % of the loop (budget 5 %)")  # fmt: skip
        shares, table = profile(runner, args.profile_steps, args.top)
        print(f"profile of {args.profile_steps} steps (cProfile inflates Python-side costs):")
        for name, share in shares:
            print(f"  {name:55s} {100 * share:5.1f} %")
        print(table)
        results["methods"][method] = {
            "steps_per_s": rate,
            "raw_physics_steps_per_s": args.steps / raw_s,
            "ratio_to_raw_physics": ratio,
            "ratio_to_mj_step_inside_loop": runner_s / times["inside_s"],
            "outside_physics_us_min": 1e6 * outside[0],
            "outside_physics_us_median": 1e6 * outside[len(outside) // 2],
            "watchdog_share_of_loop": watch_s / loop_s,
            "projected_hours_120_generations": hours,
            "profile_shares": dict(shares),
            "summary": runner.summary(),
        }
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=2, default=str)
    return results


if __name__ == "__main__":
    main()
