"""Experiments as a user runs them: run directories, config files, ``--set`` overrides, resume,
figures and videos. The command line (``cyber-rodent evolve|resume|sweep|plot|render``) is a
thin layer over this module; settings (``--set``, ``--config``, ``--grid``) are read by
:mod:`evolution.settings`.

A run directory holds everything needed to tell what produced what:

- ``run.json``: the resolved config (human-readable JSON), the settings that differ from the
  paper's defaults by dotted key, seed, behaviour policies, target generations, package version
  and git commit, and headline numbers (written by :func:`evolution.api.run`);
- ``versions.json``: Python, this package and its dependencies' versions, the command line;
- ``statistics.csv``: the per-generation statistics table (pandas-readable);
- ``events.csv``: the event log (dockings, recharge ends, matings, deaths, births);
- ``checkpoints/``: the complete state every generation (atomic writes);
- ``figures/``: the run's figures (PNG + PDF).

Bad input is rejected before the directory is created, so it never leaves a half-made run
directory behind; an interrupted run is resumed with :func:`resume_run`, and its result is
identical to an uninterrupted run's.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import os
import platform
import shutil
import sys
import typing
from importlib import metadata
from pathlib import Path
from typing import Any

import pandas as pd

from behaviours import BehaviourPolicies
from cyber_rodent.atomic import atomic_output, write_text
from evolution.api import (
    CHECKPOINT_DIR,
    RUN_FILE,
    STATISTICS_FILE,
    holds_a_run,
    make_config,
)
from evolution.runner import EvolutionRunner, RunConfig, latest_checkpoint, policy_identity

VERSIONS_FILE = "versions.json"
FIGURES_DIR = "figures"
POLICY_NAMES = ("trained", "reactive")
#: Distributions whose versions a run records.
RECORDED_DISTRIBUTIONS = (
    "cyber-rodent", "mujoco", "dm-control", "numpy", "opencv-python-headless", "pandas",
    "matplotlib", "imageio", "imageio-ffmpeg", "tqdm", "torch", "ray",
)  # fmt: skip
#: The full paper experiment, printed as a hint after a short default run.
PAPER_COMMAND = "cyber-rodent sweep --methods ee,ce --seeds 0-19 --generations 120 --out runs/fig6"


# --- policies ----------------------------------------------------------------------------------
def policies_by_name(name: str) -> BehaviourPolicies:
    """``"trained"`` (the shipped values) or ``"reactive"`` (the hand-written baseline)."""
    if name == "trained":
        return BehaviourPolicies.load_default()
    if name == "reactive":
        return BehaviourPolicies.reactive()
    raise ValueError(f"unknown policies {name!r}; allowed: {', '.join(POLICY_NAMES)}")


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


def prepare_out_dir(out: str | os.PathLike[str], *, resume: bool, force: bool) -> Path:
    """Check that ``out`` may receive a run; with ``force`` clear an old run first.

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
    is_run = holds_a_run(path)
    if resume:
        if not is_run:
            raise ValueError(f"--resume: {path} holds no run to continue")
        return path
    if non_empty:
        if not force:
            raise ValueError(
                f"--out {path} exists and is not empty; pass --resume to continue "
                "the run in it or --force to replace it"
            )
        if not is_run:
            raise ValueError(f"--force: {path} is not a run directory; refusing to delete it")
        shutil.rmtree(path)
    parent = path.resolve().parent
    while not parent.exists():
        parent = parent.parent
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"--out {path}: {parent} is not writable")
    return path


SWEEP_FILE = "sweep.json"


def prepare_sweep_dir(out: str | os.PathLike[str], *, resume: bool, force: bool) -> Path:
    """Like :func:`prepare_out_dir`, for a sweep directory (marked by ``sweep.json``)."""
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
    method: str,
    generations: int,
    seed: int,
    out: str | os.PathLike[str],
    *,
    overrides: dict[str, Any] | None = None,
    policies: str = "trained",
    resume: bool = False,
    force: bool = False,
    checkpoint_every: int = 1,
    keep_checkpoints: int = 3,
    progress: bool = True,
    argv: list[str] | None = None,
) -> tuple[Path, pd.DataFrame]:
    """Run (or continue) one EE/CE run in a run directory and draw its figures.

    Everything is validated before the directory is touched.
    """
    from evolution.api import run

    overrides = dict(overrides or {})
    make_config(method, **overrides)  # validates method and every override
    if isinstance(generations, bool) or not isinstance(generations, int) or generations < 1:
        raise ValueError(f"--generations must be an integer >= 1, got {generations!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"--seed must be an integer >= 0, got {seed!r}")
    chosen = policies_by_name(policies)
    path = prepare_out_dir(out, resume=resume, force=force)
    path.mkdir(parents=True, exist_ok=True)
    _write_json(path / VERSIONS_FILE, environment_versions(argv))
    table = run(
        method,
        generations,
        seed,
        out_dir=path,
        policies=chosen,
        resume=resume,
        checkpoint_every=checkpoint_every,
        keep_checkpoints=keep_checkpoints,
        progress=progress,
        **overrides,
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
    out: str | os.PathLike[str], *, progress: bool = True, generations: int | None = None
) -> tuple[Path, pd.DataFrame]:
    """Continue an interrupted run in its directory to its target (or ``generations``).

    The config, seed and policies come from the run's newest checkpoint (or, before the first
    checkpoint, from ``run.json``), so the result is identical to an uninterrupted run.
    """
    from evolution.api import run

    path = Path(out)
    record = read_run_record(path)
    target = int(generations if generations is not None else record["target_generations"])
    chosen = policies_for_identity(record["policies"])
    newest = latest_checkpoint(path / CHECKPOINT_DIR)
    if newest is not None:
        with EvolutionRunner.from_checkpoint(newest, chosen) as runner:
            config, seed = runner.config, runner.seed
    else:
        config, seed = run_config_from_record(record["config"]), int(record["seed"])
    table = run(
        config.method,
        target,
        seed,
        config=config,
        out_dir=path,
        policies=chosen,
        resume=True,
        progress=progress,
    )
    plot_run_dir(path)
    return path, table


def run_config_from_record(data: dict[str, Any]) -> RunConfig:
    """Rebuild a :class:`~evolution.runner.RunConfig` from its ``dataclasses.asdict`` form."""
    config: RunConfig = _dataclass_from_dict(RunConfig, data)
    return config


def _dataclass_from_dict(cls: type, values: dict[str, Any]) -> Any:
    """Inverse of ``dataclasses.asdict`` for frozen config trees (nested dataclasses, tuples)."""
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(values) - names
    if unknown:
        raise ValueError(f"run.json: unknown {cls.__name__} field(s) {sorted(unknown)}")
    kwargs = {}
    for name, value in values.items():
        nested = _dataclass_in(hints[name])
        if isinstance(value, dict) and nested is not None:
            value = _dataclass_from_dict(nested, value)
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return cls(**kwargs)


def _dataclass_in(hint: Any) -> type | None:
    """The dataclass in a field's type hint (``X`` or ``X | None``), if any."""
    for candidate in (hint, *typing.get_args(hint)):
        if isinstance(candidate, type) and dataclasses.is_dataclass(candidate):
            return candidate
    return None


# --- figures and videos ------------------------------------------------------------------------
def plot_run_dir(
    path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None
) -> list[Path]:
    """Draw the figures of a run directory or of a sweep directory into ``<path>/figures``.

    A sweep over a grid of settings gets each cell's figures in ``<cell>/figures`` and the
    comparison of its cells in ``figures/cells.{csv,png,pdf}`` (:mod:`evolution.grid`).

    Args:
        path: a run directory, a sweep directory, or a directory of published run tables.
        out: where the figures and their tables go instead of ``<path>/figures``.

    Raises:
        ValueError: no statistics found under ``path``.
    """
    from evolution.grid import cells, read_grid, write_cell_comparison

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
    return written + write_cell_comparison(root, target)


def _plot_methods(root: Path, figures: Path) -> list[Path]:
    """Fig. 6, its summary, the EE vs CE statistics (:mod:`evolution.comparison`) and the
    completed agents per generation for the runs of one directory (a run, a sweep or a cell),
    into ``figures``."""
    from evolution.comparison import write_report
    from evolution.figures import plot_completions, plot_fig6, summarise_runs
    from evolution.sweep import load_sweep

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
    return written


def render_run(
    source: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    frames: int = 300,
    fps: int = 10,
    steps_per_frame: int = 1,
    progress: bool = True,
) -> Path:
    """An MP4 continuing a run from a checkpoint file or a run directory's newest checkpoint.

    The run directory is not modified: the video's steps happen in memory only.
    """
    from cyber_rodent.render import check_writable_output
    from evolution.checkpoint import read_header
    from evolution.video import MAX_FRAMES, VideoConfig, render_video

    config = VideoConfig(fps=fps, steps_per_frame=steps_per_frame)
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
