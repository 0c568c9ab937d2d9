"""Experiments as a user runs them: run directories, config files, ``--set`` overrides, resume,
figures and videos. The command line (``cyber-rodent evolve|resume|sweep|plot|render``) is a
thin layer over this module; settings (``--set``, ``--config``, ``--grid``) are read by
:mod:`evolution.runner.settings`.

A run directory holds everything needed to tell what produced what:

- ``run.json``: the resolved config (human-readable JSON), the settings that differ from the
  paper's defaults by dotted key, seed, behaviour policies, target generations, package version
  and git commit, headline numbers, and the plugins the run loaded (name, kind and content hash;
  written by :func:`evolution.lab.api.run`);
- ``versions.json``: Python, this package and its dependencies' versions, the command line
  (written with ``run.json`` once the run is built);
- ``statistics.csv``: the per-generation statistics table (pandas-readable);
- ``events.csv``: the event log (dockings, recharge ends, matings, deaths, births);
- ``checkpoints/``: the complete state every generation (atomic writes);
- ``figures/``: the run's figures (PNG + PDF).

Bad input is rejected before the directory is created, so it never leaves a half-made run
directory behind; a directory that a run stopped during its start-up left anyway (an older
version, a kill) is cleared by ``--force`` (:func:`stopped_while_starting`). An interrupted run
is resumed with :func:`resume_run`, and its result is identical to an uninterrupted run's; it
loads the plugins the run records again and refuses one that is missing or has changed.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import platform
import shlex
import shutil
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import pandas as pd

from behaviours import BehaviourPolicies
from cyber_rodent.atomic import TEMP_MARK, atomic_output, write_text
from cyber_rodent.plugins import (
    Plugin,
    PluginMissing,
    ensure_loaded,
    identify,
    load_plugin,
    plugin_records,
    short,
)
from cyber_rodent.validation import check_integer
from evolution.checkpoint import read_header
from evolution.config import MAX_GENERATIONS, MAX_RUN_STEPS
from evolution.lab.api import (
    CHECKPOINT_DIR,
    POLICY_NAMES,
    RUN_FILE,
    STATISTICS_FILE,
    VERSIONS_FILE,
    RunOutput,
    RunSpec,
    check_run_config,
    describe_plugins,
    execute,
    holds_a_run,
    make_config,
    policies_by_name,
    read_record,
    recorded_plugins,
)
from evolution.lab.cells import write_cell_comparison
from evolution.lab.comparison import write_report
from evolution.lab.figures import plot_completions, plot_fig6, summarise_runs
from evolution.lab.grid import cells, read_grid
from evolution.lab.learning_figures import load_learning, write_learning_report
from evolution.lab.monitor import check_tensorboard
from evolution.lab.sweep import load_sweep
from evolution.lab.video import MAX_FRAMES, VideoConfig, render_video
from evolution.runner import (
    EvolutionRunner,
    latest_checkpoint,
    policy_identity,
    run_config_from_record,
)

FIGURES_DIR = "figures"
#: Distributions whose versions a run records.
RECORDED_DISTRIBUTIONS = (
    "cyber-rodent", "mujoco", "dm-control", "numpy", "opencv-python-headless", "pandas",
    "matplotlib", "imageio", "imageio-ffmpeg", "tqdm", "torch", "ray",
)  # fmt: skip
#: The full paper experiment, printed as a hint after a short default run.
PAPER_COMMAND = "cyber-rodent sweep --methods ee,ce --seeds 0-19 --generations 120 --out runs/fig6"


# --- policies ----------------------------------------------------------------------------------
def policies_for_identity(identity: str) -> BehaviourPolicies:
    """The installed policies whose identity a run recorded (for resume and render)."""
    for name in POLICY_NAMES:
        try:
            candidate = policies_by_name(name)
        except FileNotFoundError:
            continue
        if policy_identity(candidate) == identity:
            return candidate
    raise ValueError(
        f"this run used behaviour policies {identity}, which are not installed here (neither "
        "the shipped trained values nor the reactive baseline match)"
    )


# --- run directories ---------------------------------------------------------------------------
def default_out_dir(method: str, seed: int) -> Path:
    """``runs/<method>-seed<NNN>-<timestamp>``: a new directory for every default run."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{method}-seed{seed:03d}-{stamp}"


def _is_temporary(path: Path) -> bool:
    """A stray temporary of :func:`cyber_rodent.atomic.atomic_output` (a killed write)."""
    return path.name.startswith(".") and TEMP_MARK in path.name


def stopped_while_starting(path: str | os.PathLike[str]) -> bool:
    """Does ``path`` hold only what a run stopped during its start-up leaves behind?

    That is ``versions.json``, a ``run.json`` cut short, stray temporaries of atomic writes
    and a ``checkpoints/`` without a checkpoint: no state to continue and no result to lose,
    so ``--force`` may clear it, though :func:`holds_a_run` counts the partial ``run.json``.
    """
    root = Path(path)
    if not root.is_dir() or latest_checkpoint(root / CHECKPOINT_DIR) is not None:
        return False
    entries = list(root.iterdir())
    for entry in entries:
        if entry.name == VERSIONS_FILE or _is_temporary(entry):
            continue
        if entry.name == RUN_FILE and entry.is_file() and read_record(entry) is None:
            continue
        if entry.name == CHECKPOINT_DIR and entry.is_dir():
            if all(_is_temporary(p) for p in entry.iterdir()):
                continue
        return False
    return bool(entries)


def prepare_out_dir(out: str | os.PathLike[str], *, resume: bool, force: bool) -> Path:
    """Check that ``out`` may receive a run; with ``force`` clear an old run first.

    A directory that a run stopped during start-up left behind (:func:`stopped_while_starting`)
    holds nothing to continue: only ``versions.json`` is reused as is, anything more needs
    ``force``.

    Raises:
        ValueError: ``out`` is a file; it is non-empty without ``resume``/``force``; ``force``
            on a non-empty directory that is not a run directory (never deleted); ``resume``
            on a directory without a run; or its parent is not writable.
    """
    if resume and force:
        raise ValueError("--resume and --force exclude each other")
    path = Path(out).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {path} is a file, not a directory")
    # A run killed before its first record leaves only versions.json: nothing to keep.
    non_empty = path.is_dir() and any(p.name != VERSIONS_FILE for p in path.iterdir())
    started = stopped_while_starting(path)
    is_run = holds_a_run(path) and not started
    if resume:
        if started:
            raise ValueError(
                f"--resume: {path} holds no run to continue (it stopped while starting, before "
                "its first checkpoint); start it again with --force instead of --resume"
            )
        if not is_run:
            raise ValueError(f"--resume: {path} holds no run to continue")
        return path
    _check_parent_writable(path)
    if non_empty:
        if not force:
            if started:
                raise ValueError(
                    f"--out {path} holds a run that stopped while starting (no checkpoint); "
                    "pass --force to start it again"
                )
            raise ValueError(
                f"--out {path} exists and is not empty; pass --resume to continue "
                "the run in it or --force to replace it"
            )
        if not (is_run or started):
            raise ValueError(f"--force: {path} is not a run directory; refusing to delete it")
        shutil.rmtree(path)
    return path


def _check_parent_writable(path: Path) -> None:
    parent = path.resolve().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"--out {path}: {parent} is a file, not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"--out {path}: {parent} is not writable")


SWEEP_FILE = "sweep.json"


def prepare_sweep_dir(
    out: str | os.PathLike[str],
    *,
    resume: bool,
    force: bool,
    plugins: Sequence[Plugin] = (),
) -> Path:
    """Like :func:`prepare_out_dir`, for a sweep directory (marked by ``sweep.json``, which
    records the environment and, where the sweep has any, its ``plugins``)."""
    if resume and force:
        raise ValueError("--resume and --force exclude each other")
    path = Path(out).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {path} is a file, not a directory")
    non_empty = path.is_dir() and any(path.iterdir())
    is_sweep = (path / SWEEP_FILE).exists()
    if resume:
        if not is_sweep:
            raise ValueError(f"--resume: {path} holds no sweep ({SWEEP_FILE}) to continue")
    elif non_empty:
        if not force:
            raise ValueError(
                f"--out {path} exists and is not empty; pass --resume to continue "
                "the sweep in it or --force to replace it"
            )
        if not is_sweep:
            raise ValueError(f"--force: {path} is not a sweep directory; refusing to delete it")
        shutil.rmtree(path)
    path.mkdir(parents=True, exist_ok=True)
    record = environment_versions()
    if plugins:  # sweeps without plugins keep the record they always had
        record["plugins"] = plugin_records(plugins)
    _write_json(path / SWEEP_FILE, record)
    return path


def environment_versions(argv: list[str] | None = None) -> dict[str, Any]:
    """Python, platform and package versions (what a methods section needs)."""
    packages: dict[str, str | None] = {}
    for dist in RECORDED_DISTRIBUTIONS:
        try:
            packages[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            packages[dist] = None
    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "packages": packages,
        "command": argv if argv is not None else sys.argv,
        "recorded_at": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }


def _write_json(path: Path, record: dict[str, Any]) -> None:
    write_text(path, json.dumps(record, indent=2, sort_keys=True, default=repr) + "\n")


def evolve(
    spec: RunSpec,
    output: RunOutput | None = None,
    *,
    resume: bool = False,
    force: bool = False,
    argv: list[str] | None = None,
) -> tuple[Path, pd.DataFrame]:
    """Run (or continue) one run in a run directory and draw its figures.

    ``output.directory`` receives the run (default: a new one, :func:`default_out_dir`):
    ``resume`` continues the run there, ``force`` replaces it (:func:`prepare_out_dir`).
    ``output.tensorboard=DIR`` writes each generation to TensorBoard as it closes, in
    ``DIR/<name of the run directory>`` (:mod:`evolution.lab.monitor`), so that runs sharing
    ``DIR`` are overlaid. ``spec.max_steps`` stops the run after that many control steps in
    all even if its generations are not complete (a population that cannot complete its
    generations: agents that learn from zero die before they mate). ``spec.plugins`` are
    loaded first (where this process has not yet), so the overrides may name what they
    register, and ``run.json`` records them. ``argv``: the command line ``versions.json``
    records (default: this process's).

    Everything is validated before the directory is touched, in messages that name the
    command line's options (``--generations``), and the directory is created only once the
    run is built (:func:`evolution.lab.api.execute` writes ``versions.json`` and ``run.json``
    then), so bad input or a failed start leaves nothing behind.
    """

    output = output if output is not None else RunOutput()
    plugins = tuple(ensure_loaded(plugin) for plugin in spec.plugins)  # before the settings
    # the method, every override, their sizes
    check_run_config(make_config(spec.method, spec.config, **spec.overrides))
    check_integer("--generations", spec.generations, 1, MAX_GENERATIONS)
    check_integer("--seed", spec.seed, 0)
    check_integer("--checkpoint-every", output.checkpoint_every, 1, MAX_GENERATIONS)
    check_integer("--keep-checkpoints", output.keep_checkpoints, 0, MAX_GENERATIONS)
    if spec.max_steps is not None:
        check_integer("--max-steps", spec.max_steps, 1, MAX_RUN_STEPS)
    chosen = policies_by_name(spec.policies) if isinstance(spec.policies, str) else spec.policies
    board = check_tensorboard(output.tensorboard) if output.tensorboard is not None else None
    out = output.directory
    path = prepare_out_dir(
        default_out_dir(spec.method, spec.seed) if out is None else out, resume=resume, force=force
    )
    table = execute(
        dataclasses.replace(spec, policies=chosen, plugins=plugins),
        dataclasses.replace(
            output,
            directory=path,
            tensorboard=None if board is None else board / path.resolve().name,
        ),
        resume=resume,
        versions=environment_versions(argv),
    )
    plot_run_dir(path)
    return path, table


def read_run_record(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``run.json`` of a run directory.

    Raises:
        ValueError: no readable run record.
    """
    p = Path(path) / RUN_FILE
    try:
        record = json.loads(p.read_text())
    except (OSError, ValueError) as err:
        raise ValueError(
            f"{Path(path)} is not a run directory (cannot read {RUN_FILE}: {err})"
        ) from None
    if not isinstance(record, dict):
        raise ValueError(f"{Path(path)} is not a run directory ({RUN_FILE} is not a JSON object)")
    return record


def resume_run(
    out: str | os.PathLike[str],
    *,
    progress: bool = True,
    generations: int | None = None,
    tensorboard: str | os.PathLike[str] | None = None,
    plugins: Sequence[Plugin] | None = None,
) -> tuple[Path, pd.DataFrame]:
    """Continue an interrupted run in its directory to its target (or ``generations``).

    The config, seed and policies come from the run's newest checkpoint (or, before the first
    checkpoint, from ``run.json``), so the result is identical to an uninterrupted run.
    ``tensorboard=DIR`` monitors it in ``DIR/<name of the run directory>``, as :func:`evolve`.
    The plugins ``run.json`` records are loaded again from their recorded module name or path
    (:func:`load_run_plugins`); ``plugins`` (``--plugin``), where given, must name the same.
    """

    path = Path(out)
    if generations is not None:
        check_integer("--generations", generations, 1, MAX_GENERATIONS)
    board = check_tensorboard(tensorboard) if tensorboard is not None else None
    if not path.exists():
        raise ValueError(f"{path}: no such run directory")
    if not path.is_dir():
        raise ValueError(f"{path} is a file, not a run directory")
    if (path / SWEEP_FILE).exists():
        raise ValueError(
            f"{path} is a sweep directory, not a run; continue it with sweep --resume: "
            f"{rerun_command(path / SWEEP_FILE, '--resume')}"
        )
    if stopped_while_starting(path):
        raise ValueError(
            f"{path}: its run stopped while starting, before its first checkpoint, so there is "
            f"nothing to resume; start it again: {rerun_command(path / VERSIONS_FILE, '--force')}"
        )
    record = read_run_record(path)
    try:
        target = int(generations if generations is not None else record["target_generations"])
        identity = str(record["policies"])
        seed = int(record["seed"])
        budget = record.get("max_steps")
        max_steps = None if budget is None else int(budget)
    except (KeyError, TypeError, ValueError) as err:
        raise ValueError(f"{path / RUN_FILE} is incomplete or malformed ({err!r})") from None
    loaded = load_run_plugins(path, record, plugins)  # before the config names what they add
    chosen = policies_for_identity(identity)
    newest = latest_checkpoint(path / CHECKPOINT_DIR)
    if newest is not None:
        with EvolutionRunner.from_checkpoint(newest, chosen) as runner:
            config, seed = runner.config, runner.seed
    else:
        config = run_config_from_record(record.get("config"))
    spec = RunSpec(
        config.method, target, seed, config, policies=chosen, max_steps=max_steps, plugins=loaded
    )
    output = RunOutput(
        path,
        tensorboard=None if board is None else board / path.resolve().name,
        progress=progress,
    )
    table = execute(spec, output, resume=True)
    plot_run_dir(path)
    return path, table


def load_run_plugins(
    path: Path, record: dict[str, Any], given: Sequence[Plugin] | None = None
) -> tuple[Plugin, ...]:
    """Load the plugins the run record of the run directory ``path`` names, from their
    recorded module name or file path, checking each one's content against its recorded hash
    before it runs.

    Args:
        path: the run directory.
        record: its ``run.json``.
        given: the plugins the user named (``--plugin``); None: none named. Where given, they
            must be the ones the record names (in any order).

    Raises:
        ValueError: one line naming the plugin: ``given`` names other plugins than the record,
            a recorded plugin is missing or its content has changed, or it fails to load.
    """
    where = path / RUN_FILE
    recorded = recorded_plugins(record, where)
    if given is not None:
        names = {(p.kind, p.name) for p in given}
        if names != {(p.kind, p.name) for p in recorded}:
            raise ValueError(
                f"--plugin must name the plugins {where} records ({describe_plugins(recorded)}), "
                f"got {describe_plugins(tuple(given))}; resume loads the recorded ones by itself"
            )
    for plugin in recorded:
        try:
            current = identify(plugin.name)
        except PluginMissing as err:
            raise ValueError(
                f"{where} records plugin {plugin.name}, which is missing ({err.cause}); "
                "resume needs the plugins the run was started with"
            ) from None
        if current.sha256 != plugin.sha256:
            raise ValueError(
                f"{where} records plugin {plugin.name}, which has changed since (sha256 "
                f"{short(plugin.sha256)} recorded, {short(current.sha256)} now); restore it, "
                "or start a new run"
            )
        load_plugin(plugin.name, sha256=plugin.sha256)
    return recorded


def rerun_command(record: Path, flag: str) -> str:
    """The command recorded in ``record`` (``versions.json`` or ``sweep.json``) with ``flag``
    (``--resume`` or ``--force``) in place of the other, for a hint; words if none is recorded."""
    try:
        argv = json.loads(record.read_text())["command"]
    except (OSError, ValueError, KeyError, TypeError):
        return f"its original command with {flag}"
    if not isinstance(argv, list) or len(argv) < 2 or not all(isinstance(a, str) for a in argv):
        return f"its original command with {flag}"
    args = [a for a in argv[1:] if a not in ("--resume", "--force")]
    if "--out" not in args and not any(a.startswith("--out=") for a in args):
        args += ["--out", str(record.parent)]
    return "cyber-rodent " + shlex.join([*args, flag])


# --- figures and videos ------------------------------------------------------------------------
def plot_run_dir(
    path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None
) -> list[Path]:
    """Draw the figures of a run directory or of a sweep directory into ``<path>/figures``.

    A sweep over a grid of settings gets each cell's figures in ``<cell>/figures`` and the
    comparison of its cells in ``figures/cells.{csv,png,pdf}`` (:mod:`evolution.lab.grid`).

    Args:
        path: a run directory, a sweep directory, or a directory of published run tables.
        out: where the figures and their tables go instead of ``<path>/figures``.

    Raises:
        ValueError: no statistics found under ``path``.
    """

    root = Path(path)
    target = Path(out) if out is not None else root / FIGURES_DIR
    grid = read_grid(root)
    if grid is None:
        return _plot_methods(root, target)
    written: list[Path] = []
    for cell in cells(grid):
        try:
            written += _plot_methods(root / cell.name, target / cell.name)
        except ValueError:
            continue  # a cell none of whose runs has finished a generation yet
    if not written:
        raise ValueError(f"no {STATISTICS_FILE} found in the cells of {root}")

    learning = {cell.name: load_learning(root / cell.name) for cell in cells(grid)}
    return (
        written + write_cell_comparison(root, target) + write_learning_report(learning, target)
    )


def _plot_methods(root: Path, figures: Path) -> list[Path]:
    """Fig. 6, its summary, the EE vs CE statistics (:mod:`evolution.lab.comparison`) and the
    completed agents per generation for the runs of one directory (a run, a sweep or a cell),
    into ``figures``."""

    runs = load_sweep(root)
    if not any(runs.values()):
        raise ValueError(f"no {STATISTICS_FILE} found in {root} or its run directories")
    written = []
    non_empty = {m: [t for t in tables if len(t)] for m, tables in runs.items()}
    if any(non_empty.values()):
        chosen = {m: t for m, t in non_empty.items() if t}
        written += plot_fig6(chosen, figures / "fig6")
        summary = figures / "fig6_summary.csv"
        with atomic_output(summary) as temp:
            summarise_runs(chosen).to_csv(temp, index=False, float_format="%.4g")
        written.append(summary)
        written += write_report(chosen, figures)
        written += plot_completions(chosen, figures / "completions")

    written += write_learning_report({root.name: load_learning(root)}, figures)
    return written


def render_run(
    source: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    frames: int = 300,
    fps: int = 10,
    steps_per_frame: int = 1,
    progress: bool = True,
    **video: Any,
) -> Path:
    """An MP4 continuing a run from a checkpoint file or a run directory's newest checkpoint.

    The run directory is not modified: the video's steps happen in memory only. ``video``:
    further :class:`evolution.lab.video.VideoConfig` fields (``width``, ``height``, ``camera``).
    """
    from cyber_rodent.render import check_writable_output

    config = VideoConfig(fps=fps, steps_per_frame=steps_per_frame, **video)
    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_FRAMES:
        raise ValueError(f"--frames must be an integer in [1, {MAX_FRAMES}], got {frames!r}")
    if Path(out).suffix.lower() != ".mp4":
        raise ValueError(f"--out must name an .mp4 file, got {Path(out).name}")
    check_writable_output(out)  # before the (slow) checkpoint load
    src = Path(source)
    if src.is_dir():
        checkpoint = latest_checkpoint(src / CHECKPOINT_DIR)
        if checkpoint is None:
            raise ValueError(f"{src} has no checkpoint to render from (is it a run directory?)")
        identity = read_run_record(src)["policies"]
    elif src.is_file():
        checkpoint = src
        header = read_header(src)
        if header is None:
            raise ValueError(f"{src} is not a checkpoint file")
        run_dir = src.parent.parent
        identity = (
            read_run_record(run_dir)["policies"]
            if (run_dir / RUN_FILE).exists()
            else policy_identity(policies_by_name("trained"))
        )
    else:
        raise ValueError(f"{src}: no such run directory or checkpoint file")
    with EvolutionRunner.from_checkpoint(checkpoint, policies_for_identity(identity)) as runner:
        return render_video(runner, out, frames, config, progress=progress)
