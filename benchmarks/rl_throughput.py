"""Environment steps per second of the Gymnasium environments, single and vectorised.

For each task (``CyberRodent/Forage-v0``, ``Mate-v0``, ``Search-v0``, ``Survival-v0``, the
defaults of ``gymnasium.make``: discrete actions, sparse reward, normalised observation,
geometric vision) this times uniformly random actions (seeded) through:

* ``single``: one environment, ``env.step`` in a loop, ``env.reset()`` at an episode's end;
* ``sync ×N``: ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="sync")``, one process;
* ``async ×N``: ``gymnasium.make_vec(id, num_envs=N, vectorization_mode="async")``, N worker
  processes (``--context``, default ``forkserver``: safe with MuJoCo and OpenGL);
* ``SB3 subproc ×N``: Stable-Baselines3's ``make_vec_env("cyber_rodent:" + id, n_envs=N,
  vec_env_cls=SubprocVecEnv)`` (the library's default start method, forkserver), if
  Stable-Baselines3 is installed.

``--before-after`` times instead, for each task, one environment on the vision path the
environments took before they read the nearest targets from the lazy pass (the geometric
vision's full pass, ``observe()``, and the raw observation, the old default) against the
default path, alternating blocks of ``--steps`` steps in one process (``--repeats`` each; best
and median), so that a change of the machine's load hits both alike.

The vector environments reset finished episodes themselves (Gymnasium's next-step autoreset,
SB3's at once). A vectorised figure counts the steps of all N environments (N per call). Each
figure is the median of ``--repeats`` timings of ``--steps`` calls after ``--warmup`` calls;
worker start-up is not timed. Nothing here is asserted: the machine's load moves every figure
(compare figures of one run).

Run: ``python -m benchmarks.rl_throughput [--steps 1000] [--num-envs 2] [--tasks forage search]``
or ``python -m benchmarks.rl_throughput --before-after --steps 600 --repeats 8``
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

import cyber_rodent  # noqa: F401  (registers the CyberRodent/* ids)

TASKS = ("forage", "mate", "search", "survival")
MODES = ("single", "sync", "async", "sb3")


def env_id(task: str) -> str:
    """The Gymnasium id of ``task``."""
    return f"CyberRodent/{task.title()}-v0"


def _timed(step: Callable[[], None], steps: int, warmup: int, repeats: int) -> float:
    """Median seconds of ``steps`` calls of ``step`` over ``repeats`` timings."""
    for _ in range(warmup):
        step()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(steps):
            step()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def single_rate(task: str, steps: int, warmup: int, repeats: int) -> float:
    """Steps/s of one environment."""
    env = gym.make(env_id(task))
    env.reset(seed=0)
    env.action_space.seed(0)

    def step() -> None:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()

    seconds = _timed(step, steps, warmup, repeats)
    env.close()
    return steps / seconds


def vector_rate(
    make: Callable[[], Any], n: int, steps: int, warmup: int, repeats: int, gymnasium: bool
) -> float:
    """Steps/s (all environments) of a vector environment built by ``make``."""
    envs = make()
    if gymnasium:
        envs.reset(seed=0)
    else:
        envs.seed(0)
        envs.reset()
    space = envs.action_space
    space.seed(0)

    def step() -> None:
        if gymnasium:
            envs.step(space.sample())
        else:  # SB3: one action of the single space per environment
            envs.step(np.stack([space.sample() for _ in range(n)]))

    seconds = _timed(step, steps, warmup, repeats)
    envs.close()
    return n * steps / seconds


def rates(
    task: str, modes: Sequence[str], n: int, steps: int, warmup: int, repeats: int, context: str
) -> dict[str, float]:
    """Steps/s of ``task`` in each mode."""
    out: dict[str, float] = {}
    for mode in modes:
        if mode == "single":
            out[mode] = single_rate(task, steps, warmup, repeats)
        elif mode in ("sync", "async"):
            kwargs = {"vector_kwargs": {"context": context}} if mode == "async" else {}

            def make(mode: str = mode, kwargs: dict[str, Any] = kwargs) -> Any:
                return gym.make_vec(
                    env_id(task), num_envs=n, vectorization_mode=mode, **kwargs
                )

            out[mode] = vector_rate(make, n, steps, warmup, repeats, gymnasium=True)
        else:
            try:
                from stable_baselines3.common.env_util import make_vec_env
                from stable_baselines3.common.vec_env import SubprocVecEnv
            except ImportError:
                continue

            def make_sb3() -> Any:
                return make_vec_env(
                    "cyber_rodent:" + env_id(task), n_envs=n, vec_env_cls=SubprocVecEnv
                )

            out[mode] = vector_rate(make_sb3, n, steps, warmup, repeats, gymnasium=False)
    return out


def full_pass_frame(vision: Any) -> Any:
    """What the environments read before: the vision's full pass (every target, blob lists)."""
    return vision.observe()


def before_after(task: str, steps: int, warmup: int, repeats: int) -> dict[str, list[float]]:
    """Steps/s of one environment on the old vision path ("before": full pass, raw
    observation) and the default one ("after"), in alternating blocks."""
    import cyber_rodent.gym_env as gym_env

    envs = {
        "before": gym.make(env_id(task), observation="raw"),
        "after": gym.make(env_id(task)),
    }
    lazy = gym_env.nearest_frame
    out: dict[str, list[float]] = {"before": [], "after": []}
    try:
        for env in envs.values():
            env.reset(seed=0)
            env.action_space.seed(0)
        for _ in range(repeats):
            for name, env in envs.items():
                gym_env.nearest_frame = full_pass_frame if name == "before" else lazy

                def step(env: Any = env) -> None:
                    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
                    if terminated or truncated:
                        env.reset()

                out[name].append(steps / _timed(step, steps, warmup, 1))
    finally:
        gym_env.nearest_frame = lazy
        for env in envs.values():
            env.close()
    return out


def column_title(mode: str, n: int) -> str:
    return {"single": "single", "sync": f"sync ×{n}", "async": f"async ×{n}",
            "sb3": f"SB3 subproc ×{n}"}[mode]  # fmt: skip


def table(results: dict[str, dict[str, float]], modes: Sequence[str], n: int) -> str:
    """The figures as a Markdown table (steps/s; each vectorised one with its gain)."""
    shown = [m for m in modes if any(m in r for r in results.values())]
    lines = [
        "| task | " + " | ".join(column_title(m, n) for m in shown) + " |",
        "|---|" + "---|" * len(shown),
    ]
    for task, r in results.items():
        single = r.get("single")
        cells = []
        for m in shown:
            if m not in r:
                cells.append("—")
            elif m == "single" or single is None:
                cells.append(f"{r[m]:,.0f}")
            else:
                cells.append(f"{r[m]:,.0f} ({r[m] / single:.2f}×)")
        lines.append(f"| {env_id(task)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> dict[str, dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", choices=TASKS, default=list(TASKS))
    parser.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES))
    parser.add_argument("--num-envs", type=int, default=2, help="environments of a vector")
    parser.add_argument("--steps", type=int, default=1000, help="timed calls per repeat")
    parser.add_argument("--warmup", type=int, default=100, help="untimed calls first")
    parser.add_argument("--repeats", type=int, default=3, help="timings; the median is shown")
    parser.add_argument(
        "--context", default="forkserver", choices=("fork", "forkserver", "spawn"),
        help="multiprocessing start method of the async vector environment",
    )  # fmt: skip
    parser.add_argument(
        "--before-after", action="store_true",
        help="time the full vision pass (before) against the lazy one (after), single envs",
    )  # fmt: skip
    args = parser.parse_args(argv)
    for name in ("num_envs", "steps", "repeats"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.warmup < 0:
        parser.error(f"--warmup must be >= 0, got {args.warmup}")
    print(
        f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
        f"gymnasium {gym.__version__}; {args.steps} calls × {args.repeats} repeats, "
        f"{args.num_envs} environments per vector",
        flush=True,
    )
    results: dict[str, dict[str, float]] = {}
    if args.before_after:
        lines = [
            "| task | before (full vision pass, raw) | after (nearest targets, normalised) "
            "| speed-up |",
            "|---|---|---|---|",
        ]
        for task in args.tasks:
            r = before_after(task, args.steps, args.warmup, args.repeats)
            best = {k: max(v) for k, v in r.items()}
            median = {k: statistics.median(v) for k, v in r.items()}
            results[task] = {"before": median["before"], "after": median["after"]}
            lines.append(
                f"| {task.title()} | {best['before']:,.0f} ({median['before']:,.0f}) | "
                f"{best['after']:,.0f} ({median['after']:,.0f}) | "
                f"{best['after'] / best['before']:.2f}× "
                f"({median['after'] / median['before']:.2f}×) |"
            )
            print(lines[-1], flush=True)
        print("\nsteps/s, best of the repeats (median in brackets)\n")
        print("\n".join(lines))
        return results
    for task in args.tasks:
        results[task] = rates(
            task, args.modes, args.num_envs, args.steps, args.warmup, args.repeats, args.context
        )
        figures = ", ".join(f"{m} {v:,.0f}" for m, v in results[task].items())
        print(f"{env_id(task)}: {figures} steps/s", flush=True)
    print()
    print(table(results, args.modes, args.num_envs))
    return results


if __name__ == "__main__":
    main()
