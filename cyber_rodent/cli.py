"""The ``cyber-rodent`` command line.

The only module that may tie the three packages (``cyber_rodent``, ``behaviours``, ``evolution``)
together; it imports them lazily inside each sub-command so ``--help`` stays fast. User errors
(bad counts, missing assets, unwritable outputs) print one line and exit with status 2, never a
traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _int_arg(name: str):
    def parse(text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None

    return parse


def _cmd_snapshot(args: argparse.Namespace) -> int:
    import numpy as np

    from cyber_rodent.render import FieldRenderer, check_writable_output, write_png
    from cyber_rodent.world import World, WorldConfig

    check_writable_output(args.out)  # fail before any expensive work
    config = WorldConfig(n_robots=args.robots, n_packs=args.packs)
    world = World(config, np.random.default_rng(args.seed))
    if args.robot is not None and not 0 <= args.robot < config.n_robots:
        raise CliError(f"--robot must be in [0, {config.n_robots - 1}], got {args.robot}")
    if args.omni:
        if args.robot is None:
            raise CliError("--omni needs --robot I (whose omnidirectional view to save)")
        from cyber_rodent.vision import save_omni_png

        out = save_omni_png(world, args.robot, args.out)
    else:
        with FieldRenderer(world, args.size, args.size) as renderer:
            image = renderer.top_down() if args.robot is None else renderer.robot_view(args.robot)
        out = write_png(image, args.out)
    print(f"wrote {out}")
    return 0


def _cmd_train_behaviours(args: argparse.Namespace) -> int:
    from behaviours.definitions import spec
    from behaviours.inputs import BEHAVIOUR_NAMES
    from behaviours.training import check_episodes, train

    names = BEHAVIOUR_NAMES if args.behaviour is None else (args.behaviour,)
    for name in names:
        spec(name)  # unknown name: fail before any work
    if args.episodes is not None:
        check_episodes(args.episodes)
    for name in names:
        result = train(
            name,
            args.episodes,
            seed=args.seed,
            out_dir=args.out,
            resume=args.resume,
            progress=not args.no_progress,
        )
        recent = result.curve[-100:]
        if name == "search":
            measure = f"contacts per episode over the last 100: {recent[:, 4].mean():.2f}"
        else:
            measure = f"success over the last 100: {recent[:, 3].mean():.2f}"
        print(
            f"{name}: {len(result.curve)} episodes ({result.episodes_run} this run, "
            f"{result.wall_time:.1f} s), {measure}; "
            f"wrote {result.values_path}, {result.curve_csv}, {result.curve_png}"
        )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cyber-rodent",
        description="Cyber Rodent colony simulation: embodied evolution of survival in MuJoCo.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    snap = sub.add_parser(
        "snapshot",
        help="render a seeded world to PNG (top-down field, a robot's view, or its omni image)",
        description="Render a seeded world off-screen and write a PNG.",
    )
    snap.add_argument("--out", required=True, help="output PNG file")
    snap.add_argument("--seed", type=_int_arg("--seed"), default=0, help="placement seed")
    snap.add_argument("--robots", type=_int_arg("--robots"), default=4, help="number of robots")
    snap.add_argument("--packs", type=_int_arg("--packs"), default=5, help="number of packs")
    snap.add_argument("--size", type=_int_arg("--size"), default=640, help="image side in px")
    snap.add_argument(
        "--robot",
        type=_int_arg("--robot"),
        default=None,
        help="render robot I's chase view instead of the field",
    )
    snap.add_argument(
        "--omni",
        action="store_true",
        help="with --robot: save its omnidirectional image and segmentation",
    )
    snap.set_defaults(func=_cmd_snapshot)

    train = sub.add_parser(
        "train-behaviours",
        help="learn Mate, Forage and Search with Sarsa(lambda) in the physics world",
        description="Train the basic behaviours (Sarsa(lambda), tile coding, replacing traces) "
        "and write their action values, learning curves (CSV + PNG) and a resumable checkpoint.",
    )
    train.add_argument(
        "--behaviour",
        default=None,
        help="mate, forage or search (default: all three in turn)",
    )
    train.add_argument(
        "--episodes",
        type=_int_arg("--episodes"),
        default=None,
        help="training episodes per behaviour (default: what the shipped values used)",
    )
    train.add_argument("--seed", type=_int_arg("--seed"), default=0, help="training seed")
    train.add_argument("--out", default="runs/behaviours", help="output directory")
    train.add_argument(
        "--resume", action="store_true", help="continue from the checkpoint in --out"
    )
    train.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    train.set_defaults(func=_cmd_train_behaviours)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from cyber_rodent.assets import AssetNotFoundError

    try:
        return args.func(args)
    except (CliError, ValueError, AssetNotFoundError) as err:
        print(f"cyber-rodent: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as err:
        print(
            f"cyber-rodent: error: {err.strerror or err}: {err.filename or ''}".rstrip(": "),
            file=sys.stderr,
        )
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("cyber-rodent: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
