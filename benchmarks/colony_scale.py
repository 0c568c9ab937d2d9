"""Cost per robot of a control step as the colony grows, at the paper's density.

For N robots (default 4, 10, 25, 50, 100) the world is the paper's scaled up: a square field of
side 2.3 m x sqrt(N / 4), 5 N / 4 packs rounded half up (13 at 10 robots, 63 at 50), 25
agents per robot, geometric vision, embodied evolution with the shipped behaviours.
``--population 100`` keeps the paper's population instead, 100 / N agents per robot (and, with
one agent per robot, one slot of its whole life): the colony study's settings
(``benchmarks/colony_study.py``). For each N this prints the cost
per robot per control step of

* **physics**: the control step's bare ``mujoco.mj_step`` calls, replayed from the same
  states with the same wheel commands and docking welds as the loop integrated
  (:func:`benchmarks.evolution_throughput.measure`), and
* **EE loop**: the whole runner step (sensing, controllers, behaviours, survival mechanics,
  scheduler, physics),

each also as a ratio to the same cost at the first N. If the loop's per-robot cost stays flat
while the colony grows, nothing in it grows faster than the colony. Target: at 100 robots at
most 1.5x the cost per robot at 4.

Every N times the same number of robot-steps (N x control steps), after an untimed warm-up
that lets robots dock, mate and die as in a run. On a shared machine the load drifts between
sizes, so the sizes take turns: each of ``--rounds`` rounds times every size for
``--robot-steps`` robot-steps, and the table keeps each size's fastest round (of the physics
and of the loop).

Run: ``python -m benchmarks.colony_scale [--sizes 4,10,25,50,100] [--rounds 5]
[--robot-steps 4000] [--population 100]``
"""

from __future__ import annotations

import argparse
import json
import math

from benchmarks.evolution_throughput import choose_policies, measure
from cyber_rodent.constants import FIELD_SIZE
from cyber_rodent.world import WorldConfig
from evolution.config import EvolutionConfig
from evolution.runner import EvolutionRunner, RunConfig

#: Agents per robot (the paper's 100 agents on 4 robots).
AGENTS_PER_ROBOT = 25


def paper_density(n_robots: int) -> tuple[float, int]:
    """The field side (m) and pack count of ``n_robots`` at the paper's density (4 robots and
    5 packs in 2.3 m x 2.3 m): 2.3 m x sqrt(N / 4) and 5 N / 4 packs, rounded half up (10
    robots get 13 packs, 50 get 63)."""
    return FIELD_SIZE * math.sqrt(n_robots / 4), math.floor(5 * n_robots / 4 + 0.5)


def colony_config(
    n_robots: int, method: str = "ee", population_size: int | None = None
) -> RunConfig:
    """The paper's world scaled to ``n_robots`` at its density (:func:`paper_density`), with
    25 agents per robot, or ``population_size`` agents in all (it must divide by the robots)."""
    field_size, n_packs = paper_density(n_robots)
    population = AGENTS_PER_ROBOT * n_robots if population_size is None else population_size
    evolution = EvolutionConfig(population_size=population, n_robots=n_robots)
    if population == n_robots:  # one agent per robot: no time sharing
        evolution = EvolutionConfig(
            population_size=population,
            n_robots=n_robots,
            time_sharing_steps=evolution.lifetime_steps,
        )
    world = WorldConfig(field_size=field_size, n_robots=n_robots, n_packs=n_packs)
    return RunConfig(method=method, evolution=evolution, world=world)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="4,10,25,50,100", help="robot counts, comma-separated")
    parser.add_argument("--rounds", type=int, default=5, help="turns of every size")
    parser.add_argument(
        "--robot-steps", type=int, default=4_000,
        help="timed robot-steps per size and round (N robots x control steps)",
    )  # fmt: skip
    parser.add_argument("--warmup-robot-steps", type=int, default=8_000)
    parser.add_argument("--block", type=int, default=100, help="steps per interleaved block")
    parser.add_argument("--method", choices=("ee", "ce"), default="ee")
    parser.add_argument("--policies", choices=("auto", "trained", "reactive"), default="auto")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--population", type=int, default=None,
        help="agents in all at every size (default: 25 per robot; the colony study: 100)",
    )  # fmt: skip
    parser.add_argument("--json", help="also write the numbers to this JSON file")
    args = parser.parse_args(argv)

    policies, label = choose_policies(args.policies)
    sizes = [int(s) for s in args.sizes.split(",")]
    agents = "25 agents per robot" if args.population is None else f"{args.population} agents"
    print(f"behaviours: {label}; method {args.method.upper()}, geometric vision, {agents}")
    runners = {}
    for n in sizes:
        config = colony_config(n, args.method, args.population)
        runners[n] = EvolutionRunner(config, args.seed, policies)
        for _ in range(math.ceil(args.warmup_robot_steps / n)):
            runners[n].step()
    best: dict[int, dict[str, float]] = {}
    for turn in range(args.rounds):
        for n, runner in runners.items():
            steps = math.ceil(args.robot_steps / n)
            times = measure(runner, steps, min(args.block, steps))
            physics = 1e6 * times["raw_s"] / steps / n
            loop = 1e6 * times["runner_s"] / steps / n
            mine = best.setdefault(n, {"physics_us": math.inf, "loop_us": math.inf})
            mine["physics_us"] = min(mine["physics_us"], physics)
            mine["loop_us"] = min(mine["loop_us"], loop)
            mine["steps"] = steps
        print(f"  round {turn + 1} of {args.rounds} done", flush=True)
    rows = []
    for n, runner in runners.items():
        world = runner.config.world
        rows.append({"robots": n, "packs": world.n_packs, "field_m": world.field_size,
                     "agents_per_robot": runner.config.evolution.subpopulation_size,
                     **best[n]})  # fmt: skip
    base = rows[0]
    print(
        "\ncost per robot per control step (us, each size's fastest round), and as a ratio to "
        f"{base['robots']} robots:"
    )
    print(
        f"{'robots':>6} {'packs':>5} {'field m':>7} | {'physics':>8} {'ratio':>5} | "
        f"{'EE loop':>8} {'ratio':>5} | {'loop / physics':>14}"
    )
    for row in rows:
        row["physics_ratio"] = row["physics_us"] / base["physics_us"]
        row["loop_ratio"] = row["loop_us"] / base["loop_us"]
        print(
            f"{row['robots']:>6} {row['packs']:>5} {row['field_m']:>7.2f} | "
            f"{row['physics_us']:>8.1f} {row['physics_ratio']:>5.2f} | "
            f"{row['loop_us']:>8.1f} {row['loop_ratio']:>5.2f} | "
            f"{row['loop_us'] / row['physics_us']:>14.2f}"
        )
    result = {"policies": label, "method": args.method, "population": args.population,
              "rows": rows}  # fmt: skip
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(result, handle, indent=2)
    return result


if __name__ == "__main__":
    main()
