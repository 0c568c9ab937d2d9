"""The ``cyber-rodent`` command line.

The only module that may tie the three packages (``cyber_rodent``, ``behaviours``, ``evolution``)
together; it imports them lazily inside each sub-command so ``--help`` stays fast. User errors
(bad counts, missing assets, unwritable outputs, malformed options) print one line,
``cyber-rodent COMMAND: error: ...``, and exit with status 2, never a traceback or a usage
block; every input is checked before a file or directory is created. ``--help`` shows every
option's default.

``--plugin MODULE_OR_FILE`` (``evolve``, ``resume``, ``sweep``, ``config``) loads a user's code
that registers a controller, an input or a task (:mod:`cyber_rodent.plugins`) before any other
option is checked, so ``--set evolution.controller=NAME`` accepts the controller it registers.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:  # pandas is slow to import; ``--help`` must stay fast
    import pandas as pd

    from cyber_rodent.plugins import Plugin

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class UsageError(CliError):
    """A malformed command line, found by the parser of ``prog`` (``cyber-rodent evolve``)."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(message)
        self.prog = prog


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Each option's default after its help, unless the help states it or there is none (a
    flag, an option unset by default)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if "default" in text or default is None or default is False or default == []:
            return text
        if default is argparse.SUPPRESS:
            return text
        return super()._get_help_string(action)


class CliParser(argparse.ArgumentParser):
    """The parser of the command and of each sub-command (``add_subparsers`` makes its
    sub-parsers of the parent's class): an error is one line, ``PROG: error: MESSAGE``, with
    exit status 2 and no usage block, and ``--help`` shows every default."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)
        #: The sub-commands' parsers by name (set by :func:`build_parser`).
        self.commands: Mapping[str, argparse.ArgumentParser] = {}

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        """An option without help still shows its default in ``--help``."""
        if kwargs.get("help") is None and args and str(args[0]).startswith("-"):
            default = kwargs.get("default")
            if default is not None and default is not False and default != []:
                kwargs["help"] = "(default: %(default)s)"
        return super().add_argument(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, message)


def _one_line(text: object) -> str:
    """``text`` on one line (a message from a library may span several)."""
    return " ".join(str(text).split())


def _int_arg(name: str) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None

    return parse


def _float_arg(name: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None

    return parse


def _cmd_snapshot(args: argparse.Namespace) -> int:
    import numpy as np

    from cyber_rodent.render import (
        BACKGROUND_RGB,
        FieldRenderer,
        annotate_world,
        check_writable_output,
        default_image_size,
        draw_caption,
        write_png,
    )
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
        background = None if args.plain else BACKGROUND_RGB
        size = default_image_size(config.extent) if args.size is None else args.size
        with FieldRenderer(world, size, size, background=background) as renderer:
            if args.robot is not None:
                image = renderer.robot_view(args.robot)
                if not args.plain:
                    draw_caption(image, f"CR{args.robot} chase view")
            else:
                image = renderer.top_down()
                if not args.plain:  # robot IDs (CRi = --robot i) and heading arrows
                    annotate_world(image, renderer)
        out = write_png(image, args.out)
    print(f"wrote {out}")
    return 0


def _cmd_train_behaviours(args: argparse.Namespace) -> int:
    from behaviours.definitions import spec
    from behaviours.inputs import BEHAVIOUR_NAMES
    from behaviours.training import check_episodes, has_goal, train
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
        from evolution.runner import RunConfig, settings

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


def _load_plugin(spec: str) -> Plugin:
    """Load one ``--plugin``; a plugin that cannot be found or fails is one line naming
    ``--plugin``."""
    from cyber_rodent.plugins import PluginError, load_plugin

    try:
        return load_plugin(spec)
    except PluginError as err:
        raise CliError(f"--plugin {err}") from None


def _load_plugins(args: argparse.Namespace) -> tuple[Plugin, ...]:
    """Load every ``--plugin`` of the command line, in order (before any setting is read)."""
    return tuple(_load_plugin(spec) for spec in args.plugin)


#: What plugins may register, by the word ``config`` lists them with.
_REGISTRY_KINDS = ("controller", "input", "task", "scheme")


def _registered() -> dict[str, tuple[str, ...]]:
    """The names in each registry plugins may add to, by :data:`_REGISTRY_KINDS`."""
    from cyber_rodent.tasks.spec import task_names
    from evolution.controllers import controller_names
    from evolution.input_kernels import available_inputs
    from evolution.schemes import scheme_names

    return {
        "controller": controller_names(),
        "input": tuple(row.name for row in available_inputs()),
        "task": task_names(),
        "scheme": scheme_names(),
    }


def _plugins_section(added: Sequence[tuple[Plugin, dict[str, tuple[str, ...]]]]) -> str:
    """The ``config`` listing of what each plugin registered, as TOML comments."""
    lines = [
        "# registered by plugins (a --config file names them, but does not load them: give the",
        "# same --plugin again wherever you use this file):",
    ]
    for plugin, names in added:
        found = [(kind, name) for kind in _REGISTRY_KINDS for name in names[kind]]
        if not found:
            lines.append(f"#   nothing registered by {plugin.name}")
        for kind, name in found:
            lines.append(f"#   {kind} {name}  (plugin {plugin.name})")
    return "\n".join(lines) + "\n"


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """The settings of ``--config FILE`` then ``--set KEY=VALUE`` (later ones win)."""
    from evolution.runner import settings

    from_file = settings.load_config_file(args.config) if args.config else {}
    return settings.merge(from_file, settings.parse_set(args.set))


def _cmd_config(args: argparse.Namespace) -> int:
    from evolution.lab.api import make_config
    from evolution.runner.settings import to_toml

    added: list[tuple[Plugin, dict[str, tuple[str, ...]]]] = []
    if args.plugin:
        before = _registered()
        for spec in args.plugin:
            plugin = _load_plugin(spec)
            after = _registered()
            new = {kind: tuple(n for n in after[kind] if n not in before[kind]) for kind in after}
            added.append((plugin, new))
            before = after
    config = make_config(args.method, **_settings(args))
    text = to_toml(config, method=args.method)
    if added:  # after the header: the file stays a valid --config file
        header, _, rest = text.partition("\n\n")
        text = f"{header}\n\n{_plugins_section(added)}\n{rest}"
    sys.stdout.write(text)
    return 0


def _cmd_evolve(args: argparse.Namespace) -> int:
    from evolution.lab import experiment

    plugins = _load_plugins(args)  # before the settings, which may name what they register
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
            max_steps=args.max_steps,
            progress=not args.no_progress,
            argv=sys.argv,
            tensorboard=args.tensorboard,
            plugins=plugins,
        )
    except KeyboardInterrupt:
        print(
            f"cyber-rodent: interrupted; continue with: cyber-rodent resume {out}", file=sys.stderr
        )
        return 130
    _report_run(path, table)
    if args.generations < 120:
        print(
            f"This was a short run ({_count(args.generations, 'generation')}). The paper's "
            "Fig. 6 experiment (20 seeds x EE and CE x 120 generations):\n  "
            f"{experiment.PAPER_COMMAND}"
        )
    return 0


def _count(n: int, noun: str) -> str:
    """``1 generation``, ``2 generations``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _report_run(path: Path, table: pd.DataFrame) -> None:
    if len(table):
        last = table.iloc[-1]
        print(
            f"{_count(len(table), 'generation')}; last generation: {int(last['completed'])} agents "
            f"completed the survival task, batteries {last['batteries_mean']:.1f}, "
            f"matings {last['matings_mean']:.2f}"
        )
    print(_watchdog_line(path))
    print(f"run directory: {path}  (statistics.csv, events.csv, figures/, checkpoints/)")


def _watchdog_line(path: Path) -> str:
    """What the watchdog saw in the run, in one line, naming the robots (from run.json)."""
    try:
        summary = json.loads((path / "run.json").read_text()).get("summary", {})
    except (OSError, ValueError):
        return "watchdog: no record"
    tips, jams = int(summary.get("tips", 0)), int(summary.get("jams", 0))
    if not tips and not jams:
        return "watchdog: no robot tipped over or got stuck"
    robots = ", ".join(map(str, summary.get("troubled_robots", [])))
    rescues = int(summary.get("rescues", 0))
    return (
        f"watchdog: {_count(tips, 'tip')} and {_count(jams, 'jam')} (robots {robots}), "
        f"{_count(rescues, 'rescue')}; see events.csv and watchdog.csv"
    )


def _cmd_transfer(args: argparse.Namespace) -> int:
    from cyber_rodent.profiles import profile_by_name
    from cyber_rodent.validation import check_integer
    from cyber_rodent.world import MAX_ROBOTS
    from evolution.config import MAX_GENERATIONS, MAX_POPULATION
    from evolution.lab.transfer import ROBOT_STATISTICS_FILE, transfer

    # The numbers and paths first: transfer() reads the source checkpoint before its own checks.
    check_integer("--generation", args.generation, 0, MAX_GENERATIONS)
    check_integer("--top", args.top, 1, MAX_POPULATION)
    check_integer("--robots", args.robots, 1, MAX_ROBOTS)
    check_integer("--agents-per-robot", args.agents_per_robot, 1, MAX_POPULATION // args.robots)
    check_integer("--generations", args.generations, 1, MAX_GENERATIONS)
    check_integer("--seed", args.seed, 0)
    source, out = Path(args.source), Path(args.out)
    if not source.is_dir():
        what = "is a file, not a run directory" if source.exists() else "no such run directory"
        raise CliError(f"--from {source}: {what}")
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out} is a file, not a directory")
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
    from cyber_rodent.plugins import PluginError, identify
    from evolution.lab import experiment

    given = None
    if args.plugin:  # found and hashed, not run: resume loads the run's recorded plugins
        try:
            given = [identify(spec) for spec in args.plugin]
        except PluginError as err:
            raise CliError(f"--plugin {err}") from None
    try:
        path, table = experiment.resume_run(
            args.dir,
            progress=not args.no_progress,
            generations=args.generations,
            tensorboard=args.tensorboard,
            plugins=given,
        )
    except KeyboardInterrupt:
        print(
            f"cyber-rodent: interrupted; continue with: cyber-rodent resume {args.dir}",
            file=sys.stderr,
        )
        return 130
    _report_run(path, table)
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


def _cmd_sweep(args: argparse.Namespace) -> int:
    from cyber_rodent.plugins import plugin_source
    from cyber_rodent.validation import check_integer
    from evolution.lab import experiment
    from evolution.lab.grid import check_grid
    from evolution.lab.sweep import (
        STEP_SECONDS,
        SweepSpec,
        check_ray_address,
        check_sweep_plugins,
        parse_seeds,
        projected_seconds,
        sweep,
    )
    from evolution.runner.settings import parse_grid

    plugins = _load_plugins(args)  # before the settings, which may name what they register
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    if args.max_steps is not None:
        from evolution.config import MAX_RUN_STEPS

        check_integer("--max-steps", args.max_steps, 1, MAX_RUN_STEPS)
    spec = SweepSpec(
        methods,
        parse_seeds(args.seeds),
        args.generations,
        _settings(args),
        policies=args.policies,
        grid=parse_grid(args.grid),
        max_steps=args.max_steps,
        plugins=tuple(plugin_source(plugin) for plugin in plugins),
    )
    if args.resume:  # the runs there were started with this grid and these plugins
        check_grid(args.out, spec.grid)
        check_sweep_plugins(args.out, spec)
    spec.check()  # every cell's settings, before anything is written
    experiment.policies_by_name(args.policies)  # the shipped values are installed
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
    try:
        results = sweep(
            spec,
            out,
            workers=args.workers,
            executor=executor,
            ray_address=args.ray or "local",
            progress=not args.no_progress,
            tensorboard=args.tensorboard,
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
    from evolution.lab import experiment

    if not Path(args.dir).is_dir():
        what = "is a file, not" if Path(args.dir).exists() else "is not"
        raise CliError(f"{args.dir} {what} a run or sweep directory")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise CliError(f"--out {args.out} is a file, not a directory")
    for path in experiment.plot_run_dir(args.dir, args.out):
        print(f"wrote {path}")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from evolution.lab import experiment, video

    if (args.dir is None) == (args.checkpoint is None):
        raise CliError("give a run directory or --checkpoint FILE (one of them)")
    # Every option is checked (one line naming it and its range) before any file is written.
    default = video.VideoConfig()
    width, height = (
        (default.width, default.height) if args.size is None else video.parse_size(args.size)
    )
    camera = video.parse_camera(args.camera)
    frames = video.parse_integer_option("--frames", args.frames, 1, video.MAX_FRAMES)
    source = args.dir if args.dir is not None else args.checkpoint
    if args.start is not None:
        start = video.parse_integer_option("--start", args.start, 0, float("inf"))
        if args.dir is None:
            raise CliError("--start picks a run directory's checkpoint; give DIR, not --checkpoint")
        source = video.start_checkpoint(args.dir, start)
    robots = video.run_robot_count(source)
    if robots is not None:  # else the video checks it once the checkpoint is loaded
        video.check_camera_robot(camera, robots)
    out = experiment.render_run(
        source,
        args.out,
        frames=frames,
        fps=args.fps,
        steps_per_frame=args.steps_per_frame,
        progress=not args.no_progress,
        width=width,
        height=height,
        camera=str(camera),
    )
    print(f"wrote {out}")
    return 0


_NO_PROGRESS = "no progress output (a bar on a terminal, otherwise a line a minute on stderr)"


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


def _add_plugin_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--plugin",
        action="append",
        metavar="MODULE_OR_FILE",
        default=[],
        help="load your code first: a module (mylab.controllers) or a .py file that registers "
        f"a controller, an input or a task when imported (repeatable); {what}",
    )


def _add_max_steps(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-steps",
        type=_int_arg("--max-steps"),
        default=None,
        help="stop a run after this many control steps in all, even if its generations are "
        "not complete: a budget for populations that may never complete one (agents that "
        "learn from zero die before they mate); resume keeps it (default: no budget)",
    )


def _add_tensorboard(p: argparse.ArgumentParser, where: str) -> None:
    p.add_argument(
        "--tensorboard",
        default=None,
        metavar="DIR",
        help=f"write each generation's statistics and the population's weights to TensorBoard "
        f"as it closes, {where}; watch with `tensorboard --logdir DIR` (needs "
        "pip install 'cyber-rodent[monitor]'; results are unchanged)",
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
    p.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS)


#: Sub-commands whose options and entry point live in their own module,
#: ``add_arguments(parser)`` and ``run(args) -> int``: name → (module, one-line summary).
MOUNTED: dict[str, tuple[str, str]] = {
    "view": (
        "evolution.lab.viewer",
        "watch a run, a checkpoint or a task live in MuJoCo's interactive viewer",
    ),
    "deploy": (
        "evolution.lab.deploy.__main__",
        "write a deployment bundle of a run's fittest mated agents for a real robot",
    ),
    "export": (
        "behaviours.export",
        "export the learned behaviours as torch.export programs (.pt2)",
    ),
}


def _command_of(argv: Sequence[str]) -> str | None:
    """The sub-command of a command line: its first word that is not an option."""
    return next((word for word in argv if not word.startswith("-")), None)


def build_parser(command: str | None = None) -> CliParser:
    """The command-line parser; ``command`` (a :data:`MOUNTED` name) also gets its options."""
    parser = CliParser(
        prog="cyber-rodent",
        description="Cyber Rodent colony simulation: embodied evolution of survival in MuJoCo.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    parser.commands = sub.choices

    snap = sub.add_parser(
        "snapshot",
        help="render a seeded world to PNG (top-down field, a robot's view, or its omni image)",
        description="Render a seeded world off-screen and write a PNG.",
    )
    snap.add_argument("--out", required=True, help="output PNG file")
    snap.add_argument("--seed", type=_int_arg("--seed"), default=0, help="placement seed")
    snap.add_argument("--robots", type=_int_arg("--robots"), default=4, help="number of robots")
    snap.add_argument("--packs", type=_int_arg("--packs"), default=5, help="number of packs")
    snap.add_argument(
        "--field-size",
        type=_float_arg("--field-size"),
        default=2.3,
        help="side of the square field in m (the paper's: 2.3; at its density N robots need "
        "2.3 x sqrt(N / 4), e.g. --robots 100 --packs 125 --field-size 11.5)",
    )
    snap.add_argument(
        "--arenas",
        type=_int_arg("--arenas"),
        default=1,
        help="copies of the field side by side, each with its own walls, --robots / N robots "
        "and --packs / N packs (the paper's: 1; 25 copies of its world: --robots 100 --packs "
        "125 --arenas 25)",
    )
    snap.add_argument(
        "--size",
        type=_int_arg("--size"),
        default=None,
        help="image side in px (default: 640 for the paper's 2.3 m field, growing with the "
        "field to keep its pixels per metre, up to 2048)",
    )
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
    snap.add_argument(
        "--plain",
        action="store_true",
        help="the bare render: no robot IDs (CRi = robot i), heading arrows or caption, and "
        "empty space left black",
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
    train.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS)
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
    evolve.add_argument(
        "--method",
        default="ee",
        help="the evolution scheme: ee, embodied evolution; ce, the centralised GA (the "
        "paper's baseline); medea, mEDEA (one agent per robot); or one a plugin registered",
    )
    evolve.add_argument(
        "--generations",
        type=_int_arg("--generations"),
        default=5,
        help="generations to complete (default 5; the paper: 120)",
    )
    evolve.add_argument("--seed", type=_int_arg("--seed"), default=0, help="the run's seed")
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
    _add_max_steps(evolve)
    _add_tensorboard(evolve, "in DIR/<name of --out>")
    _add_plugin_option(evolve, "run.json records each one's name and content hash")
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
    _add_tensorboard(resume, "in DIR/<name of the run directory>")
    _add_plugin_option(
        resume,
        "resume loads the plugins run.json records by itself (refusing one that is missing or "
        "changed); where given, these must be the same",
    )
    resume.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS)
    resume.set_defaults(func=_cmd_resume)

    sweep = sub.add_parser(
        "sweep",
        help="many runs (grid cells x methods x seeds) in parallel: local processes or Ray",
        description="Run every method x seed (x grid cell), one process per run (or one Ray "
        "task per run with --ray), each in <out>/<method>-seed<NNN> (with --grid: "
        "<out>/<cell>/<method>-seed<NNN>); failed runs are retried from their last "
        "checkpoint. Results are identical whichever executor ran them. With only --out it "
        "runs the paper's Fig. 6 experiment (EE and CE x seeds 0-19 x 120 generations: "
        "hours); the projected run time is printed before the runs start.",
    )
    sweep.add_argument(
        "--methods", default="ee,ce", help="comma list of schemes (ee, ce, medea, a plugin's)"
    )
    sweep.add_argument("--seeds", default="0-19", help="seeds: N, A-B or a comma list")
    sweep.add_argument(
        "--generations",
        type=_int_arg("--generations"),
        default=120,
        help="generations per run (the paper: 120)",
    )
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
        help="run on Ray: auto, HOST:PORT, ray://HOST:PORT, or local (default: local "
        "processes, no Ray)",
    )
    sweep.add_argument(
        "--grid",
        action="append",
        metavar="KEY=V1,V2,...",
        default=[],
        help="a grid axis, e.g. --grid survival.reflex_max_steps=4,8,16 (repeatable: every "
        "cell of the product runs every method and seed)",
    )
    _add_max_steps(sweep)
    _add_tensorboard(sweep, "each run in DIR/<method>-seed<NNN> (with --grid: DIR/<cell>/...)")
    _add_plugin_option(
        sweep,
        "every worker (local or Ray) loads it from its text, and each run.json records it",
    )
    _add_run_options(sweep)
    sweep.set_defaults(func=_cmd_sweep)

    config = sub.add_parser(
        "config",
        help="print every setting, resolved, as commented TOML (a valid --config file)",
        description="Print the resolved configuration (the paper's defaults, then --config, "
        "then --set) as TOML: each setting with its meaning, allowed range, unit and source.",
    )
    config.add_argument(
        "--method", default="ee", help="the scheme the config is for (ee, ce, medea, ...)"
    )
    _add_plugin_option(config, "lists what each one registered")
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
    plot.add_argument("dir", help="a run directory, a sweep directory or published run tables")
    plot.add_argument(
        "--out", default=None, help="directory for the figures and tables (default: DIR/figures)"
    )
    plot.set_defaults(func=_cmd_plot)

    render = sub.add_parser(
        "render",
        help="render an MP4 video continuing a run",
        description="Render an MP4 continuing a run from its newest checkpoint (or the "
        "checkpoint of generation --start, or a given checkpoint file): the top-down field "
        "with robot labels (CRi = robot i), heading arrows, docking and mating marks, the "
        "robots' omni camera strips, and a legend of every colour and mark in each frame. "
        "The run directory is not modified.",
    )
    render.add_argument("dir", nargs="?", default=None, help="a run directory")
    render.add_argument("--checkpoint", default=None, help="a checkpoint file instead")
    render.add_argument("--out", required=True, help="output .mp4 file")
    render.add_argument(
        "--frames",
        default="300",
        metavar="N",
        help="number of frames, in [1, 100000] (one control step each by default; 300 = 30 s "
        "at 10 fps)",
    )
    render.add_argument(
        "--size",
        default=None,
        metavar="WxH",
        help="frame size in px (default 1280x720): even W and H, H in [480, 2160], W in "
        "[H + 256, 3840]",
    )
    render.add_argument(
        "--camera",
        default="top",
        metavar="VIEW",
        help="top (field from above + every robot's omni strip; the default), chase:N (robot "
        "N's chase view) or omni:N (robot N's omni strip across the frame); N a robot index",
    )
    render.add_argument(
        "--start",
        default=None,
        metavar="G",
        help="begin where generation G closed, from the run directory's checkpoint of "
        "generation G (default: the newest checkpoint; evolve with --keep-checkpoints 0 to "
        "keep every generation)",
    )
    render.add_argument(
        "--fps",
        type=_int_arg("--fps"),
        default=10,
        help="frames per second of the MP4, 1-120 (default 10). A frame is drawn every "
        "--steps-per-frame control steps of 0.2 s, so with 1 step per frame 5 fps plays in "
        "real time and 10 fps at twice real time",
    )
    render.add_argument(
        "--steps-per-frame",
        type=_int_arg("--steps-per-frame"),
        default=1,
        help="control steps simulated between two frames, 1-1000 (default 1); raise it to "
        "show more of a run in a shorter video",
    )
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
    move.add_argument(
        "--robots", type=_int_arg("--robots"), default=3, help="robots of the new colony"
    )
    move.add_argument(
        "--agents-per-robot",
        type=_int_arg("--agents-per-robot"),
        default=5,
        help="virtual agents per robot",
    )
    move.add_argument(
        "--generations", type=_int_arg("--generations"), default=10, help="generations after"
    )
    move.add_argument(
        "--profile", default="hardware", choices=("hardware", "sim"), help="world profile"
    )
    move.add_argument("--seed", type=_int_arg("--seed"), default=0, help="the new run's seed")
    move.add_argument("--out", required=True, help="new run directory")
    move.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS)
    move.set_defaults(func=_cmd_transfer)

    for name, (module, summary) in MOUNTED.items():
        mounted = sub.add_parser(name, help=summary, description=summary)
        if name == command:  # only the command being run imports its module (torch, GL)
            entry = importlib.import_module(module)
            entry.add_arguments(mounted)
            mounted.set_defaults(func=entry.run)
    return parser


def _user_errors() -> tuple[type[Exception], ...]:
    """Errors that are the user's to fix (one line, exit 2), the evolution side's included
    once it is loaded (called when an error is caught, so lazily imported modules count)."""
    from cyber_rodent.assets import AssetNotFoundError

    errors: tuple[type[Exception], ...] = (CliError, ValueError, AssetNotFoundError)
    if "evolution" not in sys.modules:
        return errors
    from evolution.checkpoint import CheckpointError
    from evolution.lab.sweep import SweepFailed

    return (*errors, CheckpointError, SweepFailed)


def _print_error(prog: str, message: object) -> int:
    """Print ``PROG: error: MESSAGE`` as one line on stderr; the usage exit status."""
    print(f"{prog}: error: {_one_line(message)}", file=sys.stderr, flush=True)
    return EXIT_USAGE


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); its exit status."""
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command_of(words))
    try:
        args, extra = parser.parse_known_args(words)
    except UsageError as err:
        return _print_error(err.prog, err)
    prog = f"{parser.prog} {args.command}"
    if extra:
        return _print_error(prog, f"unrecognized arguments: {' '.join(extra)}")
    command: Callable[[argparse.Namespace], int] = args.func
    try:
        return command(args)
    except _user_errors() as err:
        return _print_error(prog, err)
    except OSError as err:
        where = f": {err.filename}" if err.filename else ""
        return _print_error(prog, f"{err.strerror or err}{where}")
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
