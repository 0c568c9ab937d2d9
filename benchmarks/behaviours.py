"""Quality of the learned behaviours in the physics world, next to random and reactive policies.

Usage::

    .venv/bin/python -m benchmarks.behaviours                 # 200 episodes per policy
    .venv/bin/python -m benchmarks.behaviours --episodes 50 --skip-training
    .venv/bin/python -m benchmarks.behaviours --skip-training \
        --set survival.control_dt=0.2 --values runs/behaviours_dt0.2

For each behaviour it runs the same seeded episodes (identical start placements) with three
policies: the greedy policy of the shipped action values (``BehaviourPolicies.load_default``, or
those of ``--values DIR``), uniformly random wheel commands, and the hand-written reactive
baseline. ``--set survival.KEY=VALUE`` (repeatable) runs every episode and training under an
evolution run's survival rules (:func:`behaviours.episodes.episode_rules`), e.g. a 0.2 s control
step; the step counts below are then control steps of that length. It prints:

* **Forage**: share of episodes (starting with a pack in view) that dock within 100 control
  steps (target ≥ 90 %), and the median steps to dock;
* **Mate**: share of episodes (two Mate-running robots in view of each other) with an IR
  exchange within 100 steps (target ≥ 70 %);
* **Search**: obstacle contacts per 1,000 steps and the area covered per 100-step episode;
* the training budget of Forage from scratch: episodes and wall time until the greedy policy
  docks in ≥ 90 % of 100 evaluation episodes (checked every ``--check-every`` episodes);
* reproducibility: two short training runs with one seed give identical values (checksums);
* the cost of ``BehaviourPolicies.commands`` for 4 robots (the evolution runner's per-step call).

Results go to ``benchmarks/results/behaviours.json`` (not committed), or ``--out FILE``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

# Run as a script (``python benchmarks/behaviours.py``), this file's directory comes first on
# sys.path and its name would shadow the ``behaviours`` package: drop that entry.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

import numpy as np  # noqa: E402

from behaviours import FORAGE, MATE, SEARCH, BehaviourPolicies, behaviour_inputs  # noqa: E402
from behaviours.episodes import BehaviourEpisode  # noqa: E402
from behaviours.evaluation import MEASURES, evaluate  # noqa: E402
from behaviours.greedy_policy import GreedyPolicy  # noqa: E402
from behaviours.inputs import BEHAVIOUR_NAMES  # noqa: E402
from behaviours.training import survival_changes, train  # noqa: E402
from cyber_rodent.survival import SurvivalConfig  # noqa: E402
from cyber_rodent.vision import make_provider  # noqa: E402
from cyber_rodent.world import World, WorldConfig  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "behaviours.json"


def _fmt(x: float, pct: bool = False) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return f"{100 * x:.1f} %" if pct else f"{x:.3g}"


def survival_rules(items: list[str]) -> SurvivalConfig | None:
    """The survival rules of ``--set survival.KEY=VALUE`` items (None: none given).

    Raises:
        ValueError: a malformed item, an unknown key, a key outside ``survival.`` or a value
            its field refuses (one line).
    """
    if not items:
        return None
    from evolution.runner import RunConfig, settings

    values = settings.parse_set(items)
    for item in items:
        key = settings.canonical_key(item.partition("=")[0])
        if not key.startswith("survival."):
            raise ValueError(f"this benchmark takes survival.* settings, got {key}")
    return settings.apply(RunConfig(), values).survival


def compare_policies(
    episodes: int,
    seed: int,
    survival: SurvivalConfig | None = None,
    values_dir: str | None = None,
) -> dict[str, Any]:
    """Evaluate learned, random and reactive policies on every behaviour."""
    learned = BehaviourPolicies.from_directory(values_dir)
    reactive = BehaviourPolicies.reactive()
    out: dict[str, Any] = {}
    for b, name in enumerate(BEHAVIOUR_NAMES):
        rows: dict[str, Any] = {}
        for label, policy in (
            ("learned", learned.policies[b]),
            ("random", "random"),
            ("reactive", reactive.policies[b]),
        ):
            t0 = time.perf_counter()
            env = BehaviourEpisode(name, survival=survival)  # fresh, as for every policy
            result = evaluate(name, policy, episodes, seed=seed, env=env, label=label)
            summary = result.summary()
            summary["wall_time_s"] = time.perf_counter() - t0
            rows[label] = summary
            print(f"  {name:7s} {label:9s} done in {summary['wall_time_s']:.1f} s", flush=True)
        out[name] = rows
    return out


def forage_training_budget(
    seed: int,
    check_every: int,
    max_episodes: int,
    eval_episodes: int,
    survival: SurvivalConfig | None = None,
) -> dict[str, Any]:
    """Train Forage from scratch until its greedy policy docks in ≥ 90 % of evaluation episodes."""
    history: list[dict[str, Any]] = []
    train_time = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        done = 0
        while done < max_episodes:
            done += check_every
            result = train(
                "forage",
                done,
                seed,
                tmp,
                resume=done > check_every,
                progress=False,
                survival=survival,
            )
            train_time += result.wall_time
            rate = evaluate(
                "forage",
                GreedyPolicy(result.values),
                eval_episodes,
                seed=seed,
                env=BehaviourEpisode("forage", survival=survival),
            )
            history.append(
                {"episodes": done, "train_wall_time_s": train_time, "dock_rate": rate.success_rate}
            )
            print(
                f"  forage from scratch: {done} episodes, {train_time:.0f} s training, "
                f"greedy dock rate {rate.success_rate:.3f}",
                flush=True,
            )
            if rate.success_rate >= 0.9:
                break
    reached = history[-1]["dock_rate"] >= 0.9
    return {"seed": seed, "reached_target": reached, "history": history}


def reproducibility(
    seed: int, episodes: int, survival: SurvivalConfig | None = None
) -> dict[str, Any]:
    """Two training runs with the same seed: identical values?"""
    sums = []
    with tempfile.TemporaryDirectory() as tmp:
        for run in ("a", "b"):
            r = train("mate", episodes, seed, Path(tmp) / run, progress=False, survival=survival)
            sums.append(r.values.checksum)
    return {
        "behaviour": "mate",
        "episodes": episodes,
        "checksums": sums,
        "identical": sums[0] == sums[1],
    }


def command_cost(repeats: int = 20_000, values_dir: str | None = None) -> dict[str, float]:
    """Microseconds per ``BehaviourPolicies.commands`` call (4 robots, mixed behaviours)."""
    world = World(WorldConfig(), np.random.default_rng(0))
    world.set_led(True)
    frame = make_provider("geometric", world).observe()
    inputs = behaviour_inputs(frame, world.range_readings(), world.range_max)
    behaviour = np.array([MATE, FORAGE, SEARCH, FORAGE])
    out = np.empty(4, dtype=np.int64)
    result = {}
    for label, policies in (
        ("learned", BehaviourPolicies.from_directory(values_dir)),
        ("reactive", BehaviourPolicies.reactive()),
    ):
        policies.commands(behaviour, inputs, out=out)
        t0 = time.perf_counter()
        for _ in range(repeats):
            policies.commands(behaviour, inputs, out=out)
        result[label] = 1e6 * (time.perf_counter() - t0) / repeats
    t0 = time.perf_counter()
    for _ in range(repeats // 10):
        behaviour_inputs(frame, world.range_readings(), world.range_max)
    result["behaviour_inputs"] = 1e6 * (time.perf_counter() - t0) / (repeats // 10)
    return result


def print_table(results: dict[str, Any]) -> None:
    print("\nbehaviour  measure                       learned     random    reactive")
    for name, label, key, pct in MEASURES:
        r = results[name]
        cells = [_fmt(r[p][key], pct) for p in ("learned", "random", "reactive")]
        print(f"{name:10s} {label:28s} {cells[0]:>9s} {cells[1]:>10s} {cells[2]:>10s}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=200, help="episodes per policy")
    parser.add_argument("--seed", type=int, default=0, help="evaluation seed")
    parser.add_argument("--skip-training", action="store_true", help="skip the budget run")
    parser.add_argument("--train-seed", type=int, default=1, help="seed of the budget run")
    parser.add_argument("--check-every", type=int, default=250, help="episodes between checks")
    parser.add_argument("--max-episodes", type=int, default=5000, help="budget run cap")
    parser.add_argument(
        "--values",
        default=None,
        metavar="DIR",
        help="learned policy: the action values in DIR (default: the shipped ones)",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="survival rule of the episodes, e.g. --set survival.control_dt=0.2 (repeatable; "
        "survival.* keys only)",
    )
    parser.add_argument(
        "--out", type=Path, default=RESULTS, help=f"results file (default {RESULTS.name} here)"
    )
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    try:
        survival = survival_rules(args.set)
    except ValueError as err:
        parser.error(str(err))

    report: dict[str, Any] = {
        "episodes_per_policy": args.episodes,
        "seed": args.seed,
        "values": args.values,
        "survival": survival_changes(survival),
    }
    print(f"evaluating {args.episodes} episodes per policy and behaviour ...")
    report["policies"] = compare_policies(args.episodes, args.seed, survival, args.values)
    print_table(report["policies"])
    costs = command_cost(values_dir=args.values)
    report["per_step_cost_us"] = costs
    print(
        f"\nper-step cost, 4 robots: commands() learned {costs['learned']:.1f} µs, reactive "
        f"{costs['reactive']:.1f} µs; behaviour_inputs() {costs['behaviour_inputs']:.1f} µs"
    )
    report["reproducibility"] = reproducibility(args.seed, 20, survival)
    print(f"same-seed training runs identical: {report['reproducibility']['identical']}")
    if not args.skip_training:
        print("training Forage from scratch until the greedy dock rate reaches 90 % ...")
        budget = forage_training_budget(
            args.train_seed, args.check_every, args.max_episodes, eval_episodes=100,
            survival=survival,
        )
        report["forage_training_budget"] = budget
        last = budget["history"][-1]
        verdict = "reached" if budget["reached_target"] else "did NOT reach"
        print(
            f"Forage from scratch {verdict} 90 % after {last['episodes']} episodes, "
            f"{last['train_wall_time_s']:.0f} s of training (seed {args.train_seed})"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2, allow_nan=True))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
