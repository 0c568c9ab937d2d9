"""Cost per robot of a control step in many arenas against one large field.

A colony study can add robots two ways: many copies of the paper's arena (``world.arenas``,
each 2.3 m x 2.3 m with its own walls, 4 robots and 5 packs; docs/design.md §9.33), or one
large field at the paper's density. This prints the cost per robot per control step of

* **1 arena x 4 robots**: the paper's world (2.3 m, 5 packs), the baseline;
* **25 arenas x 4 robots**: 100 robots and 125 packs in 25 arenas of 2.3 m;
* **1 field x 100 robots**: 100 robots and 125 packs in one 11.5 m field,

each as the whole evolution step (geometric vision, controllers, the shipped behaviours, the
survival world's mechanics, the scheduler and the physics: embodied evolution with 25 agents
per robot) and as its physics alone (the control step's bare ``mujoco.mj_step`` calls,
replayed from the same states: :func:`benchmarks.evolution_throughput.measure`), with the
ratio of each to the paper's world. Target: 25 arenas cost each robot at most 1.5x what the
paper's world does. In the world of arenas the survival world reads the rangefinders after the
physics, through a grid of the geoms near each ray (``cyber_rodent.vision.kernels.ranges``),
rather than in MuJoCo's sensor stage, so its physics column leaves them out and its loop
column holds them; in the other two worlds ``mj_step`` evaluates them in the last substep.

The approach is :mod:`benchmarks.colony_scale`'s: every world times the same number of
robot-steps after an untimed warm-up that lets robots dock, mate and die as in a run; the
worlds take turns for ``--rounds`` rounds (the load of a shared machine drifts), and the table
keeps each world's fastest round.

Run: ``python -m benchmarks.arena_cost [--rounds 5] [--robot-steps 8000]``
"""

from __future__ import annotations

import argparse
import json
import math

from benchmarks.colony_scale import AGENTS_PER_ROBOT
from benchmarks.evolution_throughput import choose_policies, measure
from cyber_rodent.world import WorldConfig
from evolution.config import EvolutionConfig
from evolution.runner import EvolutionRunner, RunConfig

#: The worlds compared: label, then the world's settings.
WORLDS: tuple[tuple[str, WorldConfig], ...] = (
    ("1 arena x 4 robots", WorldConfig()),
    ("25 arenas x 4 robots", WorldConfig(n_robots=100, n_packs=125, arenas=25)),
    ("1 field x 100 robots", WorldConfig(n_robots=100, n_packs=125, field_size=11.5)),
)


def run_config(world: WorldConfig, method: str = "ee") -> RunConfig:
    """An evolution run in ``world`` with 25 agents per robot (the camera's range is each
    arena's diagonal: ``RunConfig``'s default for the field)."""
    evolution = EvolutionConfig(
        population_size=AGENTS_PER_ROBOT * world.n_robots, n_robots=world.n_robots
    )
    return RunConfig(method=method, evolution=evolution, world=world)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="turns of every world")
    parser.add_argument(
        "--robot-steps", type=int, default=8_000,
        help="timed robot-steps per world and round (robots x control steps)",
    )  # fmt: skip
    parser.add_argument("--warmup-robot-steps", type=int, default=8_000)
    parser.add_argument("--block", type=int, default=100, help="steps per interleaved block")
    parser.add_argument("--method", choices=("ee", "ce"), default="ee")
    parser.add_argument("--policies", choices=("auto", "trained", "reactive"), default="auto")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the numbers to this JSON file")
    args = parser.parse_args(argv)

    policies, label = choose_policies(args.policies)
    print(f"behaviours: {label}; method {args.method.upper()}, geometric vision, "
          f"{AGENTS_PER_ROBOT} agents per robot")  # fmt: skip
    runners = {}
    for name, world in WORLDS:
        runners[name] = EvolutionRunner(run_config(world, args.method), args.seed, policies)
        for _ in range(math.ceil(args.warmup_robot_steps / world.n_robots)):
            runners[name].step()
    best: dict[str, dict[str, float]] = {}
    for turn in range(args.rounds):
        for name, runner in runners.items():
            n = runner.config.world.n_robots
            steps = math.ceil(args.robot_steps / n)
            times = measure(runner, steps, min(args.block, steps))
            mine = best.setdefault(name, {"physics_us": math.inf, "loop_us": math.inf})
            mine["physics_us"] = min(mine["physics_us"], 1e6 * times["raw_s"] / steps / n)
            mine["loop_us"] = min(mine["loop_us"], 1e6 * times["runner_s"] / steps / n)
        print(f"  round {turn + 1} of {args.rounds} done", flush=True)
    rows = []
    for name, world in WORLDS:
        rows.append({"world": name, "arenas": world.arenas, "robots": world.n_robots,
                     "packs": world.n_packs, "field_m": world.field_size,
                     **best[name]})  # fmt: skip
    base = rows[0]
    print(
        "\ncost per robot per control step (us, each world's fastest round), and as a ratio to "
        f"{base['world']}:"
    )
    print(
        f"{'world':<22} {'packs':>5} {'field m':>7} | {'physics':>8} {'ratio':>5} | "
        f"{'EE loop':>8} {'ratio':>5}"
    )
    for row in rows:
        row["physics_ratio"] = row["physics_us"] / base["physics_us"]
        row["loop_ratio"] = row["loop_us"] / base["loop_us"]
        print(
            f"{row['world']:<22} {row['packs']:>5} {row['field_m']:>7.2f} | "
            f"{row['physics_us']:>8.1f} {row['physics_ratio']:>5.2f} | "
            f"{row['loop_us']:>8.1f} {row['loop_ratio']:>5.2f}"
        )
    result = {"policies": label, "method": args.method, "rows": rows}
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(result, handle, indent=2)
    return result


if __name__ == "__main__":
    main()
