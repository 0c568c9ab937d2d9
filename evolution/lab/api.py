"""Run embodied evolution or the centralised GA in one call.

::

    from evolution.lab import run
    table = run(method="ee", generations=5, seed=0)  # a DataFrame, one row per generation
    table = run(method="ce", generations=5, seed=0, out_dir="runs/ce0", population_size=20)

A run is two objects: :class:`RunSpec`, what it runs (the method, generations, seed, the
config and its overrides, the behaviours, a step budget, the plugins), and :class:`RunOutput`,
where its results go (the run directory, the checkpoint cadence and how many to keep,
TensorBoard, a progress bar). :func:`execute` runs a spec into an output; :func:`run` is the
short form above, which builds them::

    from evolution.lab.api import RunOutput, RunSpec, execute
    spec = RunSpec("ce", 5, seed=0, overrides={"population_size": 20}, max_steps=50_000)
    table = execute(spec, RunOutput("runs/ce0", keep_checkpoints=0, progress=True))

:func:`execute` builds a :class:`~evolution.runner.RunConfig` from the paper's defaults plus
any overrides, runs :class:`~evolution.runner.EvolutionRunner` and returns its per-generation
statistics. With an output directory it also writes, atomically:

- ``statistics.csv``: the table (after every checkpoint and at the end);
- ``statistics_per_robot.csv``: per generation and robot, mean batteries over the robot's full
  lifetimes with unmated agents scored 0 (the paper's Fig. 7 measure);
- ``events.csv``: the event log (dockings, recharge ends, matings, deaths, births, and what
  the watchdog saw: robots tipped over or stuck, rescues);
- ``watchdog.csv``: per generation, the tips and jams that began, the robot-steps spent
  tipped and stuck, rescues and the robots concerned;
- ``statistics_per_arena.csv``: with several arenas (``world.arenas``), per generation and
  arena, the full lifetimes, completed agents and mean batteries of its robots;
- ``run.json``: config, seed, behaviour policies, versions and headline numbers;
- ``checkpoints/gen_NNNNN.ckpt``: the complete state every ``checkpoint_every`` generations.

``RunOutput(tensorboard=DIR)`` also writes each generation's statistics and the population's
weights into TensorBoard event files in ``DIR`` as the generation closes
(:mod:`evolution.lab.monitor`; the extra ``monitor``), with or without a directory; the results
are the same either way.

``resume=True`` continues from the newest checkpoint in the output directory (the run's config,
seed and behaviour policies must match, else a :class:`~evolution.checkpoint.CheckpointError`
and nothing is touched); the result is bit-identical to an uninterrupted run. Without
``resume`` a directory that already holds a run is refused, so results are never overwritten
by accident.

``RunSpec(plugins=(...))`` names the plugins (:mod:`cyber_rodent.plugins`) whose code the run
uses (a controller, an input, a task they register): they are loaded first where this process
has not loaded them yet, and ``run.json`` records each one's name, kind and content hash (runs
without plugins keep the record they always had). A run is continued only with the plugins it
records.

The spec and the output are bundles of arguments, checked by the function that receives them
(:func:`execute` here, :func:`evolution.lab.experiment.evolve` with the command line's names
and bounds), not configs: a method can be checked only once the plugins that register it are
loaded.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import os
import subprocess
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from behaviours import BehaviourPolicies
from behaviours.inputs import BEHAVIOUR_NAMES
from cyber_rodent.atomic import atomic_output, remove_stale_temporaries, write_text
from cyber_rodent.plugins import Plugin, ensure_loaded, plugin_records, plugins_from_records, short
from cyber_rodent.validation import check_integer
from evolution.config import EvolutionConfig
from evolution.lab.monitor import TensorBoardMonitor, check_tensorboard
from evolution.runner import (
    EvolutionRunner,
    RunConfig,
    default_policies,
    latest_checkpoint,
    policy_identity,
)
from evolution.runner.settings import FLAT_KEYS, apply, changed, settings
from evolution.schemes import scheme

if TYPE_CHECKING:
    import pandas as pd

#: Keyword overrides :func:`run` and :func:`make_config` accept: every dotted key of
#: :mod:`evolution.runner.settings` (``survival.mate_distance``) and the flat names of earlier
#: versions (``population_size``).
OVERRIDES = tuple(sorted({*settings(), *FLAT_KEYS}))

STATISTICS_FILE = "statistics.csv"
VERSIONS_FILE = "versions.json"
ROBOT_STATISTICS_FILE = "statistics_per_robot.csv"
ROBOT_COLUMNS = ("generation", "robot", "batteries_mean", "full_lifetimes", "completed")
EVENTS_FILE = "events.csv"
#: Learning mode's per-generation table: within-life captures and matings by age, and the
#: evolved learning parameters (:meth:`evolution.learning.LifetimeLearning.record_rows`).
LEARNING_FILE = "learning.csv"
RUN_FILE = "run.json"
CHECKPOINT_DIR = "checkpoints"
#: The basic behaviours by name: the shipped trained values, the hand-written baseline.
POLICY_NAMES = ("trained", "reactive")


@dataclass(frozen=True)
class RunSpec:
    """What one run runs: its scheme, length and seed, its settings, the behaviours under its
    controllers, a step budget and the plugins whose code it uses."""

    method: str = "ee"
    """the evolution scheme: ``"ee"`` (embodied evolution), ``"ce"`` (the centralised GA),
    ``"medea"`` or one registered (:mod:`evolution.schemes`)"""
    generations: int = 120
    """generations to complete (the paper: 120)"""
    seed: int = 0
    """the run's seed; the same seed, config and policies give identical results"""
    config: RunConfig | EvolutionConfig | None = None
    """the base configuration (None: the paper's, Tables 1 and 2)"""
    overrides: Mapping[str, Any] = field(default_factory=dict)
    """settings over ``config`` by dotted key (``{"survival.mate_distance": 0.4}``) or by the
    flat names of earlier versions (``{"population_size": 20}``); see :func:`make_config`"""
    policies: BehaviourPolicies | str = "trained"
    """the basic behaviours: ``"trained"`` (the shipped values), ``"reactive"`` (the
    hand-written baseline), a directory of trained values (:func:`check_policies`) or the
    policies themselves"""
    max_steps: int | None = None
    """stop after this many world control steps in all, even if the generations are not
    complete (None: no budget)"""
    plugins: Sequence[Plugin] = ()
    """the plugins the run uses: loaded first where they are not yet (so ``overrides`` may
    name what they register) and recorded in ``run.json``; to continue a run, those its
    record names"""


@dataclass(frozen=True)
class RunOutput:
    """Where a run's results go, which of its checkpoints are kept, and what is shown while
    it runs."""

    directory: str | os.PathLike[str] | None = None
    """the run directory: ``statistics.csv``, ``events.csv``, ``run.json`` and checkpoints
    (None: everything stays in memory, without checkpoints)"""
    checkpoint_every: int = 1
    """generations between checkpoints"""
    keep_checkpoints: int = 3
    """newest checkpoints to keep (0: every one)"""
    tensorboard: str | os.PathLike[str] | None = None
    """a TensorBoard directory, written as each generation closes (:mod:`evolution.lab.monitor`;
    needs the extra ``monitor``; checked before anything is created; a resumed run starts a
    new event file, each generation appearing once): :func:`execute` writes into it,
    ``evolve`` and ``resume`` into ``DIR/<name of the run directory>``, a sweep into
    ``DIR/<method>-seed<NNN>``, so that runs sharing it are overlaid"""
    progress: bool = False
    """show a progress bar (a line a minute where stderr is no terminal)"""


def check_policies(name: object) -> str:
    """``name`` if it names basic behaviours: ``"trained"``, ``"reactive"``, or a directory
    holding the three behaviours' trained values (``mate.npz``, ``forage.npz``, ``search.npz``,
    as ``train-behaviours --out DIR`` writes them: behaviours trained for another robot body).

    Raises:
        ValueError: anything else, in one line.
    """
    if isinstance(name, str) and name in POLICY_NAMES:
        return name
    if isinstance(name, str | os.PathLike) and all(
        (Path(name) / f"{behaviour}.npz").is_file() for behaviour in BEHAVIOUR_NAMES
    ):
        return str(name)
    raise ValueError(
        f"policies must be {' or '.join(POLICY_NAMES)} or a directory with "
        f"{', '.join(f'{b}.npz' for b in BEHAVIOUR_NAMES)} (train-behaviours --out DIR), "
        f"got {name!r}"
    )


def policies_by_name(name: str) -> BehaviourPolicies:
    """``"trained"`` (the shipped values), ``"reactive"`` (the hand-written baseline) or a
    directory of trained values (:func:`check_policies`).

    Raises:
        ValueError: another name, or values that do not load.
        FileNotFoundError: ``"trained"`` and the trained values are not installed.
    """
    name = check_policies(name)
    if name == "trained":
        return default_policies()
    if name == "reactive":
        return BehaviourPolicies.reactive()
    return BehaviourPolicies.from_directory(name)


def make_config(
    method: str = "ee", config: RunConfig | EvolutionConfig | None = None, **overrides: Any
) -> RunConfig:
    """A :class:`RunConfig`: ``config`` (default: the paper's) with ``method`` and overrides.

    Args:
        method: the evolution scheme: ``"ee"``, ``"ce"``, ``"medea"`` or a registered one
            (:mod:`evolution.schemes`), checked against the config the overrides make.
        config: a base run or evolution config.
        **overrides: settings by dotted key (``**{"survival.mate_distance": 0.4}``) or by the
            flat names of earlier versions (``population_size=20``); see
            :mod:`evolution.runner.settings`.

    Raises:
        ValueError: an unknown method or override name (the message names the closest valid
            keys), or an invalid value (the message names the key and its allowed range).
    """
    scheme(method)  # an unknown scheme, in one line listing them
    # The settings first, under the paper's EE (which takes any colony), then the scheme, which
    # is checked against the config the settings made (mEDEA wants one agent per robot).
    if config is None:
        base = RunConfig()
    elif isinstance(config, EvolutionConfig):
        base = RunConfig(evolution=config)
    elif isinstance(config, RunConfig):
        base = config.replace(method="ee")
    else:
        raise ValueError(f"config must be a RunConfig or EvolutionConfig, got {type(config)!r}")
    return apply(base, overrides).replace(method=method)


def check_run_config(config: RunConfig) -> None:
    """Refuse a config whose run could not be built, before anything is allocated or written.

    Every field is already within its own bounds; what is left are the sizes of several fields
    together: rendered vision draws every robot's strip into one off-screen buffer.

    Raises:
        ValueError: the strips of all robots do not fit one buffer (the message names the
            camera's resolution and the robot count).
    """
    if config.vision == "rendered":
        from cyber_rodent.vision.rendering import strips_buffer_size

        strips_buffer_size(config.camera, config.world.n_robots)


def run(
    method: str = "ee",
    generations: int = 120,
    seed: int = 0,
    *,
    config: RunConfig | EvolutionConfig | None = None,
    out_dir: str | os.PathLike[str] | None = None,
    policies: BehaviourPolicies | str = "trained",
    resume: bool = False,
    plugins: Sequence[Plugin] = (),
    **overrides: Any,
) -> pd.DataFrame:
    """Run EE or CE for ``generations`` generations and return the statistics table: the short
    form of :func:`execute`, with the fields of :class:`RunSpec` it names and ``out_dir`` as
    the output directory. The checkpoint cadence, how many checkpoints to keep, a step budget,
    TensorBoard and a progress bar are fields of :class:`RunSpec` and :class:`RunOutput`: build
    them and call :func:`execute`.

    Args:
        method: ``"ee"`` (embodied evolution), ``"ce"`` (centralised GA) or another scheme.
        generations: generations to complete (the paper: 120).
        seed: the run's seed.
        config: base configuration (default: the paper's).
        out_dir: the run directory (None: in memory only).
        policies: ``"trained"``, ``"reactive"`` or the basic behaviours themselves.
        resume: continue the run in ``out_dir``.
        plugins: the plugins the run uses.
        **overrides: config fields, see :func:`make_config`.
    """
    spec = RunSpec(method, generations, seed, config, overrides, policies, plugins=plugins)
    return execute(spec, RunOutput(out_dir), resume=resume)


def execute(
    spec: RunSpec,
    output: RunOutput | None = None,
    *,
    resume: bool = False,
    versions: Mapping[str, Any] | None = None,
) -> pd.DataFrame:
    """Run ``spec`` into ``output`` and return the statistics table.

    Args:
        spec: what to run (the method, generations, seed, settings, behaviours, budget,
            plugins).
        output: where the results go (default: nowhere; only the table is returned).
        resume: continue from the newest checkpoint in ``output.directory`` (from scratch if
            it has none).
        versions: with a directory: a record of the software environment, written as
            ``versions.json`` once the run is built, just before ``run.json`` (so a run that
            fails to start leaves no directory behind).

    Returns:
        One row per completed generation (see :meth:`EvolutionRunner.statistics`).

    Raises:
        ValueError: bad arguments or overrides (population not divisible by robots,
            probabilities outside [0, 1], unknown policies, ...), or a directory holding
            another run without ``resume``, or a ``tensorboard`` directory that cannot be
            written or without the ``tensorboard`` package, or ``resume`` with other plugins
            than the run records.
        PluginError: a plugin is missing, changed or fails to load
            (:class:`cyber_rodent.plugins.PluginError`, a ``ValueError``).
        CheckpointError: ``resume`` found a corrupt or incompatible checkpoint (nothing is
            modified).
        FileNotFoundError: the trained behaviours are asked for and not installed.
    """
    output = output if output is not None else RunOutput()
    plugins = tuple(spec.plugins)
    for plugin in plugins:
        ensure_loaded(plugin)
    run_config = make_config(spec.method, spec.config, **spec.overrides)
    check_run_config(run_config)
    generations, max_steps = spec.generations, spec.max_steps
    if isinstance(generations, bool) or not isinstance(generations, int) or generations < 0:
        raise ValueError(f"generations must be an integer in [0, ∞), got {generations!r}")
    check_integer("checkpoint_every", output.checkpoint_every, 1)
    check_integer("keep_checkpoints", output.keep_checkpoints, 0)
    if max_steps is not None:
        check_integer("max_steps", max_steps, 0)
    board = (
        check_tensorboard(output.tensorboard, "tensorboard")
        if output.tensorboard is not None
        else None
    )
    policies = (
        policies_by_name(spec.policies) if isinstance(spec.policies, str) else spec.policies
    )
    progress = output.progress
    if output.directory is None:
        if resume:
            raise ValueError("resume=True needs the out_dir of the run to continue")
        with (
            EvolutionRunner(run_config, spec.seed, policies) as runner,
            monitoring(board, runner) as monitor,
        ):
            return runner.run(
                generations, max_steps=max_steps, progress=progress, on_generation=monitor
            )

    out = Path(output.directory)
    checkpoints = out / CHECKPOINT_DIR
    newest = latest_checkpoint(checkpoints)
    previous = read_record(out / RUN_FILE) if resume else None
    if previous is not None:
        check_plugins(previous, plugins, out / RUN_FILE)
    if resume and newest is not None:
        remove_stale_temporaries(checkpoints)
        runner = EvolutionRunner.from_checkpoint(
            newest, policies, expect=(run_config, spec.seed)
        )
    else:
        if not resume and holds_a_run(out):
            raise ValueError(
                f"out_dir {out} already holds a run ({RUN_FILE} or checkpoints); pass "
                "resume=True to continue it, or choose an empty directory"
            )
        runner = EvolutionRunner(run_config, spec.seed, policies)
    with runner:
        if previous is not None and is_final_record(
            previous, runner, generations, max_steps, plugins
        ):
            # Finished and fully written: every file stays as it is, the record included, so
            # it keeps the commit that made the run.
            return runner.statistics()
        earlier = earlier_commits(previous)
        out.mkdir(parents=True, exist_ok=True)
        if versions is not None:
            text = json.dumps(versions, indent=2, sort_keys=True, default=repr) + "\n"
            write_text(out / VERSIONS_FILE, text)
        _write_json(out / RUN_FILE, run_record(runner, generations, max_steps, earlier, plugins))
        with monitoring(board, runner) as monitor:

            def write_results(r: EvolutionRunner) -> None:
                write_tables(out, r.statistics(), robot_table(r), learning_table(r),
                             extra_tables(r))  # fmt: skip
                if monitor is not None:
                    monitor(r)

            table = runner.run(
                generations,
                checkpoint_dir=checkpoints,
                checkpoint_every=output.checkpoint_every,
                keep_checkpoints=output.keep_checkpoints,
                max_steps=max_steps,
                progress=progress,
                on_generation=write_results,
            )
        write_tables(
            out, table, robot_table(runner), learning_table(runner), extra_tables(runner)
        )
        with atomic_output(out / EVENTS_FILE) as temp:
            runner.events.write_csv(temp)
        _write_json(out / RUN_FILE, run_record(runner, generations, max_steps, earlier, plugins))
    return table


@contextlib.contextmanager
def monitoring(
    board: Path | None, runner: EvolutionRunner
) -> Iterator[TensorBoardMonitor | None]:
    """A TensorBoard monitor of ``runner`` writing into ``board`` from the generation it
    stands at (None without ``board``), closed on exit."""
    if board is None:
        yield None
        return
    with TensorBoardMonitor(board, runner.completed_generations) as monitor:
        yield monitor


def robot_table(runner: EvolutionRunner) -> pd.DataFrame:
    """Per generation and robot: batteries_mean (unmated agents scored 0), full_lifetimes,
    completed — the table Fig. 7 plots (:class:`evolution.stats.RobotGenerationStats`)."""
    import pandas as pd

    return pd.DataFrame(runner.scheduler.stats.robot_records(), columns=list(ROBOT_COLUMNS))


#: Per generation, what the watchdog saw (:meth:`evolution.runner.events.EventLog.watchdog`).
WATCHDOG_FILE = "watchdog.csv"
#: Per generation and arena, in a world of several arenas (``world.arenas``).
ARENA_STATISTICS_FILE = "statistics_per_arena.csv"


def extra_tables(runner: EvolutionRunner) -> list[tuple[str, pd.DataFrame]]:
    """The run's tables beside ``statistics.csv``: the watchdog's per generation (tips and
    jams that began, robot-steps tipped and stuck, rescues, robots concerned) and, with
    several arenas, the statistics per arena (full lifetimes, completed agents and mean
    batteries of the arena's robots, from ``statistics_per_robot.csv``)."""
    import pandas as pd

    tables = [(WATCHDOG_FILE, pd.DataFrame(
        runner.events.watchdog(runner.generation_steps),
        columns=["generation", "tips", "jams", "rescues", "tipped_steps", "stuck_steps", "robots"],
    ))]  # fmt: skip
    world = runner.config.world
    if world.arenas > 1:
        robots = robot_table(runner)
        robots["arena"] = robots["robot"] // world.robots_per_arena
        robots["battery_sum"] = robots["batteries_mean"] * robots["full_lifetimes"]
        per_arena = robots.groupby(["generation", "arena"], as_index=False)[
            ["full_lifetimes", "completed", "battery_sum"]
        ].sum()
        lives = per_arena["full_lifetimes"].where(per_arena["full_lifetimes"] > 0)
        per_arena["batteries_mean"] = per_arena.pop("battery_sum") / lives
        tables.append((ARENA_STATISTICS_FILE, per_arena))
    return tables


def learning_table(runner: EvolutionRunner) -> pd.DataFrame | None:
    """Learning mode's per-generation table (None outside learning mode)."""
    import pandas as pd

    if runner.learning is None:
        return None
    table = pd.DataFrame(runner.learning.record_rows())
    if len(table):
        # Lives of generations the run has not closed yet (slots run ahead) are a partial count.
        table.insert(2, "closed", table["generation"] < runner.completed_generations)
    return table


def holds_a_run(out: Path) -> bool:
    """Does ``out`` already hold a run (a run record or a checkpoint)?"""
    return (out / RUN_FILE).exists() or latest_checkpoint(out / CHECKPOINT_DIR) is not None


def run_record(
    runner: EvolutionRunner,
    generations: int,
    max_steps: int | None = None,
    earlier: Sequence[str] = (),
    plugins: Sequence[Plugin] = (),
) -> dict[str, Any]:
    """The content of ``run.json``: config, the settings changed from the paper's defaults,
    seed, policies, target (generations, and the step budget if one was set), versions and
    source commit, summary, and the plugins the run loaded.

    ``earlier``: the other commits that advanced the run before this one, oldest first
    (:func:`earlier_commits`); recorded as ``versions.earlier_commits`` when there are any.
    ``plugins``: recorded as ``plugins``, a list of ``{"name", "kind", "sha256"}``
    (:meth:`cyber_rodent.plugins.Plugin.record`), when there are any.
    """
    record: dict[str, Any] = {
        "config": dataclasses.asdict(runner.config),
        "settings": changed(runner.config),
        "seed": runner.seed,
        "policies": policy_identity(runner.policies),
        "target_generations": generations,
        "versions": {
            "cyber-rodent": package_version(),
            "git_commit": source_commit(),
            "mujoco": mujoco.__version__,
            "numpy": np.__version__,
        },
        "summary": runner.summary(),
    }
    if max_steps is not None:  # runs without a budget keep the record they always had
        record["max_steps"] = max_steps
    if earlier:  # a run resumed under other code says so
        record["versions"]["earlier_commits"] = list(earlier)
    if plugins:  # runs without plugins keep the record they always had
        record["plugins"] = plugin_records(plugins)
    return record


def recorded_plugins(record: Mapping[str, Any], where: Path | str = RUN_FILE) -> tuple[Plugin, ...]:
    """The plugins a run record names (none for a record without ``plugins``).

    Raises:
        ValueError: its ``plugins`` is malformed (the message names ``where``).
    """
    return plugins_from_records(record.get("plugins"), f"{where}: plugins")


def describe_plugins(plugins: Sequence[Plugin]) -> str:
    """Plugins in words, for messages: ``a.py (sha256 0123456789ab), mylab.x (...)``."""
    if not plugins:
        return "none"
    return ", ".join(f"{p.name} (sha256 {short(p.sha256)})" for p in plugins)


def check_plugins(record: Mapping[str, Any], plugins: Sequence[Plugin], where: Path) -> None:
    """Refuse to continue the run of ``record`` with other plugins than it records (the
    order they are given in does not count).

    Raises:
        ValueError: one line naming ``where``, the recorded plugins and the given ones.
    """
    recorded = recorded_plugins(record, where)
    if set(recorded) != set(plugins):
        raise ValueError(
            f"{where} records the plugins {describe_plugins(recorded)}, but this run was given "
            f"{describe_plugins(plugins)}; continue a run with the plugins it was started with"
        )


def read_record(path: Path) -> dict[str, Any] | None:
    """The run record at ``path``; None if it is missing or unreadable."""
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def earlier_commits(previous: Mapping[str, Any] | None) -> list[str]:
    """The commits that advanced a run before the code now resuming it, oldest first: those
    the ``previous`` record lists, then the commit that wrote it, where it differs from this
    code's commit (a run resumed under the same commit adds nothing)."""
    if previous is None:
        return []
    versions = previous.get("versions") or {}
    commits = [str(c) for c in versions.get("earlier_commits") or ()]
    last = versions.get("git_commit")
    if last is not None and (not commits or commits[-1] != last):
        commits.append(str(last))
    current = source_commit()
    return commits[:-1] if commits and commits[-1] == current else commits


def is_final_record(
    previous: Mapping[str, Any],
    runner: EvolutionRunner,
    generations: int,
    max_steps: int | None,
    plugins: Sequence[Plugin] = (),
) -> bool:
    """Is ``previous`` the final record of the run ``runner`` was restored to: the run reached
    its target (or spent its step budget) and the record, written last, says exactly that?"""
    summary = runner.summary()
    done = runner.completed_generations >= generations or (
        max_steps is not None and int(summary["control_steps"]) >= max_steps
    )
    if not done:
        return False
    fresh = json.loads(
        json.dumps(run_record(runner, generations, max_steps, plugins=plugins), default=repr)
    )
    return {k: v for k, v in previous.items() if k != "versions"} == {
        k: v for k, v in fresh.items() if k != "versions"
    }


def package_version() -> str | None:
    """The installed version of this package (None when run from an uninstalled tree)."""
    try:
        return metadata.version("cyber-rodent")
    except metadata.PackageNotFoundError:
        return None


@functools.cache
def source_commit() -> str | None:
    """The git commit of the source tree this package runs from, ``+dirty`` if it has local
    changes; None outside a git checkout (a wheel install). Results are traced to their code."""
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if status else "") if head else None


def write_tables(
    out: Path,
    statistics: pd.DataFrame,
    per_robot: pd.DataFrame,
    learning: pd.DataFrame | None = None,
    extra: Sequence[tuple[str, pd.DataFrame]] = (),
) -> None:
    """Write ``statistics.csv``, ``statistics_per_robot.csv``, in learning mode
    ``learning.csv``, and the ``extra`` tables (:func:`extra_tables`) into ``out``,
    atomically."""
    tables = [(STATISTICS_FILE, statistics), (ROBOT_STATISTICS_FILE, per_robot)]
    if learning is not None:
        tables.append((LEARNING_FILE, learning))
    tables += list(extra)
    for name, table in tables:
        with atomic_output(out / name) as temp:
            table.to_csv(temp, index=False)


def _write_json(path: Path, record: dict[str, Any]) -> None:
    write_text(path, json.dumps(record, indent=2, sort_keys=True, default=repr))
