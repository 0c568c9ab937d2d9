"""``cyber-rodent sweep``: many runs (grid cells x methods x seeds) in parallel, local or on
Ray, with their projected run time first."""

from __future__ import annotations

import argparse
import os
import sys

from evolution.cli import options
from evolution.cli.parsing import int_arg

HELP = "many runs (grid cells x methods x seeds) in parallel: local processes or Ray"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Run every method x seed (x grid cell), one process per run (or one Ray "
        "task per run with --ray), each in <out>/<method>-seed<NNN> (with --grid: "
        "<out>/<cell>/<method>-seed<NNN>); failed runs are retried from their last "
        "checkpoint. Results are identical whichever executor ran them. With only --out it "
        "runs the paper's Fig. 6 experiment (EE and CE x seeds 0-19 x 120 generations: "
        "hours); the projected run time is printed before the runs start."
    )
    parser.add_argument(
        "--methods", default="ee,ce", help="comma list of schemes (ee, ce, medea, a plugin's)"
    )
    parser.add_argument("--seeds", default="0-19", help="seeds: N, A-B or a comma list")
    parser.add_argument(
        "--generations",
        type=int_arg("--generations"),
        default=120,
        help="generations per run (the paper: 120)",
    )
    parser.add_argument("--out", required=True, help="sweep directory")
    parser.add_argument(
        "--workers",
        type=int_arg("--workers"),
        default=None,
        help="concurrent runs (default: CPU count)",
    )
    parser.add_argument(
        "--ray",
        default=None,
        metavar="ADDRESS",
        help="run on Ray: auto, HOST:PORT, ray://HOST:PORT, or local (default: local "
        "processes, no Ray)",
    )
    parser.add_argument(
        "--grid",
        action="append",
        metavar="KEY=V1,V2,...",
        default=[],
        help="a grid axis, e.g. --grid survival.reflex_max_steps=4,8,16 (repeatable: every "
        "cell of the product runs every method and seed)",
    )
    options.add_max_steps(parser)
    options.add_tensorboard(
        parser, "each run in DIR/<method>-seed<NNN> (with --grid: DIR/<cell>/...)"
    )
    options.add_plugin_option(
        parser,
        "every worker (local or Ray) loads it from its text, and each run.json records it",
    )
    options.add_run_options(parser)


def run(args: argparse.Namespace) -> int:
    from cyber_rodent.plugins import plugin_source
    from cyber_rodent.validation import check_integer
    from evolution.lab import experiment
    from evolution.lab.api import RunOutput, policies_by_name
    from evolution.lab.grid import check_grid
    from evolution.lab.sweep import (
        STEP_SECONDS,
        Execution,
        SweepSpec,
        check_ray_address,
        check_sweep_plugins,
        parse_seeds,
        projected_seconds,
        sweep,
    )
    from evolution.runner.settings import parse_grid

    plugins = options.load_plugins(args)  # before the settings, which may name what they add
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    if args.max_steps is not None:
        from evolution.config import MAX_RUN_STEPS

        check_integer("--max-steps", args.max_steps, 1, MAX_RUN_STEPS)
    spec = SweepSpec(
        methods,
        parse_seeds(args.seeds),
        args.generations,
        options.read_settings(args),
        policies=args.policies,
        grid=parse_grid(args.grid),
        max_steps=args.max_steps,
        plugins=tuple(plugin_source(plugin) for plugin in plugins),
    )
    if args.resume:  # the runs there were started with this grid and these plugins
        check_grid(args.out, spec.grid)
        check_sweep_plugins(args.out, spec)
    spec.check()  # every cell's settings, before anything is written
    policies_by_name(args.policies)  # the shipped values are installed
    if args.workers is not None:
        check_integer("--workers", args.workers, 1, 4096)
    executor = "ray" if args.ray is not None else "local"
    if executor == "ray":
        check_ray_address(args.ray)  # before anything is written
    if args.tensorboard is not None:
        from evolution.lab.monitor import check_tensorboard

        check_tensorboard(args.tensorboard)
    workers = args.workers or os.cpu_count() or 1
    out = experiment.prepare_sweep_dir(
        args.out, resume=args.resume, force=args.force, plugins=plugins
    )
    seconds = projected_seconds(spec, workers)
    print(
        f"sweep: {len(spec.runs)} runs x {spec.generations} generations on {workers} "
        f"workers; projected run time about {_duration(seconds)} (an estimate from the "
        f"config and a documented rate of ~{1 / STEP_SECONDS:,.0f} control steps/s per core"
        f"{'; less what is already done' if args.resume else ''})",
        flush=True,
    )
    output = RunOutput(out, tensorboard=args.tensorboard, progress=not args.no_progress)
    try:
        results = sweep(spec, output, Execution(executor, args.workers, args.ray or "local"))
    except KeyboardInterrupt:
        print(
            "cyber-rodent: interrupted; continue with the same command and --resume",
            file=sys.stderr,
        )
        return 130
    figures = experiment.plot_run_dir(out)
    print(f"{len(results)} runs finished in {out}; figures: " + ", ".join(str(f) for f in figures))
    return 0


def _duration(seconds: float) -> str:
    """A duration in words: seconds, minutes, hours or days."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    if seconds < 48 * 3600:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"
