"""Live monitoring: each generation's statistics written to TensorBoard as it closes.

``statistics.csv`` is rewritten after each checkpoint and read at the end; this module shows a
run while it goes. It subscribes to the run loop's one seam, ``on_generation(runner)``, which
:func:`evolution.runner.loop.run_generations` calls after every control step that closed one or
more generations; the science core knows nothing of TensorBoard (nor of this package), and
nothing here runs inside a generation, so the hot loop is untouched. Reading the runner's
statistics and population draws no random number and changes no state: a run's results are the
same, byte for byte, with and without monitoring (tested).

Each closed generation ``g`` becomes one TensorBoard step ``g`` holding:

- every numeric column of its ``statistics.csv`` row (:class:`~evolution.stats.GenerationStats`
  and ``closed_at_step``) as a scalar, grouped by :data:`SCALAR_TAGS`: ``batteries/mean``,
  ``batteries/std``, ``matings/mean``, ``agents/completed``, ``agents/deaths``, ...;
- the spread of the evolved controllers: ``weights/spread``, the mean over the controller's 39
  weights of their standard deviation across the population (0 when every agent has the same
  controller), and ``weights/mean_abs``;
- ``weights/population``: a histogram of every weight of every agent of the population.

The population is every slot's current agent at the moment the generation closed (for EE,
mostly the agents of the next generation, since a generation closes once its slots have
passed it); a step that closes two generations at once gives both the same population.

TensorBoard stores scalars as 32-bit floats: counts are exact, means and standard deviations
are rounded to float32; ``statistics.csv`` stays the exact record.

**One TensorBoard run per run directory**: :func:`evolution.lab.api.run` writes into the
directory it is given; ``evolve --tensorboard DIR`` into ``DIR/<name of the run directory>``; a
sweep into ``DIR/<cell>/<method>-seed<NNN>``, mirroring its run directories, so that
``tensorboard --logdir DIR`` overlays the runs.

**Resume** starts a new event file in the same directory (TensorBoard reads every event file of
a directory as one run, in order). Its first event is a restart marker at the first generation
the resumed run will close, N, the generations of its checkpoint: TensorBoard discards the
steps >= N written before the interruption (a run checkpointing every k generations may have
written up to k - 1 generations past its last checkpoint, which the resumed run closes again,
with the same values) and keeps the earlier ones, so every generation appears once. The
writer does the same for a new run in a directory that holds another run's events: its
steps replace the old ones.

TensorBoard is an optional extra (``pip install 'cyber-rodent[monitor]'``): the package
``tensorboard`` provides both the viewer and the writer used here
(``tensorboard.summary.writer``, the event-file writer under ``torch.utils.tensorboard``'s,
which needs neither torch nor TensorFlow). :func:`check_tensorboard` refuses a missing package
or an unusable directory before anything is created.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evolution.stats import GenerationStats

if TYPE_CHECKING:
    from evolution.runner import EvolutionRunner

#: The extra that installs the writer.
EXTRA = "monitor"
INSTALL = f"pip install 'cyber-rodent[{EXTRA}]'"
#: TensorBoard tag of each statistics column; a column not listed is ``statistics/<name>``.
SCALAR_TAGS = {
    "batteries_mean": "batteries/mean",
    "batteries_std": "batteries/std",
    "batteries_full_life_mean": "batteries/full_life_mean",
    "matings_mean": "matings/mean",
    "matings_std": "matings/std",
    "completed": "agents/completed",
    "full_lifetimes": "agents/full_lifetimes",
    "unmated": "agents/unmated",
    "deaths": "agents/deaths",
    "reproductions": "reproduction/reproductions",
    "crossovers": "reproduction/crossovers",
    "new_offspring": "births/offspring",
    "new_from_spare": "births/from_spare",
    "new_random": "births/random",
    "random_share": "births/random_share",
    "spare_list_size": "births/spare_list_size",
    "closed_at_step": "run/closed_at_step",
}
WEIGHT_SPREAD_TAG = "weights/spread"
WEIGHT_MEAN_ABS_TAG = "weights/mean_abs"
WEIGHT_HISTOGRAM_TAG = "weights/population"
#: Buckets of the weight histogram.
HISTOGRAM_BINS = 30


def tag_of(column: str) -> str:
    """The TensorBoard tag of a ``statistics.csv`` column."""
    return SCALAR_TAGS.get(column, f"statistics/{column}")


def require_tensorboard(flag: str = "--tensorboard") -> None:
    """Raise ValueError (one line naming ``flag`` and the extra) if the writer is missing."""
    try:
        import tensorboard.compat.proto.event_pb2  # noqa: F401
        import tensorboard.summary.writer.event_file_writer  # noqa: F401
    except ImportError:
        raise ValueError(f"{flag} needs tensorboard: {INSTALL}") from None


def check_tensorboard(directory: str | os.PathLike[str], flag: str = "--tensorboard") -> Path:
    """Check that TensorBoard's writer is installed and that ``directory`` can receive event
    files (it is a directory, or can be made in one that is writable); create nothing.

    Raises:
        ValueError: one line naming ``flag``: the package is missing (and the extra that
            installs it), or the path is a file, lies under a file, or is not writable.
    """
    require_tensorboard(flag)
    path = Path(directory).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"{flag} {path} is a file, not a directory")
    existing = path.resolve()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{flag} {path}: {existing} is a file, not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{flag} {path}: {existing} is not writable")
    return path


# --- what one generation shows --------------------------------------------------------------
@dataclass(frozen=True)
class GenerationRecord:
    """What TensorBoard shows of one closed generation (plain data: it travels from a Ray
    task to the driver, which writes it).

    Attributes:
        generation: the generation, TensorBoard's step.
        scalars: tag -> value (:func:`tag_of` of each statistics column, and the weights'
            spread).
        weights: (population, controller weights) of the population when it closed.
    """

    generation: int
    scalars: dict[str, float]
    weights: np.ndarray


def population_weights(runner: EvolutionRunner) -> np.ndarray:
    """(population, 39): the controller weights of every slot's current agent, robot-major."""
    return np.stack([genome.controller for genome in runner.scheduler.population()])


def weight_scalars(weights: np.ndarray) -> dict[str, float]:
    """The spread of a population's controllers: mean over the weights of their standard
    deviation across the population (ddof 0), and the mean absolute weight."""
    return {
        WEIGHT_SPREAD_TAG: float(weights.std(axis=0).mean()),
        WEIGHT_MEAN_ABS_TAG: float(np.abs(weights).mean()),
    }


def statistics_scalars(row: GenerationStats, closed_at_step: int) -> dict[str, float]:
    """A ``statistics.csv`` row's numeric columns by tag (the generation is the step)."""
    values: dict[str, Any] = dataclasses.asdict(row)
    del values["generation"]
    values["closed_at_step"] = closed_at_step
    return {tag_of(name): float(value) for name, value in values.items()}


def generation_records(runner: EvolutionRunner, start: int) -> list[GenerationRecord]:
    """The records of the generations ``start, ...`` that ``runner`` has closed."""
    rows = runner.scheduler.stats.rows
    closed = min(len(rows), runner.completed_generations)
    if closed <= start:
        return []
    weights = population_weights(runner)
    spread = weight_scalars(weights)
    return [
        GenerationRecord(
            g, {**statistics_scalars(rows[g], runner.generation_steps[g]), **spread}, weights
        )
        for g in range(start, closed)
    ]


class GenerationMonitor:
    """An ``on_generation`` callback: hands each generation's record to ``sink`` once.

    Args:
        sink: called with each :class:`GenerationRecord`, in generation order.
        start: the first generation to hand over (a resumed run's completed generations).
    """

    def __init__(self, sink: Callable[[GenerationRecord], object], start: int = 0) -> None:
        self.sink = sink
        self.next = start

    def __call__(self, runner: EvolutionRunner) -> None:
        for record in generation_records(runner, self.next):
            self.sink(record)
            self.next = record.generation + 1


# --- the writer -----------------------------------------------------------------------------
class TensorBoardWriter:
    """Writes :class:`GenerationRecord` s into one TensorBoard run directory.

    Opening starts a new event file whose first event is a restart marker at ``start`` (see
    the module docstring: TensorBoard then discards any step >= ``start`` of earlier files of
    the directory). Every record is flushed to disk as it is written, so TensorBoard shows it
    on its next reload.

    Args:
        directory: the TensorBoard run directory (created if missing).
        start: the first generation this writer will write.
    """

    def __init__(self, directory: str | os.PathLike[str], start: int = 0) -> None:
        from tensorboard.compat.proto import event_pb2, summary_pb2
        from tensorboard.summary.writer.event_file_writer import EventFileWriter

        self.directory = Path(directory)
        self._event_pb2 = event_pb2
        self._summary_pb2 = summary_pb2
        self._writer = EventFileWriter(str(self.directory))
        start_event = event_pb2.Event(
            wall_time=time.time(),
            step=start,
            session_log=event_pb2.SessionLog(status=event_pb2.SessionLog.START),
        )
        self._writer.add_event(start_event)
        self._writer.flush()

    def write(self, record: GenerationRecord) -> None:
        """Write one generation's scalars and weight histogram, and flush."""
        summary = self._summary_pb2
        values = [
            summary.Summary.Value(tag=tag, simple_value=value)
            for tag, value in record.scalars.items()
        ]
        values.append(
            summary.Summary.Value(tag=WEIGHT_HISTOGRAM_TAG, histo=self._histogram(record.weights))
        )
        event = self._event_pb2.Event(
            wall_time=time.time(), step=record.generation, summary=summary.Summary(value=values)
        )
        self._writer.add_event(event)
        self._writer.flush()

    def _histogram(self, weights: np.ndarray) -> Any:
        """TensorBoard's histogram of ``weights``: bucket i counts (limit[i - 1], limit[i]],
        the first from the minimum."""
        values = np.asarray(weights, dtype=np.float64).ravel()
        counts, edges = np.histogram(values, bins=HISTOGRAM_BINS)
        return self._summary_pb2.HistogramProto(
            min=float(values.min()),
            max=float(values.max()),
            num=float(values.size),
            sum=float(values.sum()),
            sum_squares=float(values @ values),
            bucket_limit=edges[1:].tolist(),
            bucket=counts.astype(np.float64).tolist(),
        )

    def close(self) -> None:
        """Flush and close the event file."""
        self._writer.close()

    def __enter__(self) -> TensorBoardWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class TensorBoardMonitor(GenerationMonitor):
    """An ``on_generation`` callback writing each closed generation to TensorBoard.

    Args:
        directory: the TensorBoard run directory.
        start: generations the runner has already completed (its checkpoint's).
    """

    def __init__(self, directory: str | os.PathLike[str], start: int = 0) -> None:
        self.writer = TensorBoardWriter(directory, start)
        super().__init__(self.writer.write, start)

    def close(self) -> None:
        self.writer.close()

    def __enter__(self) -> TensorBoardMonitor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = [
    "EXTRA",
    "INSTALL",
    "SCALAR_TAGS",
    "GenerationMonitor",
    "GenerationRecord",
    "TensorBoardMonitor",
    "TensorBoardWriter",
    "check_tensorboard",
    "generation_records",
    "require_tensorboard",
    "tag_of",
]
