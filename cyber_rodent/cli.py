"""The ``cyber-rodent`` command line.

The only module that may tie the three packages (``cyber_rodent``, ``behaviours``, ``evolution``)
together; it imports them lazily inside each sub-command so ``--help`` stays fast. User errors
(bad counts, missing assets, unwritable outputs) print one line and exit with status 2, never a
traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pandas is slow to import; ``--help`` must stay fast
    import pandas as pd

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _int_arg(name: str) -> Callable[[str], int]:
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
    from cyber_rodent.profiles import HardwareProfile, profile_by_name

    profile = profile_by_name(args.profile)
    if args.randomise and profile is None:
        profile = HardwareProfile()  # the ranges the episodes are drawn from
    names = BEHAVIOUR_NAMES if args.behaviour is None else (args.behaviour,)
    for name in names:
        spec(name)  # unknown name: fail before any work
    if args.episodes is not None:
        check_episodes(args.episodes)
    survival = None  # the paper's rules
    if args.config or args.set:  # an evolution run's rules: its survival.* settings only
        from evolution import settings
        from evolution.runner import RunConfig

        from_file = settings.load_config_file(args.config) if args.config else {}
        from_set = settings.parse_set(args.set)
        # A file's survival.initial_energy etc. arrive under the evolution key of their number.
        shared = {v for k, v in settings.SHARED_KEYS.items() if k.startswith("survival.")}
        keys = [settings.canonical_key(item.partition("=")[0]) for item in args.set]
        for key in [*keys, *(k for k in from_file if k not in shared)]:
            if not key.startswith("survival."):
                raise CliError(f"train-behaviours takes survival.* settings, got {key}")
        run = settings.apply(RunConfig(), settings.merge(from_file, from_set))
        survival = run.survival
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


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """The settings of ``--config FILE`` then ``--set KEY=VALUE`` (later ones win)."""
    from evolution import settings

    from_file = settings.load_config_file(args.config) if args.config else {}
    return settings.merge(from_file, settings.parse_set(args.set))


def _cmd_config(args: argparse.Namespace) -> int:
    from evolution.api import make_config
    from evolution.settings import to_toml

    config = make_config(args.method, **_settings(args))
    sys.stdout.write(to_toml(config, method=args.method))
    return 0


def _cmd_evolve(args: argparse.Namespace) -> int:
    from evolution import experiment

    overrides = _settings(args)
    out = args.out if args.out is not None else experiment.default_out_dir(args.method, args.seed)
    try:
        path, table = experiment.evolve(
            args.method,
            args.generations,
            args.seed,
            out,
            overrides=overrides,
            policies=args.policies,
            resume=args.resume,
            force=args.force,
            checkpoint_every=args.checkpoint_every,
            keep_checkpoints=args.keep_checkpoints,
            progress=not args.no_progress,
            argv=sys.argv,
        )
    except KeyboardInterrupt:
        print(
            f"cyber-rodent: interrupted; continue with: cyber-rodent resume {out}", file=sys.stderr
        )
        return 130
    _report_run(path, table)
    if args.generations < 120:
        print(
            f"This was a short run ({args.generations} generations). The paper's Fig. 6 "
            f"experiment (20 seeds x EE and CE x 120 generations):\n  {experiment.PAPER_COMMAND}"
        )
    return 0


def _report_run(path: Path, table: pd.DataFrame) -> None:
    if len(table):
        last = table.iloc[-1]
        print(
            f"{len(table)} generations; last generation: {int(last['completed'])} agents "
            f"completed the survival task, batteries {last['batteries_mean']:.1f}, "
            f"matings {last['matings_mean']:.2f}"
        )
    print(f"run directory: {path}  (statistics.csv, events.csv, figures/, checkpoints/)")


def _cmd_transfer(args: argparse.Namespace) -> int:
    from cyber_rodent.profiles import profile_by_name
    from evolution.transfer import ROBOT_STATISTICS_FILE, transfer

    profile = profile_by_name(args.profile)
    result = transfer(
        args.source,
        args.out,
        generation=args.generation,
        top=args.top,
        robots=args.robots,
        agents_per_robot=args.agents_per_robot,
        generations=args.generations,
        profile=profile,
        seed=args.seed,
        progress=not args.no_progress,
    )
    table = result.per_robot
    if len(table):
        first = table[table["generation"] == table["generation"].min()]
        last = table[table["generation"] == table["generation"].max()]
        for robot in sorted(table["robot"].unique()):
            a = first.loc[first["robot"] == robot, "batteries_mean"]
            b = last.loc[last["robot"] == robot, "batteries_mean"]
            print(
                f"CR {robot + 1}: batteries per agent {a.iloc[0] if len(a) else float('nan'):.2f}"
                f" -> {b.iloc[0] if len(b) else float('nan'):.2f}"
            )
    print(
        f"transfer run: {result.out}  (statistics.csv, {ROBOT_STATISTICS_FILE}, transfer.json, "
        "figures/fig7.png)"
    )
    return 0


def _cmd_resume(args: argparse.Namespace) -> int:
    from evolution import experiment

    try:
        path, table = experiment.resume_run(
            args.dir, progress=not args.no_progress, generations=args.generations
        )
    except KeyboardInterrupt:
        print(
            f"cyber-rodent: interrupted; continue with: cyber-rodent resume {args.dir}",
            file=sys.stderr,
        )
        return 130
    _report_run(path, table)
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from evolution import experiment
    from evolution.grid import check_grid
    from evolution.settings import parse_grid
    from evolution.sweep import SweepSpec, check_ray_address, parse_seeds, sweep

    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    spec = SweepSpec(
        methods,
        parse_seeds(args.seeds),
        args.generations,
        _settings(args),
        policies=args.policies,
        grid=parse_grid(args.grid),
    )
    spec.check()  # every cell's settings, before anything is written
    if args.resume:
        check_grid(args.out, spec.grid)
    experiment.policies_by_name(args.policies)  # the shipped values are installed
    if args.workers is not None and args.workers < 1:
        raise CliError(f"--workers must be >= 1, got {args.workers}")
    executor = "ray" if args.ray is not None else "local"
    if executor == "ray":
        check_ray_address(args.ray)  # before anything is written
    out = experiment.prepare_sweep_dir(args.out, resume=args.resume, force=args.force)
    try:
        results = sweep(
            spec,
            out,
            workers=args.workers,
            executor=executor,
            ray_address=args.ray or "local",
            progress=not args.no_progress,
        )
    except KeyboardInterrupt:
        print(
            "cyber-rodent: interrupted; continue with the same command and --resume",
            file=sys.stderr,
        )
        return 130
    figures = experiment.plot_run_dir(out)
    print(f"{len(results)} runs finished in {out}; figures: " + ", ".join(str(f) for f in figures))
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    from evolution import experiment

    for path in experiment.plot_run_dir(args.dir, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from evolution import experiment

    if (args.dir is None) == (args.checkpoint is None):
        raise CliError("give a run directory or --checkpoint FILE (one of them)")
    out = experiment.render_run(
        args.dir if args.dir is not None else args.checkpoint,
        args.out,
        frames=args.frames,
        fps=args.fps,
        steps_per_frame=args.steps_per_frame,
        progress=not args.no_progress,
    )
    print(f"wrote {out}")
    return 0


def _add_setting_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        default=None,
        help="TOML or JSON file of settings, e.g. the output of `cyber-rodent config`",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="change one setting, e.g. --set survival.mate_distance=0.4 (repeatable; "
        "`cyber-rodent config` lists every key)",
    )


def _add_run_options(p: argparse.ArgumentParser) -> None:
    _add_setting_options(p)
    p.add_argument(
        "--policies",
        default="trained",
        choices=("trained", "reactive"),
        help="basic behaviours: the shipped trained values or the reactive baseline",
    )
    p.add_argument("--resume", action="store_true", help="continue the run(s) in --out")
    p.add_argument("--force", action="store_true", help="replace the run(s) in --out")
    p.add_argument("--no-progress", action="store_true", help="hide progress bars")


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
    train.add_argument(
        "--profile",
        default="sim",
        choices=("sim", "hardware"),
        help="episode world: the plain simulation or the hardware-like profile",
    )
    train.add_argument(
        "--randomise",
        action="store_true",
        help="domain randomisation: each episode draws its sensor noise and actuator "
        "differences from the hardware profile's ranges",
    )
    train.add_argument(
        "--config",
        default=None,
        help="TOML or JSON file of survival.* settings (the rules of an evolution run)",
    )
    train.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="train under a survival rule of an evolution run, e.g. --set "
        "survival.control_dt=0.2 (repeatable; survival.* keys only; energy is never used)",
    )
    train.set_defaults(func=_cmd_train_behaviours)

    evolve = sub.add_parser(
        "evolve",
        help="run embodied evolution (EE) or the centralised GA (CE) in a run directory",
        description="Run EE or CE on the physics world. Writes a run directory (config, "
        "versions, statistics.csv, events.csv, checkpoints, figures). With no arguments: a "
        "short EE run (5 generations) that finishes in minutes.",
    )
    evolve.add_argument("--method", default="ee", choices=("ee", "ce"))
    evolve.add_argument(
        "--generations",
        type=_int_arg("--generations"),
        default=5,
        help="generations to complete (default 5; the paper: 120)",
    )
    evolve.add_argument("--seed", type=_int_arg("--seed"), default=0)
    evolve.add_argument(
        "--out", default=None, help="run directory (default: runs/<method>-seed<S>-<timestamp>)"
    )
    evolve.add_argument(
        "--checkpoint-every",
        type=_int_arg("--checkpoint-every"),
        default=1,
        help="generations between checkpoints",
    )
    evolve.add_argument(
        "--keep-checkpoints",
        type=_int_arg("--keep-checkpoints"),
        default=3,
        help="newest checkpoints to keep (default 3; 0 keeps every generation, which "
        "'transfer --generation' needs)",
    )
    _add_run_options(evolve)
    evolve.set_defaults(func=_cmd_evolve)

    resume = sub.add_parser(
        "resume",
        help="continue an interrupted run from its checkpoint",
        description="Continue a run directory's run from its newest "
        "checkpoint; the result is identical to an uninterrupted run.",
    )
    resume.add_argument("dir", help="the run directory")
    resume.add_argument(
        "--generations",
        type=_int_arg("--generations"),
        default=None,
        help="new target (default: the run's own)",
    )
    resume.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    resume.set_defaults(func=_cmd_resume)

    sweep = sub.add_parser(
        "sweep",
        help="many runs (grid cells x methods x seeds) in parallel: local processes or Ray",
        description="Run every method x seed (x grid cell), one process per run (or one Ray "
        "task per run with --ray), each in <out>/<method>-seed<NNN> (with --grid: "
        "<out>/<cell>/<method>-seed<NNN>); failed runs are retried from their last "
        "checkpoint. Results are identical whichever executor ran them.",
    )
    sweep.add_argument("--methods", default="ee,ce", help="comma list of ee, ce")
    sweep.add_argument("--seeds", default="0-19", help="seeds: N, A-B or a comma list")
    sweep.add_argument("--generations", type=_int_arg("--generations"), default=120)
    sweep.add_argument("--out", required=True, help="sweep directory")
    sweep.add_argument(
        "--workers",
        type=_int_arg("--workers"),
        default=None,
        help="concurrent runs (default: CPU count)",
    )
    sweep.add_argument(
        "--ray",
        default=None,
        metavar="ADDRESS",
        help="run on Ray: auto, HOST:PORT, ray://HOST:PORT, or local",
    )
    sweep.add_argument(
        "--grid",
        action="append",
        metavar="KEY=V1,V2,...",
        default=[],
        help="a grid axis, e.g. --grid survival.reflex_max_steps=4,8,16 (repeatable: every "
        "cell of the product runs every method and seed)",
    )
    _add_run_options(sweep)
    sweep.set_defaults(func=_cmd_sweep)

    config = sub.add_parser(
        "config",
        help="print every setting, resolved, as commented TOML (a valid --config file)",
        description="Print the resolved configuration (the paper's defaults, then --config, "
        "then --set) as TOML: each setting with its meaning, allowed range, unit and source.",
    )
    config.add_argument("--method", default="ee", choices=("ee", "ce"))
    _add_setting_options(config)
    config.set_defaults(func=_cmd_config)

    plot = sub.add_parser(
        "plot",
        help="Fig. 6 and the EE vs CE statistics of a run or sweep directory",
        description="Draw Fig. 6 and the completed agents per generation (PNG + PDF), and "
        "write the EE vs CE statistics (comparison.csv: Mann-Whitney U, effect size, CE "
        "convergence, EE rise) of a run directory, a sweep directory or a directory of "
        "published run tables into <dir>/figures (or --out); a grid sweep also gets the "
        "comparison of its cells (cells.csv, cells.png).",
    )
    plot.add_argument("dir")
    plot.add_argument(
        "--out", default=None, help="directory for the figures and tables (default: DIR/figures)"
    )
    plot.set_defaults(func=_cmd_plot)

    render = sub.add_parser(
        "render",
        help="render an MP4 video continuing a run",
        description="Render an MP4 (top-down field + omni views + "
        "overlays) continuing a run from its newest checkpoint (or a "
        "given checkpoint file). The run directory is not modified.",
    )
    render.add_argument("dir", nargs="?", default=None, help="a run directory")
    render.add_argument("--checkpoint", default=None, help="a checkpoint file instead")
    render.add_argument("--out", required=True, help="output .mp4 file")
    render.add_argument(
        "--frames",
        type=_int_arg("--frames"),
        default=300,
        help="frames (one control step each by default; 300 = 30 s)",
    )
    render.add_argument("--fps", type=_int_arg("--fps"), default=10)
    render.add_argument("--steps-per-frame", type=_int_arg("--steps-per-frame"), default=1)
    render.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    render.set_defaults(func=_cmd_render)

    move = sub.add_parser(
        "transfer",
        help="seed a hardware-like colony with a run's fittest agents and keep evolving (Fig. 7)",
        description="Take the fittest individuals of one generation of a run (its checkpoint: "
        "evolve it with --keep-checkpoints 0), put them on --robots robots with "
        "--agents-per-robot virtual agents each, and continue embodied evolution, by default "
        "in the hardware-like profile (noisy IR and vision, per-robot motors, 3 robots and 6 "
        "packs). Writes a run directory with per-robot statistics and a Fig. 7-style figure.",
    )
    move.add_argument("--from", dest="source", required=True, help="source run directory")
    move.add_argument(
        "--generation", type=_int_arg("--generation"), default=40, help="source generation"
    )
    move.add_argument("--top", type=_int_arg("--top"), default=5, help="fittest individuals")
    move.add_argument("--robots", type=_int_arg("--robots"), default=3)
    move.add_argument("--agents-per-robot", type=_int_arg("--agents-per-robot"), default=5)
    move.add_argument(
        "--generations", type=_int_arg("--generations"), default=10, help="generations after"
    )
    move.add_argument(
        "--profile", default="hardware", choices=("hardware", "sim"), help="world profile"
    )
    move.add_argument("--seed", type=_int_arg("--seed"), default=0)
    move.add_argument("--out", required=True, help="new run directory")
    move.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    move.set_defaults(func=_cmd_transfer)
    return parser


def _user_errors() -> tuple[type[Exception], ...]:
    """Errors that are the user's to fix (one line, exit 2), the evolution side's included
    once it is loaded (called when an error is caught, so lazily imported modules count)."""
    from cyber_rodent.assets import AssetNotFoundError

    errors: tuple[type[Exception], ...] = (CliError, ValueError, AssetNotFoundError)
    if "evolution" not in sys.modules:
        return errors
    from evolution.checkpoint import CheckpointError
    from evolution.sweep import SweepFailed

    return (*errors, CheckpointError, SweepFailed)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    command: Callable[[argparse.Namespace], int] = args.func
    try:
        return command(args)
    except _user_errors() as err:
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
