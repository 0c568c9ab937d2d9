"""``cyber-rodent train-behaviours``: learn Mate, Forage and Search with Sarsa(lambda)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from evolution.cli.options import NO_PROGRESS
from evolution.cli.parsing import CliError, int_arg

if TYPE_CHECKING:
    from cyber_rodent.survival import SurvivalConfig

HELP = "learn Mate, Forage and Search with Sarsa(lambda) in the physics world"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Train the basic behaviours (Sarsa(lambda), tile coding, replacing traces) "
        "and write their action values, learning curves (CSV + PNG) and a resumable checkpoint."
    )
    parser.add_argument(
        "--behaviour",
        default=None,
        help="mate, forage or search (default: all three in turn)",
    )
    parser.add_argument(
        "--episodes",
        type=int_arg("--episodes"),
        default=None,
        help="training episodes per behaviour (default: what the shipped values used)",
    )
    parser.add_argument("--seed", type=int_arg("--seed"), default=0, help="training seed")
    parser.add_argument("--out", default="runs/behaviours", help="output directory")
    parser.add_argument(
        "--resume", action="store_true", help="continue from the checkpoint in --out"
    )
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS)
    parser.add_argument(
        "--profile",
        default="sim",
        help="episode world: sim (the plain simulation), hardware (the hardware-like "
        "profile) or a profile file fitted by 'cyber-rodent sysid'",
    )
    parser.add_argument(
        "--randomise",
        action="store_true",
        help="domain randomisation: each episode draws its sensor noise and actuator "
        "differences from the hardware profile's ranges (a fitted profile: around the "
        "fitted values, within their uncertainty)",
    )
    parser.add_argument(
        "--robot",
        default="cyber_rodent",
        help="the body to train on, a name of cyber_rodent.robot.ROBOTS (default: "
        "cyber_rodent, the paper's robot; small_disc: an e-puck class robot)",
    )
    parser.add_argument(
        "--config",
        default=None,
        help="TOML or JSON file of survival.* settings (the rules of an evolution run)",
    )
    parser.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="train under a survival rule of an evolution run, e.g. --set "
        "survival.control_dt=0.2 (repeatable; survival.* keys only; energy is never used)",
    )


def run(args: argparse.Namespace) -> int:
    from behaviours.definitions import spec
    from behaviours.inputs import BEHAVIOUR_NAMES
    from behaviours.training import check_episodes, has_goal, train
    from cyber_rodent.profiles import HardwareProfile, profile_from_arg

    profile = profile_from_arg(args.profile)
    if args.randomise and profile is None:
        profile = HardwareProfile()  # the ranges the episodes are drawn from
    from cyber_rodent.robot import robot_names
    from cyber_rodent.validation import check_choice

    check_choice("--robot", args.robot, robot_names())
    names = BEHAVIOUR_NAMES if args.behaviour is None else (args.behaviour,)
    for name in names:
        spec(name)  # unknown name: fail before any work
    if args.episodes is not None:
        check_episodes(args.episodes)
    survival = _survival_rules(args) if args.config or args.set else None  # None: the paper's
    for name in names:
        result = train(
            name,
            args.episodes,
            seed=args.seed,
            out_dir=args.out,
            resume=args.resume,
            progress=not args.no_progress,
            profile=profile,
            randomise=args.randomise,
            survival=survival,
            robot=args.robot,
        )
        recent = result.curve[-100:]
        if has_goal(name):
            measure = f"success over the last 100: {recent[:, 3].mean():.2f}"
        else:
            measure = f"contacts per episode over the last 100: {recent[:, 4].mean():.2f}"
        print(
            f"{name}: {len(result.curve)} episodes ({result.episodes_run} this run, "
            f"{result.wall_time:.1f} s), {measure}; "
            f"wrote {result.values_path}, {result.curve_csv}, {result.curve_png}"
        )
    return 0


def _survival_rules(args: argparse.Namespace) -> SurvivalConfig:
    """An evolution run's rules from ``--config`` and ``--set``: its survival.* settings only."""
    from evolution.runner import RunConfig, settings

    from_file = settings.load_config_file(args.config) if args.config else {}
    from_set = settings.parse_set(args.set)
    # A file's survival.initial_energy etc. arrive under the evolution key of their number.
    shared = {v for k, v in settings.SHARED_KEYS.items() if k.startswith("survival.")}
    keys = [settings.canonical_key(item.partition("=")[0]) for item in args.set]
    for key in [*keys, *(k for k in from_file if k not in shared)]:
        if not key.startswith("survival."):
            raise CliError(f"train-behaviours takes survival.* settings, got {key}")
    return settings.apply(RunConfig(), settings.merge(from_file, from_set)).survival
