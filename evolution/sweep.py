"""Many runs (grid cells × methods × seeds) in parallel: local processes, or a Ray cluster.

Each run is independent and its result depends only on its config and seed, so a sweep gives
identical tables whichever executor or how many workers ran it. Every run writes its own run
directory ``<out>/<method>-seed<NNN>`` (``<out>/<cell>/<method>-seed<NNN>`` in a sweep over a
grid of settings, :mod:`evolution.grid`) through :func:`evolution.api.run`, checkpointing every
generation; a run whose worker fails or is killed is submitted again with ``resume=True`` and
continues from its last checkpoint, so a retry costs at most one generation and changes nothing
in the result.

Backends:

- ``local`` (default): one process per run, ``workers`` at a time (``spawn`` start method, so
  MuJoCo and OpenGL state never crosses a ``fork``). A killed worker breaks a
  ``ProcessPoolExecutor``; the pool is rebuilt and the unfinished runs resumed.
- ``ray``: each run is a Ray task (``num_cpus=1``) on an existing cluster
  (``ray_address="auto"`` or ``"host:port"``) or on a fresh local one (``"local"``). Ray retries
  a task whose worker died (``max_retries``). For retries to resume rather than restart, the
  output directory must be on a filesystem the workers share; without one a retried run starts
  again from scratch, with the same result.

Progress: an aggregate bar over all runs' generations, with ETA and the latest mean batteries
and matings, read from the runs' ``statistics.csv`` files as they are rewritten.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import os
import re
import socket
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd

from cyber_rodent.validation import check_integer, choice, validate_fields
from evolution.grid import Cell, Grid, cells

METHODS = ("ee", "ce")
EXECUTORS = ("local", "ray")
POLICIES = ("trained", "reactive")
#: Environment for worker processes: one BLAS / llvmpipe thread each, since runs already fill
#: the cores one process per run.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "LP_NUM_THREADS": "1"}


class SweepRun(NamedTuple):
    """One member of a sweep: a method and seed, in a grid cell ("" without a grid)."""

    method: str
    seed: int
    cell: str = ""


@dataclass(frozen=True)
class SweepSpec:
    """What a sweep runs.

    Attributes:
        methods: subset of ``("ee", "ce")``.
        seeds: the seeds, each run once per method (and cell).
        generations: generations per run.
        overrides: settings passed to every run (see :func:`evolution.api.make_config`).
        policies: basic behaviours: ``"trained"`` (the shipped values) or ``"reactive"`` (the
            hand-written baseline).
        grid: axes of settings, ``((dotted key, values), ...)``; every cell of their product
            runs every method and seed, its settings over ``overrides``. Empty: one cell.
    """

    methods: tuple[str, ...]
    seeds: tuple[int, ...]
    generations: int
    overrides: dict[str, Any] = field(default_factory=dict)
    policies: str = choice("trained", POLICIES)
    grid: Grid = ()

    def __post_init__(self) -> None:
        validate_fields(self)
        if not self.methods or any(m not in METHODS for m in self.methods):
            raise ValueError(
                f"methods must be a non-empty subset of {METHODS}, got {self.methods!r}"
            )
        if len(set(self.methods)) != len(self.methods):
            raise ValueError(f"methods must not repeat, got {self.methods!r}")
        if not self.seeds or len(set(self.seeds)) != len(self.seeds):
            raise ValueError(f"seeds must be a non-empty list without repeats, got {self.seeds!r}")
        for seed in self.seeds:
            check_integer("seed", seed, 0)
        check_integer("generations", self.generations, 1)

    @property
    def cells(self) -> tuple[Cell, ...]:
        """The grid's cells (one unnamed cell without a grid)."""
        return cells(self.grid) or (Cell("", {}),)

    @property
    def runs(self) -> list[SweepRun]:
        """Every (method, seed, cell) in a fixed order: cell by cell, seed by seed, then method.

        Workers take runs in this order, so a sweep stopped part-way (a session's end, a
        cluster's time limit) has finished whole seeds of every method, which are comparable,
        rather than every seed of one method and none of the other.
        """
        return [
            SweepRun(m, s, c.name) for c in self.cells for s in self.seeds for m in self.methods
        ]

    def settings_of(self, cell: str) -> dict[str, Any]:
        """The settings of the runs in ``cell``: the sweep's overrides, then the cell's."""
        from evolution.settings import merge

        chosen = next(c for c in self.cells if c.name == cell)
        return merge(self.overrides, chosen.settings)

    def check(self) -> None:
        """Build every cell's config for every method, so a bad setting fails before any run.

        Raises:
            ValueError: the first setting a config refuses (one line naming the key).
        """
        from evolution.api import make_config

        for c in self.cells:
            for method in self.methods:
                make_config(method, **self.settings_of(c.name))


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
        seeds.extend(range(lo, hi + 1))
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"bad seed range {text!r}: a seed appears twice")
    return tuple(seeds)


def run_dir(out_dir: str | os.PathLike[str], method: str, seed: int, cell: str = "") -> Path:
    """The run directory of one sweep member."""
    return Path(out_dir) / cell / f"{method}-seed{seed:03d}"


def run_one(
    method: str,
    seed: int,
    generations: int,
    out: str,
    overrides: dict[str, Any],
    policies: str = "trained",
) -> pd.DataFrame:
    """Run (or resume) one sweep member in its run directory; the worker entry point."""
    from behaviours import BehaviourPolicies
    from evolution.api import run

    chosen = BehaviourPolicies.reactive() if policies == "reactive" else None
    return run(method, generations, seed, out_dir=out, resume=True, policies=chosen, **overrides)


def check_ray_address(address: str, timeout: float = 3.0) -> None:
    """Fail fast, with a clear message, if a ``host:port`` Ray address does not answer.

    ``auto`` and ``local`` are not checked here (Ray resolves them itself).

    Raises:
        ValueError: the address is malformed or nothing listens there.
    """
    if address in ("auto", "local") or address.startswith("ray://"):
        target = address.removeprefix("ray://")
        if target in ("auto", "local"):
            return
    else:
        target = address
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
        raise ValueError(f"cannot reach a Ray cluster at {address}: {err}") from None


class _Progress:
    """Aggregate progress over a sweep's run directories (polls their statistics.csv)."""

    def __init__(self, spec: SweepSpec, out_dir: Path, enabled: bool):
        self.spec = spec
        self.out_dir = out_dir
        self.total = len(spec.runs) * spec.generations
        self.bar = None
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(
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


def sweep(
    spec: SweepSpec,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    executor: str = "local",
    ray_address: str = "local",
    max_retries: int = 2,
    progress: bool = True,
    poll_seconds: float = 2.0,
) -> dict[SweepRun, pd.DataFrame]:
    """Run every (method, seed, cell) of ``spec``; return their statistics tables.

    Args:
        spec: methods, seeds, generations and overrides.
        out_dir: parent directory of the run directories (and of the cells' directories).
        workers: concurrent runs for the local executor (default: the number of CPUs).
        executor: ``"local"`` (one process per run) or ``"ray"`` (one Ray task per run).
        ray_address: with ``executor="ray"``: ``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:PORT"``
            or ``"local"`` (start a Ray instance on this machine with ``workers`` CPUs).
        max_retries: how often a failed run is resubmitted (it resumes from its checkpoint).
        progress: show the aggregate progress bar.
        poll_seconds: how often progress is refreshed.

    Raises:
        ValueError: bad arguments or an unreachable Ray address (before any run starts).
        SweepFailed: a run still failed after ``max_retries`` retries (the others finish
            first; their results stay on disk).
    """
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS}, got {executor!r}")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if not isinstance(max_retries, int) or max_retries < 0:
        raise ValueError(f"max_retries must be an integer >= 0, got {max_retries!r}")
    from evolution.grid import check_grid, write_grid

    spec.check()  # every cell's settings, before anything runs
    if executor == "ray":
        check_ray_address(ray_address)
    out = Path(out_dir)
    check_grid(out, spec.grid)
    out.mkdir(parents=True, exist_ok=True)
    if spec.grid:
        write_grid(out, spec.grid)
    bar = _Progress(spec, out, progress)
    try:
        if executor == "local":
            return _sweep_local(
                spec, out, workers or os.cpu_count() or 1, max_retries, bar, poll_seconds
            )
        return _sweep_ray(spec, out, workers, ray_address, max_retries, bar, poll_seconds)
    finally:
        bar.close()


def _sweep_local(
    spec: SweepSpec, out: Path, workers: int, max_retries: int, bar: _Progress, poll_seconds: float
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
                    member.method,
                    member.seed,
                    spec.generations,
                    str(run_dir(out, *member)),
                    spec.settings_of(member.cell),
                    spec.policies,
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
            pool.shutdown(wait=True, cancel_futures=True)
    finally:
        for k, v in saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    _raise_failures(errors)
    return {key: results[key] for key in spec.runs}


def _sweep_ray(
    spec: SweepSpec,
    out: Path,
    workers: int | None,
    address: str,
    max_retries: int,
    bar: _Progress,
    poll_seconds: float,
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
        if address == "local":
            kwargs["num_cpus"] = workers or os.cpu_count() or 1
        else:
            kwargs["address"] = address
        try:
            ray.init(**kwargs)
        except (ConnectionError, RuntimeError) as err:
            raise ValueError(f"cannot connect to the Ray cluster at {address}: {err}") from None
    try:
        remote = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=True)(run_one)
        refs = {
            remote.remote(
                member.method,
                member.seed,
                spec.generations,
                str(run_dir(out, *member).resolve()),
                spec.settings_of(member.cell),
                spec.policies,
            ): member
            for member in spec.runs
        }
        results: dict[SweepRun, pd.DataFrame] = {}
        errors: dict[SweepRun, BaseException] = {}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1, timeout=poll_seconds)
            bar.update()
            for ref in done:
                key = refs[ref]
                try:
                    results[key] = ray.get(ref)
                except Exception as err:  # retries exhausted
                    errors[key] = err
        _raise_failures(errors)
        return {key: results[key] for key in spec.runs}
    finally:
        if started_here:
            ray.shutdown()


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
    out_dir: str | os.PathLike[str], methods: Sequence[str] = METHODS
) -> dict[str, list[pd.DataFrame]]:
    """Statistics tables of every run directory under ``out_dir``, grouped by method.

    Also accepts a single run directory (one holding ``statistics.csv``).
    """
    out = Path(out_dir)
    found: dict[str, list[pd.DataFrame]] = {}
    if (out / "statistics.csv").exists():
        candidates = [out]
    else:
        candidates = sorted(p for p in out.iterdir() if p.is_dir()) if out.is_dir() else []
    for path in candidates:
        m = re.fullmatch(r"(ee|ce)-seed(\d+)", path.name)
        method = m.group(1) if m else _method_of(path)
        if method is not None and method in methods and (path / "statistics.csv").exists():
            found.setdefault(method, []).append(pd.read_csv(path / "statistics.csv"))
    return found


def _method_of(path: Path) -> str | None:
    import json

    try:
        record = json.loads((path / "run.json").read_text())
        method = record["config"]["method"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return method if isinstance(method, str) else None
