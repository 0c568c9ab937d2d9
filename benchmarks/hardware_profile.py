"""Robustness of the behaviours under the hardware-like profile: shipped vs domain-randomised.

Usage::

    .venv/bin/cyber-rodent train-behaviours --randomise --out runs/behaviours_randomised
    .venv/bin/python -m benchmarks.hardware_profile --randomised runs/behaviours_randomised

For each behaviour it runs the same seeded episodes (identical start placements, identical
hardware draws) with the greedy policies of the shipped values and of the values trained with
``--randomise``, in the plain simulation and in the hardware-like profile
(:class:`cyber_rodent.profiles.HardwareProfile`: IR noise and dropouts, camera noise and missed
detections, per-robot wheel gain, friction and motor lag with one weak robot, the 6-pack
field). With ``--parts`` it also evaluates the shipped values with each part of the profile on
its own. The measures are those of ``benchmarks/behaviours.py``: Forage dock rate and median
steps to dock, Mate IR-exchange rate and median steps, Search contacts per 1,000 steps and area
covered. It also measures the evolution runner's per-step cost with and without the profile.

Results go to ``benchmarks/results/hardware_profile.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from behaviours import BehaviourPolicies  # noqa: E402
from behaviours.episodes import BehaviourEpisode  # noqa: E402
from behaviours.evaluation import MEASURES, evaluate  # noqa: E402
from behaviours.inputs import BEHAVIOUR_NAMES  # noqa: E402
from cyber_rodent.profiles import PROFILE_PARTS, HardwareProfile  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "hardware_profile.json"


def _fmt(x: float, pct: bool = False) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return f"{100 * x:.1f} %" if pct else f"{x:.3g}"


def evaluate_set(
    policies: BehaviourPolicies, profile: HardwareProfile | None, episodes: int, seed: int
) -> dict:
    """Every behaviour's evaluation summary with one policy set in one world."""
    out = {}
    for i, name in enumerate(BEHAVIOUR_NAMES):
        env = BehaviourEpisode(name, profile=profile)
        t = time.perf_counter()
        result = evaluate(name, policies.policies[i], episodes, seed, env=env, label=policies.kind)
        out[name] = {**result.summary(), "wall_time_s": time.perf_counter() - t}
    return out


def runner_step_cost(steps: int = 2000) -> dict:
    """Per-step wall time of the evolution runner (4 robots / 3 robots), without and with the
    profile; the profile adds range noise to the perception and nothing else per step."""
    from evolution.config import EvolutionConfig
    from evolution.lab.transfer import hardware_run_config
    from evolution.runner import EvolutionRunner, RunConfig

    base = RunConfig(evolution=EvolutionConfig(population_size=12, n_robots=3))
    configs = {
        "3 robots, 6 packs, no profile": hardware_run_config(
            base, HardwareProfile().without(*PROFILE_PARTS), robots=3, agents_per_robot=4
        ),
        "3 robots, 6 packs, hardware profile": hardware_run_config(
            base, HardwareProfile(), robots=3, agents_per_robot=4
        ),
    }
    out = {}
    for label, config in configs.items():
        with EvolutionRunner(config, 0, BehaviourPolicies.load_default()) as runner:
            for _ in range(100):
                runner.step()
            t = time.perf_counter()
            for _ in range(steps):
                runner.step()
            out[label] = 1e6 * (time.perf_counter() - t) / steps
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=200, help="episodes per measurement")
    parser.add_argument("--seed", type=int, default=0, help="evaluation seed")
    parser.add_argument(
        "--randomised", default=None, help="values directory of train-behaviours --randomise"
    )
    parser.add_argument("--parts", action="store_true", help="also each profile part alone")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    sets = {"shipped": BehaviourPolicies.load_default()}
    if args.randomised:
        sets["randomised"] = BehaviourPolicies.from_directory(args.randomised)
    worlds = {"sim": None, "hardware": HardwareProfile()}
    report: dict = {"episodes": args.episodes, "seed": args.seed, "results": {}}
    for world, profile in worlds.items():
        for label, policies in sets.items():
            print(f"evaluating {label} behaviours in the {world} world ...", flush=True)
            report["results"][f"{label}/{world}"] = evaluate_set(
                policies, profile, args.episodes, args.seed
            )
    if args.parts:
        for part in PROFILE_PARTS:
            print(f"evaluating shipped behaviours with only {part} ...", flush=True)
            report["results"][f"shipped/only-{part}"] = evaluate_set(
                sets["shipped"], HardwareProfile().only(part), args.episodes, args.seed
            )
    report["runner_step_us"] = runner_step_cost()
    columns = list(report["results"])
    print(f"\n{args.episodes} episodes each, seed {args.seed}")
    print(f"{'behaviour':10s} {'measure':30s} " + " ".join(f"{c:>20s}" for c in columns))
    for name, label, key, pct in MEASURES:
        cells = [_fmt(report["results"][c][name][key], pct) for c in columns]
        print(f"{name:10s} {label:30s} " + " ".join(f"{c:>20s}" for c in cells))
    for label, us in report["runner_step_us"].items():
        print(f"runner step, {label}: {us:.0f} µs")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(report, indent=2, allow_nan=True))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
