"""``cyber-rodent snapshot``: render a seeded world off-screen to a PNG."""

from __future__ import annotations

import argparse

from evolution.cli.parsing import CliError, float_arg, int_arg

HELP = "render a seeded world to PNG (top-down field, a robot's view, or its omni image)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = "Render a seeded world off-screen and write a PNG."
    parser.add_argument("--out", required=True, help="output PNG file")
    parser.add_argument("--seed", type=int_arg("--seed"), default=0, help="placement seed")
    parser.add_argument(
        "--robots", type=int_arg("--robots"), default=4, help="number of robots"
    )
    parser.add_argument("--packs", type=int_arg("--packs"), default=5, help="number of packs")
    parser.add_argument(
        "--field-size",
        type=float_arg("--field-size"),
        default=2.3,
        help="side of the square field in m (the paper's: 2.3; at its density N robots need "
        "2.3 x sqrt(N / 4), e.g. --robots 100 --packs 125 --field-size 11.5)",
    )
    parser.add_argument(
        "--arenas",
        type=int_arg("--arenas"),
        default=1,
        help="copies of the field side by side, each with its own walls, --robots / N robots "
        "and --packs / N packs (the paper's: 1; 25 copies of its world: --robots 100 --packs "
        "125 --arenas 25)",
    )
    parser.add_argument(
        "--size",
        type=int_arg("--size"),
        default=None,
        help="image side in px (default: 640 for the paper's 2.3 m field, growing with the "
        "field to keep its pixels per metre, up to 2048)",
    )
    parser.add_argument(
        "--robot",
        type=int_arg("--robot"),
        default=None,
        help="render robot I's chase view instead of the field",
    )
    parser.add_argument(
        "--omni",
        action="store_true",
        help="with --robot: save its omnidirectional image and segmentation",
    )
    parser.add_argument(
        "--plain",
        action="store_true",
        help="the bare render: no robot IDs (CRi = robot i), heading arrows or caption, and "
        "empty space left black",
    )


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from cyber_rodent.render import check_writable_output, snapshot, write_png
    from cyber_rodent.world import World, WorldConfig

    check_writable_output(args.out)  # fail before any expensive work
    config = WorldConfig(
        field_size=args.field_size, n_robots=args.robots, n_packs=args.packs, arenas=args.arenas
    )
    world = World(config, np.random.default_rng(args.seed))
    if args.robot is not None and not 0 <= args.robot < config.n_robots:
        raise CliError(f"--robot must be in [0, {config.n_robots - 1}], got {args.robot}")
    if args.omni:
        if args.robot is None:
            raise CliError("--omni needs --robot I (whose omnidirectional view to save)")
        from cyber_rodent.vision import save_omni_png

        out = save_omni_png(world, args.robot, args.out)
    else:
        out = write_png(snapshot(world, args.robot, args.size, args.plain), args.out)
    print(f"wrote {out}")
    return 0
