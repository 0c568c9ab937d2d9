"""Many runs (grid cells × methods × seeds) in parallel: local processes, or a Ray cluster.

Each run is independent and its result depends only on its config and seed, so a sweep gives
identical tables whichever executor or how many workers ran it. Every run has its own run
directory ``<out>/<method>-seed<NNN>`` (``<out>/<cell>/<method>-seed<NNN>`` in a sweep over a
grid of settings, :mod:`evolution.lab.grid`) holding what :func:`evolution.lab.api.run` writes there
(``statistics.csv``, ``statistics_per_robot.csv``, ``events.csv``, ``run.json``, the newest
:data:`KEEP_CHECKPOINTS` checkpoints), checkpointed every generation. A run whose worker fails
or is killed is submitted again and continues from its last checkpoint, so a retry costs at
most one generation and changes nothing in the result (resuming is bit-identical,
docs/design.md §10).

Backends:

- ``local`` (default): one process per run, ``workers`` at a time (``spawn`` start method, so
  MuJoCo and OpenGL state never crosses a ``fork``), each writing its run directory itself. A
  killed worker breaks a ``ProcessPoolExecutor``; the pool is rebuilt and the unfinished runs
  resumed.
- ``ray``: the runs go to an existing cluster (``ray_address="auto"`` or ``"host:port"``) or to
  a fresh Ray instance here (``"local"``, listening on loopback only: :func:`init_local_ray`),
  as many at a time as the cluster has CPUs (at most ``workers`` where given), in
  :attr:`SweepSpec.runs` order.

On a cluster the worker nodes usually do not share the driver's filesystem, so the Ray backend
never lets a task write to ``out``: the driver's disk holds every run's state. A run advances
in *chunks* of ``chunk_generations`` whole generations (default :data:`CHUNK_GENERATIONS`), one
Ray task each (:func:`advance_run`). The task gets the run's newest checkpoint as bytes from the
driver (none for a new run), rebuilds the runner from it in a temporary directory of its own,
runs the chunk there, and returns what it wrote as bytes: its new checkpoints, the statistics
tables, ``run.json``, and ``events.csv`` once the run is complete. The driver writes them
atomically into the run directory in the order :func:`evolution.lab.api.run` does and prunes the
checkpoints alike, then submits the run's next chunk; so ``out`` ends with the same files, byte
for byte, as the local backend writes, and ``cyber-rodent resume`` or ``sweep --resume``
continue from it. A chunk whose node or worker is lost, whose returned object is lost, or which
raises, is submitted again from the newest checkpoint the driver holds (a line on stderr says
so; at most ``max_retries`` times per run, as locally, counted by the driver rather than by Ray
so that the budget is the run's, not the chunk's): the retried run continues where it stood,
not from scratch, and, resuming being bit-identical, ends as an uninterrupted run would. Chunks
are whole generations because checkpoints are written when a generation completes; one
generation bounds what a lost node costs, and rebuilding a runner from its checkpoint takes a
small fraction of a generation. Runs under way continue before new ones start, so a sweep
stopped part-way has whole seeds done. Worker nodes need the package installed (the same
version: checkpoints record it), not the driver's directories.

Plugins: a sweep's plugins (:attr:`SweepSpec.plugins`, ``--plugin`` on the command line: code
that registers a controller, an input or a task, :mod:`cyber_rodent.plugins`) travel with each
run as their source text and hash. A local worker or a Ray task loads them (checking the text
against the hash) before it builds its run, so neither needs the plugin's file, and every run
records them in its ``run.json``. A sweep is continued only with the plugins its runs record.

Monitoring: with ``RunOutput(tensorboard=DIR)`` every run writes each generation to TensorBoard
as it closes (:mod:`evolution.lab.monitor`), in ``DIR/<method>-seed<NNN>`` (``DIR/<cell>/...``
in a grid), so that ``tensorboard --logdir DIR`` overlays the runs. Local workers write their run's
event files themselves; on Ray the tasks return each closed generation's record with their
files and the driver writes them, so the worker nodes need neither the package nor ``DIR``.

Progress: an aggregate bar over all runs' generations, with ETA and the latest mean batteries
and matings, read from the runs' ``statistics.csv`` files as they are rewritten (a line a minute
when stderr is no terminal, :mod:`cyber_rodent.progress`). Before it starts, a sweep's run time
can be projected from its size (:func:`projected_seconds`).
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import math
import multiprocessing
import os
import re
import socket
import sys
import tempfile
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd

from cyber_rodent.plugins import PluginSource
from cyber_rodent.validation import check_integer, choice, validate_fields
from evolution.checkpoint import CheckpointError
from evolution.config import MAX_GENERATIONS, MAX_RUN_STEPS
from evolution.lab.api import (
    CHECKPOINT_DIR,
    EVENTS_FILE,
    RUN_FILE,
    RunOutput,
    RunSpec,
    check_plugins,
    check_policies,
    check_run_config,
    execute,
    extra_tables,
    learning_table,
    make_config,
    policies_by_name,
    read_record,
    robot_table,
    run_record,
    write_tables,
)
from evolution.lab.grid import Cell, Grid, cells, check_grid, write_grid
from evolution.lab.monitor import (
    GenerationMonitor,
    GenerationRecord,
    TensorBoardWriter,
    check_tensorboard,
)
from evolution.runner import EvolutionRunner, latest_checkpoint
from evolution.runner.checkpoints import prune_checkpoints
from evolution.runner.settings import merge
from evolution.schemes import scheme_names

EXECUTORS = ("local", "ray")
#: Orders in which a sweep's runs start (:attr:`SweepSpec.runs`): cell by cell, or seed by
#: seed across every cell (a sweep stopped part-way then has a few seeds of every cell).
RUN_ORDERS = ("cell", "seed")
#: Environment for worker processes: one BLAS / llvmpipe thread each, since runs already fill
#: the cores one process per run.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "LP_NUM_THREADS": "1"}
#: Most runs (cells x methods x seeds) of one sweep: 250x the paper's Fig. 6 (40 runs). More is
#: a typo (a seed range with a digit too many), refused before the runs are even listed.
MAX_RUNS = 10_000
#: Seconds of one control step of the default world (4 robots, geometric vision, 24 physics
#: steps of 1/120 s) on one core: ``cyber-rodent evolve``'s measured 1,007 steps/s (README,
#: Command line). :func:`projected_seconds` scales it to a sweep's config.
STEP_SECONDS = 1 / 1000
#: Cost of rendered vision per control step, a multiple of the geometric loop's (README,
#: Performance: 10.3x).
RENDERED_STEP_COST = 10.3
#: Cost of learning mode per control step, a multiple of the fixed behaviours' loop (README,
#: Performance: ``python -m benchmarks``).
LEARNING_STEP_COST = 1.2
#: Control steps of a generation per agent life in it: EE generations close only after the
#: replacements of dead agents have lived too (README, Performance: 1.40-1.50 M steps for 120
#: generations of 25 lives of 400 steps, ~1.2x); CE's lives are the generation (~0.95x).
STEPS_PER_LIFE = {"ee": 1.2, "ce": 0.95}
#: Newest checkpoints each run directory keeps (:func:`evolution.lab.api.run`'s default).
KEEP_CHECKPOINTS = 3
#: The address a Ray instance started here (``--ray local``) listens on.
LOOPBACK = "127.0.0.1"
#: Generations one Ray task advances its run by: a lost node costs at most this much of each
#: run it held, and every chunk pays one checkpoint's transfer and one runner rebuild.
CHUNK_GENERATIONS = 1


class SweepRun(NamedTuple):
    """One member of a sweep: a method and seed, in a grid cell ("" without a grid)."""

    method: str
    seed: int
    cell: str = ""


@dataclass(frozen=True)
class SweepSpec:
    """What a sweep runs.

    Attributes:
        methods: evolution schemes (``method``: ``ee``, ``ce``, ``medea`` or a registered
            one), each run for every seed.
        seeds: the seeds, each run once per method (and cell).
        generations: generations per run.
        overrides: settings passed to every run (see :func:`evolution.lab.api.make_config`).
        policies: basic behaviours: ``"trained"`` (the shipped values), ``"reactive"`` (the
            hand-written baseline) or a directory of trained values (``check_policies``).
        grid: axes of settings, ``((dotted key, values), ...)``; every cell of their product
            runs every method and seed, its settings over ``overrides``. Empty: one cell.
        max_steps: stop each run after this many control steps even if its generations are
            not complete (None: no budget).
        cell_list: explicit cells, each with its own settings and, optionally, its own methods
            (a subset of ``methods``): for settings that change together (a colony's robot
            count, field side and packs), which a grid's product cannot express. Excludes
            ``grid``; its cells' names must be distinct directory names.
        order: ``"cell"`` (cell by cell, then seed, then method) or ``"seed"`` (seed by seed,
            then cell, then method), the order in which the runs start (:attr:`runs`).
        members: run only these members of the sweep (each one of its runs), in the sweep's
            order; None: every run. What a caller passes to leave out runs it knows finished.
        plugins: the plugins every run loads before it is built and records in its
            ``run.json``, with their source (:func:`cyber_rodent.plugins.plugin_source`), so
            that workers need not have their files.
    """

    methods: tuple[str, ...]
    seeds: tuple[int, ...]
    generations: int
    overrides: dict[str, Any] = field(default_factory=dict)
    policies: str = "trained"
    grid: Grid = ()
    max_steps: int | None = None
    cell_list: tuple[Cell, ...] = ()
    order: str = choice("cell", RUN_ORDERS)
    members: tuple[SweepRun, ...] | None = None
    plugins: tuple[PluginSource, ...] = ()

    def __post_init__(self) -> None:
        validate_fields(self)
        check_policies(self.policies)
        if not isinstance(self.plugins, tuple) or not all(
            isinstance(p, PluginSource) for p in self.plugins
        ):
            raise ValueError(f"plugins must be a tuple of PluginSource, got {self.plugins!r}")
        names = scheme_names()
        if not self.methods or any(m not in names for m in self.methods):
            raise ValueError(
                f"methods must be a non-empty subset of {names}, got {self.methods!r}"
            )
        if len(set(self.methods)) != len(self.methods):
            raise ValueError(f"methods must not repeat, got {self.methods!r}")
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise ValueError(f"seeds must be a non-empty list without repeats, got {self.seeds!r}")
        for seed in self.seeds:
            check_integer("seed", seed, 0)
        check_integer("generations", self.generations, 1, MAX_GENERATIONS)
        if self.max_steps is not None:
            check_integer("max_steps", self.max_steps, 1, MAX_RUN_STEPS)
        self._check_cell_list()
        n_cells = len(self.cell_list) or math.prod(len(v) for _, v in self.grid)
        n_runs = len(self.methods) * len(self.seeds) * n_cells
        if n_runs > MAX_RUNS:
            raise ValueError(
                f"a sweep runs at most {MAX_RUNS} runs (cells x methods x seeds), got {n_runs}"
            )
        if self.members is not None:
            every = set(self._ordered_runs())
            strays = [m for m in self.members if m not in every]
            if strays:
                raise ValueError(f"members must be runs of the sweep, got {strays[0]!r}")

    def _check_cell_list(self) -> None:
        if not self.cell_list:
            return
        if self.grid:
            raise ValueError("a sweep takes a grid or a cell list, not both")
        names = [c.name for c in self.cell_list if isinstance(c, Cell)]
        if len(names) != len(self.cell_list):
            raise ValueError("cell_list must hold Cell objects")
        for name in names:
            if not name or name in (".", "..") or "/" in name or os.sep in name:
                raise ValueError(f"a cell's name must be a directory name, got {name!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"cell names must not repeat, got {names!r}")
        for c in self.cell_list:
            if any(m not in self.methods for m in c.methods) or len(set(c.methods)) != len(
                c.methods
            ):
                raise ValueError(
                    f"cell {c.name}: methods must be distinct methods of the sweep "
                    f"{self.methods!r}, got {c.methods!r}"
                )

    @property
    def cells(self) -> tuple[Cell, ...]:
        """The cell list, or the grid's cells (one unnamed cell without either)."""
        return self.cell_list or cells(self.grid) or (Cell("", {}),)

    def methods_of(self, cell: Cell) -> tuple[str, ...]:
        """The methods ``cell`` runs, in the sweep's order."""
        return tuple(m for m in self.methods if not cell.methods or m in cell.methods)

    def _ordered_runs(self) -> list[SweepRun]:
        if self.order == "seed":
            return [
                SweepRun(m, s, c.name)
                for s in self.seeds
                for c in self.cells
                for m in self.methods_of(c)
            ]
        return [
            SweepRun(m, s, c.name)
            for c in self.cells
            for s in self.seeds
            for m in self.methods_of(c)
        ]

    @property
    def runs(self) -> list[SweepRun]:
        """Every (method, seed, cell) in a fixed order: by default cell by cell, seed by seed,
        then method; with ``order="seed"`` seed by seed, cell by cell, then method. Only
        :attr:`members` where given.

        Workers take runs in this order, so a sweep stopped part-way (a machine's time limit, a
        cluster's time limit) has finished whole seeds of every method, which are comparable,
        rather than every seed of one method and none of the other.
        """
        ordered = self._ordered_runs()
        if self.members is None:
            return ordered
        chosen = set(self.members)
        return [member for member in ordered if member in chosen]

    def run_spec(self, member: SweepRun) -> RunSpec:
        """What ``member`` runs (its plugins are loaded from :attr:`plugins` where it runs)."""
        return RunSpec(
            member.method, self.generations, member.seed, overrides=self.settings_of(member.cell),
            policies=self.policies, max_steps=self.max_steps,
        )  # fmt: skip

    def settings_of(self, cell: str) -> dict[str, Any]:
        """The settings of the runs in ``cell``: the sweep's overrides, then the cell's."""

        chosen = next(c for c in self.cells if c.name == cell)
        return merge(self.overrides, chosen.settings)

    def check(self) -> None:
        """Load the sweep's plugins here (once per process), then build every cell's config for
        each of its methods, so a bad setting fails before any run.

        Raises:
            ValueError: the first setting a config refuses (one line naming the key).
            PluginError: a plugin fails to load (:mod:`cyber_rodent.plugins`).
        """

        for source in self.plugins:
            source.load()
        for c in self.cells:
            for method in self.methods_of(c):
                check_run_config(make_config(method, **self.settings_of(c.name)))


def parse_seeds(text: str) -> tuple[int, ...]:
    """Parse ``"0-19"``, ``"3"`` or ``"0,2,5-7"`` into seeds.

    Raises:
        ValueError: for anything else (the message shows the accepted forms).
    """
    seeds: list[int] = []
    for part in str(text).split(","):
        part = part.strip()
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if not m:
            raise ValueError(f"bad seed range {text!r}: use N, A-B or a comma list like 0,2,5-7")
        lo = int(m.group(1))
        hi = int(m.group(2)) if m.group(2) is not None else lo
        if hi < lo:
            raise ValueError(f"bad seed range {part!r} in {text!r}: the end is below the start")
        if len(seeds) + hi - lo + 1 > MAX_RUNS:
            raise ValueError(f"bad seed range {text!r}: more than {MAX_RUNS} seeds")
        seeds.extend(range(lo, hi + 1))
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"bad seed range {text!r}: a seed appears twice")
    return tuple(seeds)


def run_dir(out_dir: str | os.PathLike[str], method: str, seed: int, cell: str = "") -> Path:
    """The run directory of one sweep member."""
    return Path(out_dir) / cell / f"{method}-seed{seed:03d}"


def check_sweep_plugins(out_dir: str | os.PathLike[str], spec: SweepSpec) -> None:
    """Refuse to continue a sweep whose runs record other plugins than ``spec`` has.

    Raises:
        ValueError: one line naming the first run whose ``run.json`` records other plugins.
    """
    given = tuple(source.plugin for source in spec.plugins)
    for member in spec.runs:
        path = run_dir(out_dir, *member) / RUN_FILE
        record = read_record(path) if path.is_file() else None
        if record is not None:
            check_plugins(record, given, path)


def run_one(
    spec: RunSpec, output: RunOutput, plugins: tuple[PluginSource, ...] = ()
) -> pd.DataFrame:
    """Run (or resume) one sweep member (:meth:`SweepSpec.run_spec`) in its run directory; the
    local worker entry point.

    ``plugins``: loaded first, from their text (checked against their hash), and run as the
    spec's plugins.
    """
    loaded = tuple(source.load() for source in plugins)
    return execute(replace(spec, plugins=loaded), output, resume=True)


class RunChunk(NamedTuple):
    """What a Ray task needs to advance one run: the run's identity and its newest checkpoint.

    Attributes:
        method, seed, overrides, policies: the run (as :meth:`SweepSpec.run_spec` has them).
        generations: the run's target.
        chunk: generations this task adds at most.
        keep_checkpoints: newest checkpoints a run directory keeps (0: all).
        checkpoint: ``(file name, bytes)`` of the newest checkpoint the driver holds; None
            starts the run.
        max_steps: the run's step budget (None: none).
        monitor: return each closed generation's :class:`GenerationRecord` (for the driver's
            TensorBoard writer).
        plugins: the run's plugins with their source text: the task loads them before it
            builds the runner (no file of theirs is needed on the worker's node).
    """

    method: str
    seed: int
    generations: int
    chunk: int
    overrides: dict[str, Any]
    policies: str
    keep_checkpoints: int
    checkpoint: tuple[str, bytes] | None
    max_steps: int | None = None
    monitor: bool = False
    plugins: tuple[PluginSource, ...] = ()


class ChunkResult(NamedTuple):
    """What a Ray task returns: the run's progress and the files the chunk wrote.

    Attributes:
        completed: generations the run has completed.
        files: path in the run directory (``checkpoints/gen_00003.ckpt``, ``statistics.csv``)
            -> content, for every file the chunk wrote.
        table: the run's statistics so far (:meth:`EvolutionRunner.statistics`).
        finished: the run reached its target generations or spent its step budget.
        generations: with ``RunChunk.monitor``, the record of each generation the chunk
            closed, in order.
    """

    completed: int
    files: dict[str, bytes]
    table: pd.DataFrame
    finished: bool = False
    generations: tuple[GenerationRecord, ...] = ()


def advance_run(task: RunChunk) -> ChunkResult:
    """Advance one run by a chunk of generations in a temporary directory; the Ray task.

    Writes exactly what :func:`evolution.lab.api.run` writes in a run directory, in a directory of
    its own that is deleted on return, and returns those files: the driver stores them, so the
    worker needs no filesystem shared with it.

    Raises:
        CheckpointError: the checkpoint is corrupt or belongs to another run.
        PluginError: a plugin's text does not match its hash, or it fails to load.
    """
    plugins = tuple(source.load() for source in task.plugins)  # before the config names them
    config = make_config(task.method, **task.overrides)
    check_run_config(config)
    policies = policies_by_name(task.policies)
    with tempfile.TemporaryDirectory(prefix="cyber-rodent-run-") as temp:
        out = Path(temp)
        checkpoints = out / CHECKPOINT_DIR
        checkpoints.mkdir()
        given: Path | None = None
        if task.checkpoint is None:
            runner = EvolutionRunner(config, task.seed, policies)
        else:
            name, data = task.checkpoint
            given = checkpoints / Path(name).name
            given.write_bytes(data)
            try:
                runner = EvolutionRunner.from_checkpoint(
                    given, policies, expect=(config, task.seed)
                )
            except CheckpointError as err:  # name the file as the run directory has it
                raise CheckpointError(str(err).replace(f"{out}{os.sep}", "")) from None
        records: list[GenerationRecord] = []
        with runner:
            target = min(runner.completed_generations + task.chunk, task.generations)
            monitor = None
            if task.monitor:
                monitor = GenerationMonitor(records.append, runner.completed_generations)
            table = runner.run(
                target,
                checkpoint_dir=checkpoints,
                checkpoint_every=1,
                keep_checkpoints=task.keep_checkpoints,
                max_steps=task.max_steps,
                on_generation=monitor,
            )
            write_tables(
                out, table, robot_table(runner), learning_table(runner), extra_tables(runner)
            )
            completed = runner.completed_generations
            spent = task.max_steps is not None and runner.steps >= task.max_steps
            finished = completed >= task.generations or spent
            if finished:  # api.run writes the event log at the end
                runner.events.write_csv(out / EVENTS_FILE)
            record = run_record(runner, task.generations, task.max_steps, plugins=plugins)
        # The format of api.run's run.json (the tests compare the two byte for byte).
        (out / RUN_FILE).write_text(json.dumps(record, indent=2, sort_keys=True, default=repr))
        files = {
            path.relative_to(out).as_posix(): path.read_bytes()
            for path in sorted(out.rglob("*"))
            if path.is_file() and path != given
        }
    return ChunkResult(completed, files, table, finished, tuple(records))


def check_ray_address(address: str, timeout: float = 3.0) -> None:
    """Fail fast, with a clear message, if Ray is missing or a cluster address does not answer.

    ``local`` (a Ray instance started here) needs Ray only; ``auto`` is resolved as Ray resolves
    it (``RAY_ADDRESS``, else the cluster ``ray start`` last started on this machine) and then
    checked like ``host:port``.

    Raises:
        ValueError: Ray is not installed, the address is malformed, ``auto`` finds no cluster,
            or nothing listens there.
    """
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ValueError("--ray needs ray: pip install 'cyber-rodent[cluster]'") from None
    target = address.removeprefix("ray://")
    if target == "local":
        return
    if target == "auto":
        found = _auto_ray_address()
        if found is None:
            return
        target = found
    m = re.fullmatch(r"\[?([A-Za-z0-9.\-:]+?)\]?:(\d+)", target)
    if not m:
        raise ValueError(
            f"bad Ray address {address!r}: use auto, local, HOST:PORT or ray://HOST:PORT"
        )
    host, port = m.group(1), int(m.group(2))
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as err:
        auto = address.removeprefix("ray://") == "auto"
        where = f"{address} ({host}:{port})" if auto else address
        raise ValueError(f"cannot reach a Ray cluster at {where}: {err}") from None


def _auto_ray_address() -> str | None:
    """The ``host:port`` Ray's ``auto`` names; None where this Ray cannot be asked (the
    lookup is not public API, so ``ray.init`` will tell instead).

    Raises:
        ValueError: no running cluster is found.
    """
    try:
        from ray._private.services import canonicalize_bootstrap_address_or_die
    except ImportError:
        return None
    try:
        found: str = canonicalize_bootstrap_address_or_die("auto")
    except ConnectionError:
        raise ValueError(
            "--ray auto: no running Ray cluster found (RAY_ADDRESS is unset and `ray start` "
            "started none here); give HOST:PORT, or --ray local to start one on this machine"
        ) from None
    except Exception:  # the private lookup changed: let ray.init report
        return None
    return found


def projected_seconds(spec: SweepSpec, workers: int) -> float:
    """Wall-clock seconds a sweep should take: an estimate from its size and config.

    A generation is about ``population_size / n_robots x lifetime_steps`` control steps (the
    robots run their subpopulations side by side, one life after another; x
    :data:`STEPS_PER_LIFE`); a control step costs :data:`STEP_SECONDS`, scaled by its physics
    steps, its robots and rendered vision; the runs share ``workers`` cores. Runs are not all
    alike (deaths shorten lives, docking costs more physics): this is the order of magnitude.
    """

    default = make_config("ee")
    default_physics = default.survival.control_dt / default.world.timestep
    total = 0.0
    for member in spec.runs:
        config = make_config(member.method, **spec.settings_of(member.cell))
        evo = config.evolution
        per_life = STEPS_PER_LIFE.get(member.method, STEPS_PER_LIFE["ee"])  # others: as EE
        steps = evo.subpopulation_size * evo.lifetime_steps * per_life
        physics = config.survival.control_dt / config.world.timestep
        cost = STEP_SECONDS * physics / default_physics
        cost *= evo.n_robots / default.evolution.n_robots
        if config.vision == "rendered":
            cost *= RENDERED_STEP_COST
        if evo.learning.enabled:
            cost *= LEARNING_STEP_COST
        run_steps = spec.generations * steps
        if spec.max_steps is not None:
            run_steps = min(run_steps, spec.max_steps)
        total += run_steps * cost
    return total / max(1, min(workers, len(spec.runs)))


class _Progress:
    """Aggregate progress over a sweep's run directories (polls their statistics.csv)."""

    def __init__(self, spec: SweepSpec, out_dir: Path, enabled: bool):
        self.spec = spec
        self.out_dir = out_dir
        self.total = len(spec.runs) * spec.generations
        self.bar: Any = None
        if enabled:
            from cyber_rodent.progress import progress_bar

            self.bar = progress_bar(
                total=self.total,
                unit="gen",
                desc=f"sweep ({len(spec.runs)} runs)",
                dynamic_ncols=True,
            )

    def update(self) -> None:
        if self.bar is None:
            return
        done, batteries, matings = 0, [], []
        for member in self.spec.runs:
            path = run_dir(self.out_dir, *member) / "statistics.csv"
            try:
                table = pd.read_csv(path)
            except (OSError, pd.errors.EmptyDataError, pd.errors.ParserError):
                continue
            done += min(len(table), self.spec.generations)
            if len(table):
                last = table.iloc[-1]
                if not math.isnan(last.get("batteries_mean", math.nan)):
                    batteries.append(last["batteries_mean"])
                    matings.append(last["matings_mean"])
        self.bar.n = done
        if batteries:
            self.bar.set_postfix(
                batteries=f"{sum(batteries) / len(batteries):.1f}",
                matings=f"{sum(matings) / len(matings):.2f}",
                refresh=False,
            )
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.update()
            self.bar.close()


@dataclass(frozen=True)
class Execution:
    """How a sweep runs its members: where (local processes or Ray), how many at a time, and
    how often a failed run is tried again."""

    executor: str = "local"
    """``"local"`` (one process per run) or ``"ray"`` (Ray tasks, a chunk of generations
    each)"""
    workers: int | None = None
    """concurrent runs (None: the number of CPUs here; with Ray, the cluster's)"""
    ray_address: str = "local"
    """with ``executor="ray"``: ``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:PORT"`` or
    ``"local"`` (start a Ray instance on this machine with ``workers`` CPUs)"""
    max_retries: int = 2
    """how often a failed run is resubmitted (it resumes from its checkpoint)"""
    chunk_generations: int = CHUNK_GENERATIONS
    """with ``executor="ray"``: generations one task advances a run by"""
    poll_seconds: float = 2.0
    """how often progress is refreshed"""


def sweep(
    spec: SweepSpec,
    output: RunOutput,
    execution: Execution | None = None,
    *,
    on_run_done: Callable[[SweepRun], None] | None = None,
) -> dict[SweepRun, pd.DataFrame]:
    """Run every (method, seed, cell) of ``spec``; return their statistics tables.

    Args:
        spec: methods, seeds, generations and overrides.
        output: ``directory``, the parent of the run directories (and of the cells'
            directories); ``keep_checkpoints``, the newest checkpoints each run directory keeps
            (0: all of them); ``tensorboard``, where every run's generations are written to
            TensorBoard as they close, each run in ``<tensorboard>/<cell>/<method>-seed<NNN>``
            (:mod:`evolution.lab.monitor`); ``progress``, the aggregate progress bar. A sweep
            checkpoints every generation, so ``checkpoint_every`` must be 1.
        execution: local processes or Ray, and how many workers (default: :class:`Execution`,
            a process per CPU here).
        on_run_done: called in this process with each run as soon as it has finished and
            its run directory is complete (e.g. to publish its tables while the others run).

    Raises:
        ValueError: bad arguments, an unreachable Ray address, or a ``tensorboard``
            directory that cannot be written or without the package (before any run starts).
        SweepFailed: a run still failed after ``max_retries`` retries (the others finish
            first; their results stay on disk).
    """
    how = execution if execution is not None else Execution()
    workers, keep_checkpoints = how.workers, output.keep_checkpoints
    if output.directory is None:
        raise ValueError("a sweep needs an output directory, the parent of its run directories")
    if output.checkpoint_every != 1:
        raise ValueError(
            "a sweep checkpoints every generation (so a retried run loses at most one): "
            f"checkpoint_every must be 1, got {output.checkpoint_every!r}"
        )
    if how.executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {how.executor!r}")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if not isinstance(how.max_retries, int) or how.max_retries < 0:
        raise ValueError(f"max_retries must be an integer >= 0, got {how.max_retries!r}")
    check_integer("keep_checkpoints", keep_checkpoints, 0)
    check_integer("chunk_generations", how.chunk_generations, 1)

    out = Path(output.directory)
    check_grid(out, spec.grid)
    check_sweep_plugins(out, spec)
    spec.check()  # the plugins, every cell's settings, before anything runs
    if how.executor == "ray":
        check_ray_address(how.ray_address)
    tensorboard = output.tensorboard
    board = check_tensorboard(tensorboard, "tensorboard") if tensorboard is not None else None
    out.mkdir(parents=True, exist_ok=True)
    if spec.grid:
        write_grid(out, spec.grid, spec.plugins)
    bar = _Progress(spec, out, output.progress)
    try:
        if how.executor == "local":
            return _sweep_local(
                spec, out, workers or os.cpu_count() or 1, how.max_retries, keep_checkpoints,
                bar, how.poll_seconds, board, on_run_done,
            )  # fmt: skip
        plan = _RayPlan(spec, out, keep_checkpoints, how.chunk_generations, board)
        return _sweep_ray(
            plan, workers, how.ray_address, how.max_retries, bar, how.poll_seconds, on_run_done
        )
    finally:
        bar.close()


def _sweep_local(
    spec: SweepSpec,
    out: Path,
    workers: int,
    max_retries: int,
    keep_checkpoints: int,
    bar: _Progress,
    poll_seconds: float,
    board: Path | None = None,
    on_run_done: Callable[[SweepRun], None] | None = None,
) -> dict[SweepRun, pd.DataFrame]:
    results: dict[SweepRun, pd.DataFrame] = {}
    failures: dict[SweepRun, int] = {}
    errors: dict[SweepRun, BaseException] = {}
    todo = list(spec.runs)
    context = multiprocessing.get_context("spawn")
    saved_env = {k: os.environ.get(k) for k in WORKER_ENV}
    os.environ.update(WORKER_ENV)  # inherited by the spawned workers
    try:
        while todo:
            pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=context)
            futures = {
                pool.submit(
                    run_one,
                    spec.run_spec(member),
                    RunOutput(
                        str(run_dir(out, *member)),
                        keep_checkpoints=keep_checkpoints,
                        tensorboard=None if board is None else str(run_dir(board, *member)),
                    ),
                    spec.plugins,
                ): member
                for member in todo
            }
            todo = []
            pending = set(futures)
            while pending:
                done, pending = cf.wait(
                    pending, timeout=poll_seconds, return_when=cf.FIRST_COMPLETED
                )
                bar.update()
                for fut in done:
                    key = futures[fut]
                    try:
                        results[key] = fut.result()
                    except Exception as err:  # a crash, a kill (BrokenProcessPool), an error
                        failures[key] = failures.get(key, 0) + 1
                        if failures[key] > max_retries:
                            errors[key] = err
                        else:
                            todo.append(key)
                        continue
                    if on_run_done is not None:
                        on_run_done(key)
            pool.shutdown(wait=True, cancel_futures=True)
    finally:
        for k, v in saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    _raise_failures(errors)
    return {key: results[key] for key in spec.runs}


class _RayPlan(NamedTuple):
    """The driver's side of a Ray sweep: what to run, where its files go, how to chunk it."""

    spec: SweepSpec
    out: Path
    keep_checkpoints: int
    chunk_generations: int
    #: The sweep's TensorBoard directory (None: no monitoring).
    tensorboard: Path | None = None

    def next_chunk(self, member: SweepRun) -> RunChunk:
        """The task that advances ``member`` from the newest checkpoint in its run directory."""

        newest = latest_checkpoint(run_dir(self.out, *member) / CHECKPOINT_DIR)
        return RunChunk(
            member.method,
            member.seed,
            self.spec.generations,
            self.chunk_generations,
            self.spec.settings_of(member.cell),
            self.spec.policies,
            self.keep_checkpoints,
            None if newest is None else (newest.name, newest.read_bytes()),
            self.spec.max_steps,
            self.tensorboard is not None,
            self.spec.plugins,
        )

    def store(self, member: SweepRun, result: ChunkResult) -> None:
        """Write a chunk's files into ``member``'s run directory, atomically, in the order
        :func:`evolution.lab.api.run` writes them (checkpoints, tables, records), then prune."""
        from cyber_rodent.atomic import write_bytes

        directory = run_dir(self.out, *member)

        def order(name: str) -> tuple[bool, bool, str]:
            return (not name.startswith(f"{CHECKPOINT_DIR}/"), name == RUN_FILE, name)

        for name in sorted(result.files, key=order):
            relative = Path(name)
            if relative.is_absolute() or ".." in relative.parts:
                raise ValueError(f"a Ray task returned a file outside its run directory: {name}")
            target = directory / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            write_bytes(target, result.files[name])
        prune_checkpoints(directory / CHECKPOINT_DIR, self.keep_checkpoints)


def _sweep_ray(
    plan: _RayPlan,
    workers: int | None,
    address: str,
    max_retries: int,
    bar: _Progress,
    poll_seconds: float,
    on_run_done: Callable[[SweepRun], None] | None = None,
) -> dict[SweepRun, pd.DataFrame]:
    try:
        import ray
    except ImportError:
        message = "the Ray executor needs ray: pip install 'cyber-rodent[cluster]'"
        raise ValueError(message) from None
    started_here = not ray.is_initialized()
    if started_here:
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "runtime_env": {"env_vars": dict(WORKER_ENV)},
        }
        try:
            if address == "local":
                init_local_ray(ray, num_cpus=workers or os.cpu_count() or 1, **kwargs)
            else:
                ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError) as err:
            hint = ""
            if address != "local" and "RAY_AUTH_MODE" not in os.environ:
                hint = (
                    " (a cluster with token authentication, the default where `ray start` "
                    "found ~/.ray/auth_token, needs RAY_AUTH_MODE=token and its token in "
                    "~/.ray/auth_token or RAY_AUTH_TOKEN)"
                )
            raise ValueError(
                f"cannot connect to the Ray cluster at {address}: {err}{hint}"
            ) from None
    writers: dict[SweepRun, TensorBoardWriter] = {}  # with plan.tensorboard, one per run
    try:
        # Retries are the driver's, from the checkpoint it holds: Ray's own would resend a
        # chunk's arguments, but count per chunk rather than per run.
        remote = ray.remote(num_cpus=1, max_retries=0)(advance_run)
        spec = plan.spec
        todo = deque(spec.runs)
        running: dict[Any, SweepRun] = {}
        results: dict[SweepRun, pd.DataFrame] = {}
        failures: dict[SweepRun, int] = {}
        errors: dict[SweepRun, BaseException] = {}

        def submit(member: SweepRun, error: BaseException | None = None) -> None:
            task = plan.next_chunk(member)
            if plan.tensorboard is not None and member not in writers:
                # From the generation the run stands at: steps an interrupted sweep wrote
                # past the run's checkpoint are replaced (evolution.lab.monitor).
                start = 0 if task.checkpoint is None else _generation_of(task.checkpoint[0])
                writers[member] = TensorBoardWriter(run_dir(plan.tensorboard, *member), start)
            if error is not None:
                held = 0 if task.checkpoint is None else _generation_of(task.checkpoint[0])
                cell = f" in {member.cell}" if member.cell else ""
                why = (str(error).strip().splitlines() or [""])[0].split(". ")[0][:160]
                print(
                    f"sweep: {member.method} seed {member.seed}{cell}: {type(error).__name__}"
                    f"{': ' + why if why else ''}; retry {failures[member]} of {max_retries} "
                    f"from generation {held}",
                    file=sys.stderr,
                    flush=True,
                )
            running[remote.remote(task)] = member

        refreshed = time.monotonic()
        while todo or running:
            # Runs under way continue first and new ones start in spec.runs order, as many as
            # the cluster's CPUs (now, after nodes left or joined): a sweep stopped part-way has
            # whole seeds done, as locally.
            cpus = ray.cluster_resources().get("CPU", 0)  # type: ignore[no-untyped-call]
            slots = max(1, int(cpus))
            while todo and len(running) < min(slots, workers or slots):
                submit(todo.popleft())
            done, _ = ray.wait(list(running), num_returns=1, timeout=poll_seconds)
            for ref in done:
                member = running.pop(ref)
                try:
                    result: ChunkResult = ray.get(ref)
                    plan.store(member, result)
                    for record in result.generations:
                        writers[member].write(record)
                except Exception as err:  # a lost node or worker, an error in the run
                    failures[member] = failures.get(member, 0) + 1
                    if failures[member] > max_retries:
                        errors[member] = _cause(err)
                    else:
                        submit(member, _cause(err))  # from the driver's newest checkpoint
                    continue
                if result.finished:
                    results[member] = result.table
                    if on_run_done is not None:
                        on_run_done(member)
                else:
                    submit(member)
            if not done or time.monotonic() - refreshed >= poll_seconds:
                bar.update()
                refreshed = time.monotonic()
        _raise_failures(errors)
        return {key: results[key] for key in spec.runs}
    finally:
        for writer in writers.values():
            writer.close()
        if started_here:
            ray.shutdown()


def init_local_ray(ray: Any, **kwargs: Any) -> None:
    """Start a Ray instance on this machine (``--ray local``) whose every process listens on
    loopback only: no port of it is reachable from the network.

    ``ray.init(_node_ip_address="127.0.0.1")`` alone does not do it: while Ray allows
    multi-node clusters (on Linux, always) it replaces a loopback node address by this machine's
    network address, and its servers then listen on every interface. The switch it reads for
    that (``ray_constants.ENABLE_RAY_CLUSTER``, which ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``
    turns off for a whole process) is turned off only while this one-node instance starts,
    then restored, so the process can still drive a real cluster later. The switch is not
    public API: where a Ray version lacks it, Ray starts as it would without it, and
    ``tests/test_ray_cluster.py`` (which lists the instance's listening sockets) fails.

    Args:
        ray: the ``ray`` module.
        **kwargs: ``ray.init``'s other arguments.
    """
    constants: Any = None
    try:
        from ray._private import ray_constants

        constants = ray_constants
    except ImportError:
        pass
    saved = getattr(constants, "ENABLE_RAY_CLUSTER", None)
    if saved is not None:
        constants.ENABLE_RAY_CLUSTER = False
    try:
        ray.init(_node_ip_address=LOOPBACK, **kwargs)
    finally:
        if saved is not None:
            constants.ENABLE_RAY_CLUSTER = saved


def _generation_of(checkpoint: str) -> int:
    """Generations completed when a checkpoint ``gen_NNNNN.ckpt`` was written."""
    match = re.fullmatch(r"gen_(\d+)\.ckpt", checkpoint)
    return int(match.group(1)) if match else 0


def _cause(err: BaseException) -> BaseException:
    """The error a Ray task raised, not Ray's wrapper with its remote traceback."""
    cause = getattr(err, "cause", None)
    return cause if isinstance(cause, BaseException) else err


class SweepFailed(RuntimeError):
    """Some runs of a sweep failed even after their retries (the others are on disk)."""


def _raise_failures(errors: dict[SweepRun, BaseException]) -> None:
    if errors:
        lines = "; ".join(
            f"{m} seed {s}{' in ' + c if c else ''}: {type(e).__name__}: {e}"
            for (m, s, c), e in sorted(errors.items())
        )
        raise SweepFailed(f"{len(errors)} run(s) failed after retries: {lines}")


def load_sweep(
    out_dir: str | os.PathLike[str], methods: Sequence[str] | None = None
) -> dict[str, list[pd.DataFrame]]:
    """Statistics tables of every run directory under ``out_dir``, grouped by method (every
    scheme's, or only ``methods``).

    Also accepts a single run directory (one holding ``statistics.csv``).
    """
    out = Path(out_dir)
    found: dict[str, list[pd.DataFrame]] = {}
    if (out / "statistics.csv").exists():
        candidates = [out]
    else:
        candidates = sorted(p for p in out.iterdir() if p.is_dir()) if out.is_dir() else []
    for path in candidates:
        m = re.fullmatch(r"([a-z][a-z0-9_]*)-seed(\d+)", path.name)
        method = m.group(1) if m else _method_of(path)
        wanted = methods is None or method in methods
        if method is not None and wanted and (path / "statistics.csv").exists():
            found.setdefault(method, []).append(pd.read_csv(path / "statistics.csv"))
    return found


def _method_of(path: Path) -> str | None:
    try:
        record = json.loads((path / "run.json").read_text())
        method = record["config"]["method"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return method if isinstance(method, str) else None
