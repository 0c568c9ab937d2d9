"""The run loop: step a runner until its generations are complete, with checkpoints and progress.

:meth:`EvolutionRunner.run <evolution.runner.step.EvolutionRunner.run>` calls
:func:`run_generations`. The step itself knows nothing of files or terminals; this loop writes
a checkpoint whenever enough generations have completed, keeps only the newest ones, and shows
a progress bar.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

from cyber_rodent.validation import check_integer
from evolution.runner.checkpoints import checkpoint_path, prune_checkpoints
from evolution.scheduler import CentralisedEvolution, EmbodiedEvolution

if TYPE_CHECKING:
    import pandas as pd

    from evolution.runner.config import RunConfig
    from evolution.scheduler import TimeSharingScheduler

#: Control steps between progress-bar refreshes while a generation is under way.
PROGRESS_EVERY = 500


class SteppedRun(Protocol):
    """What the loop drives: the members of :class:`evolution.runner.step.EvolutionRunner` it
    reads, named here so that the runner, which runs this loop, and the loop do not import each
    other."""

    config: RunConfig
    seed: int
    steps: int
    scheduler: TimeSharingScheduler

    @property
    def completed_generations(self) -> int: ...

    def step(self) -> bool: ...

    def save_checkpoint(self, path: str | os.PathLike[str]) -> Path: ...

    def statistics(self) -> pd.DataFrame: ...


Run = TypeVar("Run", bound=SteppedRun)


def run_generations(
    runner: Run,
    generations: int,
    *,
    checkpoint_dir: str | os.PathLike[str] | None = None,
    checkpoint_every: int = 1,
    keep_checkpoints: int = 3,
    max_steps: int | None = None,
    progress: bool = False,
    on_generation: Callable[[Run], object] | None = None,
) -> pd.DataFrame:
    """Step ``runner`` until ``generations`` generations have completed; return its statistics.

    Args:
        runner: the run.
        generations: completed generations to reach (a resumed runner counts the ones it
            already has).
        checkpoint_dir: where to write checkpoints (``gen_NNNNN.ckpt``); None: none.
        checkpoint_every: write a checkpoint each time this many more generations have
            completed.
        keep_checkpoints: newest checkpoint files to keep (older ones are deleted after a
            newer one is safely written); 0 keeps all.
        max_steps: stop after this many control steps in total even if the generations
            are not complete (an EE slot whose agents keep dying never completes a
            generation); None: no limit.
        progress: show a tqdm progress bar over generations.
        on_generation: optional callable ``f(runner)`` after each control step that
            completed one or more generations (after their checkpoint): the seam through
            which run directories' tables and live monitors (:mod:`evolution.lab.monitor`)
            follow a run. It runs between steps, never inside one, and must not change the
            runner.

    Returns:
        ``runner.statistics()`` of the completed generations.
    """
    generations = check_integer("generations", generations, 0)
    checkpoint_every = check_integer("checkpoint_every", checkpoint_every, 1)
    keep_checkpoints = check_integer("keep_checkpoints", keep_checkpoints, 0)
    if max_steps is not None:
        max_steps = check_integer("max_steps", max_steps, 0)
    directory = Path(checkpoint_dir) if checkpoint_dir is not None else None
    if directory is not None:
        directory.mkdir(parents=True, exist_ok=True)
    bar = None
    if progress:
        from cyber_rodent.progress import progress_bar

        bar = progress_bar(
            total=generations, initial=min(runner.completed_generations, generations),
            unit="gen", desc=f"{runner.config.method.upper()} seed {runner.seed}",
        )  # fmt: skip
    step = runner.step
    last_saved = runner.completed_generations
    started, start_steps = time.perf_counter(), runner.steps
    try:
        while runner.completed_generations < generations:
            if max_steps is not None and runner.steps >= max_steps:
                break
            if not step():
                if bar is not None and runner.steps % PROGRESS_EVERY == 0:
                    show_progress(runner, bar, generations, started, start_steps)
                continue
            done = runner.completed_generations
            if directory is not None and done - last_saved >= checkpoint_every:
                runner.save_checkpoint(checkpoint_path(directory, done))
                last_saved = done
                prune_checkpoints(directory, keep_checkpoints)
            if bar is not None:
                show_progress(runner, bar, generations, started, start_steps)
            if on_generation is not None:
                on_generation(runner)
    finally:
        if bar is not None:
            bar.close()
    return runner.statistics()


def generation_progress(runner: SteppedRun) -> float:
    """Completed generations plus the share of the next one done (for progress bars).

    EE: the share of the slots (up to the closing quorum) already past the next generation;
    CE: the share of the population that has finished its lifetime.
    """
    done = runner.completed_generations
    scheduler = runner.scheduler
    share = 0.0
    if isinstance(scheduler, EmbodiedEvolution):
        ahead = int((scheduler.slot_generation > done).sum())
        share = ahead / scheduler.close_quorum
    elif isinstance(scheduler, CentralisedEvolution):
        share = float(scheduler.finished.mean())
    return done + min(share, 0.999)


def show_progress(
    runner: SteppedRun, bar: Any, generations: int, started: float, start_steps: int
) -> None:
    """Refresh ``bar``: generations (with the share of the next), steps, rate, last row."""
    rate = (runner.steps - start_steps) / max(time.perf_counter() - started, 1e-9)
    postfix = {"steps": runner.steps, "steps/s": f"{rate:.0f}"}
    rows = runner.scheduler.stats.rows
    if rows and rows[-1].completed:
        postfix["batteries"] = f"{rows[-1].batteries_mean:.1f}"
        postfix["matings"] = f"{rows[-1].matings_mean:.2f}"
    bar.set_postfix(postfix, refresh=False)
    bar.n = round(min(generation_progress(runner), generations), 3)
    bar.refresh()


__all__ = [
    "PROGRESS_EVERY",
    "SteppedRun",
    "generation_progress",
    "run_generations",
    "show_progress",
]
