"""Pretraining on the fitted robot: does a behaviour trained on the fitted profile do better on
the "true robot" than one trained on the default profiles?

The true robot is a hidden hardware of :func:`cyber_rodent.sysid.synthetic.true_robot` (seed
1001 by default, one of the three the recovery table reports). Its fitted profile is what
``benchmarks/sysid_validation.py`` wrote from its log (``results/sysid/fitted_1001.json``);
neither the fit nor the training sees the true values. One behaviour (Forage by default: its
success is docking within 100 steps) is trained three times, from the same training seed and
for the same number of episodes, each in the 3-robot, 6-pack hardware field:

* ``sim``: the plain simulation (``train-behaviours``' default);
* ``hardware+DR``: the hand-set hardware profile with domain randomisation
  (``--profile hardware --randomise``), what a user without logs does;
* ``fitted+DR``: the fitted profile with domain randomisation around the fit, within its
  uncertainty (``--profile results/sysid/fitted_1001.json --randomise``).

With ``--oracle`` a fourth arm, ``true``, is trained on the true robot itself (its exact
values, no randomisation): the most any profile could recover, an upper bound no real user has.

Each is then evaluated greedily on the true robot (its drives, IR and camera noise exactly, no
randomisation) over ``--eval-episodes`` episodes whose placements no training saw
(``behaviours.evaluation``'s evaluation stream). The tests, fitted+DR against sim and against
hardware+DR: Fisher's exact test (two-sided) of the success rates, and the two-sided
Mann-Whitney U test of the steps each episode took (to the goal, or the limit when it failed).
Writes ``pretraining_<behaviour>[_<seed>].csv`` (per arm), ``..._episodes.csv`` (per episode)
and ``....json`` (the tests, the settings and the commit) in ``--out``; ``--summarise DIR``
gathers every such JSON in DIR into ``tests.csv`` with Holm's correction over its Fisher tests::

    python -m benchmarks.sysid_pretraining                     # Forage (round one)
    python -m benchmarks.sysid_pretraining --behaviour mate    # Mate (round one)
    python -m benchmarks.sysid_pretraining --spread worn --true-robot 2001 --oracle \
        --fitted results/sysid/round2/worn/fitted_2001.json --out results/sysid/round2/pretraining
    python -m benchmarks.sysid_pretraining --summarise results/sysid/round2/pretraining
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import fisher_exact, mannwhitneyu

from behaviours.definitions import load_values
from behaviours.episodes import BehaviourEpisode
from behaviours.evaluation import evaluate
from behaviours.greedy_policy import GreedyPolicy
from behaviours.training import DEFAULT_EPISODES, train
from benchmarks.colony_toggles import holm
from cyber_rodent.atomic import write_json, write_text
from cyber_rodent.profiles import (
    FittedActuators,
    FittedProfile,
    HardwareProfile,
    load_profile,
)
from cyber_rodent.sysid.synthetic import SPREADS, true_robot

ROOT = Path(__file__).resolve().parents[1]


def true_profile(seed: int, fitted: HardwareProfile, spread: str = "typical") -> FittedProfile:
    """The hidden hardware ``seed`` (drawn within ``SPREADS[spread]``) as a profile with no
    uncertainty (in ``fitted``'s field)."""
    truth = true_robot(seed, spread=spread)
    drives = truth.drives
    actuators = FittedActuators(
        wheel_gain=tuple((float(d[0]), float(d[1])) for d in drives),
        wheel_gain_sd=tuple((0.0, 0.0) for _ in drives),
        friction_scale=tuple(float(d[3]) for d in drives),
        friction_scale_sd=tuple(0.0 for _ in drives),
        motor_lag=tuple(float(d[2]) for d in drives),
        motor_lag_sd=tuple(0.0 for _ in drives),
    )
    return FittedProfile(
        range_noise=truth.range_noise,
        vision=truth.vision,
        actuators=actuators,
        field=fitted.field,
    )


def summarise(directory: Path) -> pd.DataFrame:
    """Every Fisher test of the JSON files in ``directory``, with Holm's correction over them
    all, and the steps tests beside them (not corrected); written to ``tests.csv``."""
    rows = []
    for path in sorted(directory.glob("pretraining_*.json")):
        record = json.loads(path.read_text())
        for name, t in record["tests"].items():
            rows.append({"behaviour": record["behaviour"], "true_robot": record["true_robot_seed"],
                         "comparison": name, "difference": t["difference"], "p_fisher": t["p"],
                         "steps_effect": t["steps_effect"], "p_steps": t["p_steps"]})  # fmt: skip
    table = pd.DataFrame(rows)
    if len(table):
        table.insert(5, "p_fisher_holm", holm(table["p_fisher"].tolist()))
    write_text(directory / "tests.csv", table.to_csv(index=False, float_format="%.4g"))
    return table


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--true-robot", type=int, default=1001, help="hidden hardware seed")
    parser.add_argument("--spread", default="typical", choices=sorted(SPREADS),
                        help="what the hidden hardware is drawn from")  # fmt: skip
    parser.add_argument(
        "--fitted", default=None, help="fitted profile (default: results/sysid/fitted_SEED.json)"
    )
    parser.add_argument("--behaviour", default="forage", choices=("forage", "mate"))
    parser.add_argument("--episodes", type=int, default=None, help="training episodes per arm")
    parser.add_argument("--train-seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=200)
    parser.add_argument("--eval-seed", type=int, default=0)
    parser.add_argument("--oracle", action="store_true", help="add the arm trained on the truth")
    parser.add_argument("--out", default=str(ROOT / "results" / "sysid"))
    parser.add_argument("--summarise", type=Path, default=None, metavar="DIR",
                        help="only gather DIR's results into DIR/tests.csv")  # fmt: skip
    args = parser.parse_args()
    if args.summarise is not None:
        print(summarise(args.summarise).to_string(index=False))
        return 0
    episodes = args.episodes or DEFAULT_EPISODES[args.behaviour]
    fitted_path = Path(args.fitted or ROOT / "results" / "sysid" / f"fitted_{args.true_robot}.json")
    fitted = load_profile(fitted_path)
    truth = true_profile(args.true_robot, fitted, args.spread)
    arms: dict[str, tuple[HardwareProfile | None, bool]] = {
        "sim": (None, False),
        "hardware+DR": (HardwareProfile(), True),
        "fitted+DR": (fitted, True),
    }
    if args.oracle:
        arms["true"] = (truth, False)
    started = time.time()
    rows, per_episode = [], []
    successes: dict[str, np.ndarray] = {}
    steps: dict[str, np.ndarray] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, (profile, randomise) in arms.items():
            out = Path(tmp) / name.replace("+", "_")
            train(args.behaviour, episodes, seed=args.train_seed, out_dir=out, progress=False,
                  profile=profile, randomise=randomise)  # fmt: skip
            policy = GreedyPolicy(load_values(args.behaviour, out))
            env = BehaviourEpisode(args.behaviour, profile=truth, randomise=False)
            result = evaluate(args.behaviour, policy, args.eval_episodes, seed=args.eval_seed,
                              env=env, label=name)  # fmt: skip
            successes[name], steps[name] = result.success, result.steps
            per_episode += [{"arm": name, "episode": i, "success": int(ok), "steps": int(n)}
                            for i, (ok, n) in enumerate(zip(result.success, result.steps,
                                                            strict=True))]  # fmt: skip
            rows.append({"arm": name, "trained_episodes": episodes,
                         "eval_episodes": result.episodes, "successes": int(result.success.sum()),
                         "success_rate": result.success_rate,
                         "median_steps_to_goal": result.median_steps_to_goal,
                         "mean_steps": float(result.steps.mean())})  # fmt: skip
            print(f"{name}: success {result.success_rate:.3f} on the true robot "
                  f"({time.time() - started:.0f} s)", flush=True)  # fmt: skip
    tests = {}
    f = successes["fitted+DR"]
    for other in ("sim", "hardware+DR"):
        o = successes[other]
        table = [[int(f.sum()), int((~f).sum())], [int(o.sum()), int((~o).sum())]]
        odds, p = fisher_exact(table, alternative="two-sided")
        u = mannwhitneyu(steps["fitted+DR"], steps[other], alternative="two-sided")
        effect = 2.0 * float(u.statistic) / (len(f) * len(o)) - 1.0
        tests[f"fitted+DR vs {other}"] = {"table": table, "odds_ratio": float(odds), "p": float(p),
                                          "difference": float(f.mean() - o.mean()),
                                          "steps_effect": effect,
                                          "p_steps": float(u.pvalue)}  # fmt: skip
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    frame = pd.DataFrame(rows)
    stem = f"pretraining_{args.behaviour}"
    if args.fitted is not None:  # round two: one file set per true robot
        stem += f"_{args.true_robot}"
    write_text(out / f"{stem}.csv", frame.to_csv(index=False, float_format="%.4g"))
    if args.fitted is not None:
        write_text(out / f"{stem}_episodes.csv", pd.DataFrame(per_episode).to_csv(index=False))
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()  # fmt: skip
    write_json(out / f"{stem}.json", {
        "command": "python -m benchmarks.sysid_pretraining " + " ".join(sys.argv[1:]),
        "commit": commit, "behaviour": args.behaviour, "true_robot_seed": args.true_robot,
        "spread": args.spread,
        "fitted_profile": str(fitted_path.relative_to(ROOT)) if fitted_path.is_relative_to(ROOT)
        else str(fitted_path),
        "training_episodes": episodes, "train_seed": args.train_seed,
        "eval_episodes": args.eval_episodes, "eval_seed": args.eval_seed,
        "test": "Fisher's exact test of success, two-sided; Mann-Whitney U of steps, two-sided "
                "(steps_effect: rank-biserial, positive when fitted+DR took more steps)",
        "tests": tests,
        "wall_s": round(time.time() - started, 1),
    })  # fmt: skip
    print(frame.to_string(index=False))
    for name, t in tests.items():
        print(f"{name}: difference {t['difference']:+.3f}, odds ratio {t['odds_ratio']:.3g}, "
              f"p = {t['p']:.3g}; steps effect {t['steps_effect']:+.3f}, "
              f"p = {t['p_steps']:.3g}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
