"""Per-generation statistics, as the paper defines them (Fig. 6, Fig. 7, §2, §4.1).

The paper's headline numbers are, per generation, the mean and standard deviation of captured
batteries and of matings over the agents that *completed the survival task*: lived the full
lifetime and mated at least once. Next to those, the scheduler records what explains them:
deaths, full lifetimes without a mating, reproductions (and how many used crossover), new agents
by origin, the share of new agents that had to be random (the paper's motivation for the spare
list), and the spare-list size.

A generation means different things in the two methods (paper §4.1):

- **EE**: reproduction is asynchronous, so a generation is per slot: an agent belongs to the
  generation its slot has reached, and a slot advances when its agent lives the full lifetime.
  Row ``g`` collects everything that happened while a slot was at generation ``g`` (agents born
  into ``g``, deaths in ``g``, full lifetimes ending ``g``). It is closed, and its row written,
  once every slot has passed ``g``; ``spare_list_size`` is the total over robots at that moment.
- **CE**: a generation is the whole population's lifetime, closed at the generational
  replacement; ``spare_list_size`` is 0 (CE keeps no spare lists).

Standard deviations are population standard deviations (``ddof=0``); a generation with no agent
that completed the task has NaN mean and std.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from evolution.agent import Origin

_Row = TypeVar("_Row", "GenerationStats", "RobotGenerationStats")


@dataclass(frozen=True)
class GenerationStats:
    """One row of the statistics table.

    Attributes:
        generation: generation index, from 0.
        completed: agents that lived the full lifetime and mated at least once.
        batteries_mean: mean batteries captured by the completed agents (Fig. 6a).
        batteries_std: their standard deviation.
        matings_mean: mean matings of the completed agents (Fig. 6b).
        matings_std: their standard deviation.
        batteries_full_life_mean: mean batteries over every full lifetime, counting agents that
            never mated as 0 (the measure of Fig. 7).
        full_lifetimes: agents that lived the full lifetime.
        unmated: full lifetimes without any mating (no offspring).
        deaths: agents whose energy reached 0.
        reproductions: offspring made (EE: by completed agents; CE: new individuals).
        crossovers: reproductions that used crossover.
        new_offspring: new agents born as offspring (EE) or by selection (CE).
        new_from_spare: new agents drawn from a spare list.
        new_random: new agents made at random because the spare list was empty.
        random_share: ``new_random`` / all new agents (NaN if none was born).
        spare_list_size: genomes in all robots' spare lists when the generation closed.
    """

    generation: int
    completed: int
    batteries_mean: float
    batteries_std: float
    matings_mean: float
    matings_std: float
    batteries_full_life_mean: float
    full_lifetimes: int
    unmated: int
    deaths: int
    reproductions: int
    crossovers: int
    new_offspring: int
    new_from_spare: int
    new_random: int
    random_share: float
    spare_list_size: int


@dataclass(frozen=True)
class RobotGenerationStats:
    """One row of the per-robot table (Fig. 7 plots each robot separately).

    Attributes:
        generation: generation index, from 0.
        robot: the physical robot.
        batteries_mean: mean batteries over the robot's full lifetimes in this generation,
            agents that never mated scored 0 (the paper's Fig. 7 caption); NaN if none.
        full_lifetimes: full lifetimes on this robot in this generation.
        completed: of those, agents that mated at least once.
    """

    generation: int
    robot: int
    batteries_mean: float
    full_lifetimes: int
    completed: int


@dataclass
class _Tally:
    """What a still-open generation has seen so far."""

    batteries: list[int] = field(default_factory=list)
    matings: list[int] = field(default_factory=list)
    full_life_batteries: list[int] = field(default_factory=list)
    deaths: int = 0
    reproductions: int = 0
    crossovers: int = 0
    births: dict[int, int] = field(default_factory=dict)
    robot_full_life: dict[int, list[tuple[int, bool]]] = field(default_factory=dict)

    def state(self) -> dict[str, Any]:
        """Plain state; integer-keyed maps as ``[key, value]`` pairs in insertion order."""
        return {
            "batteries": list(self.batteries),
            "matings": list(self.matings),
            "full_life_batteries": list(self.full_life_batteries),
            "deaths": self.deaths,
            "reproductions": self.reproductions,
            "crossovers": self.crossovers,
            "births": [[origin, count] for origin, count in self.births.items()],
            "robot_full_life": [
                [robot, [[b, mated] for b, mated in lives]]
                for robot, lives in self.robot_full_life.items()
            ],
        }

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> _Tally:
        return cls(
            batteries=[int(b) for b in state["batteries"]],
            matings=[int(m) for m in state["matings"]],
            full_life_batteries=[int(b) for b in state["full_life_batteries"]],
            deaths=int(state["deaths"]),
            reproductions=int(state["reproductions"]),
            crossovers=int(state["crossovers"]),
            births={int(origin): int(count) for origin, count in state["births"]},
            robot_full_life={
                int(robot): [(int(b), bool(mated)) for b, mated in lives]
                for robot, lives in state["robot_full_life"]
            },
        )


def _mean_std(values: list[int]) -> tuple[float, float]:
    if not values:
        return math.nan, math.nan
    array = np.asarray(values, dtype=float)
    return float(array.mean()), float(array.std())


class StatisticsRecorder:
    """Collects events into open generations and turns each into a row when it closes."""

    def __init__(self) -> None:
        self._open: dict[int, _Tally] = {}
        #: Accept (and count in :attr:`late`) events of already-closed generations: EE rows close
        #: at a quorum of slots (``EvolutionConfig.ee_close_quorum``), so lagging slots report late.
        self.accept_late = False
        self.late = 0
        self.rows: list[GenerationStats] = []
        self.robot_rows: list[RobotGenerationStats] = []

    def _tally(self, generation: int) -> _Tally:
        tally = self._open.get(generation)
        if tally is None:
            if self.rows and generation <= self.rows[-1].generation:
                if self.accept_late:
                    self.late += 1
                    return _Tally()  # counted, not tallied: its row is already written
                raise RuntimeError(f"generation {generation} is already closed")
            tally = self._open[generation] = _Tally()
        return tally

    def record_full_life(
        self, generation: int, batteries: int, matings: int, robot: int | None = None
    ) -> None:
        """An agent of ``generation`` lived the full lifetime (on ``robot``, if given: the
        per-robot table counts it there)."""
        tally = self._tally(generation)
        tally.full_life_batteries.append(batteries if matings > 0 else 0)
        if robot is not None:
            per_robot = tally.robot_full_life
            per_robot.setdefault(int(robot), []).append((int(batteries), matings > 0))
        if matings > 0:
            tally.batteries.append(batteries)
            tally.matings.append(matings)

    def record_death(self, generation: int) -> None:
        """An agent of ``generation`` died (energy 0)."""
        self._tally(generation).deaths += 1

    def record_reproduction(self, generation: int, crossover: bool) -> None:
        """An agent of ``generation`` (EE), or the GA at the end of it (CE), made an offspring."""
        tally = self._tally(generation)
        tally.reproductions += 1
        tally.crossovers += int(crossover)

    def record_birth(self, generation: int, origin: Origin) -> None:
        """A new agent was born into ``generation``."""
        births = self._tally(generation).births
        births[int(origin)] = births.get(int(origin), 0) + 1

    def close(self, generation: int, spare_list_size: int) -> GenerationStats:
        """Turn ``generation``'s tally into a row; generations must close in order."""
        expected = self.rows[-1].generation + 1 if self.rows else 0
        if generation != expected:
            raise RuntimeError(f"closing generation {generation}, expected {expected}")
        tally = self._open.pop(generation, None) or _Tally()
        b_mean, b_std = _mean_std(tally.batteries)
        m_mean, m_std = _mean_std(tally.matings)
        full_mean, _ = _mean_std(tally.full_life_batteries)
        offspring = (
            tally.births.get(int(Origin.OFFSPRING), 0)
            + tally.births.get(int(Origin.SELECTED), 0)
            + tally.births.get(int(Origin.RECEIVED), 0)
        )
        spare = tally.births.get(int(Origin.SPARE), 0)
        random = tally.births.get(int(Origin.RANDOM), 0)
        born = offspring + spare + random
        row = GenerationStats(
            generation=generation,
            completed=len(tally.batteries),
            batteries_mean=b_mean,
            batteries_std=b_std,
            matings_mean=m_mean,
            matings_std=m_std,
            batteries_full_life_mean=full_mean,
            full_lifetimes=len(tally.full_life_batteries),
            unmated=len(tally.full_life_batteries) - len(tally.batteries),
            deaths=tally.deaths,
            reproductions=tally.reproductions,
            crossovers=tally.crossovers,
            new_offspring=offspring,
            new_from_spare=spare,
            new_random=random,
            random_share=random / born if born else math.nan,
            spare_list_size=int(spare_list_size),
        )
        self.rows.append(row)
        per_robot = tally.robot_full_life
        for robot in sorted(per_robot):
            lives = per_robot[robot]
            self.robot_rows.append(
                RobotGenerationStats(
                    generation=generation,
                    robot=robot,
                    batteries_mean=float(np.mean([b if mated else 0 for b, mated in lives])),
                    full_lifetimes=len(lives),
                    completed=sum(mated for _, mated in lives),
                )
            )
        return row

    def robot_records(self) -> list[dict[str, float | int]]:
        """The closed per-robot rows as plain dicts (generation, robot, batteries_mean, ...)."""
        return [dataclasses.asdict(row) for row in self.robot_rows]

    def to_records(self) -> list[dict[str, float | int]]:
        """The closed rows as plain dicts (what crosses package boundaries)."""
        return [dataclasses.asdict(row) for row in self.rows]

    def write_csv(self, path: str | os.PathLike[str]) -> None:
        """Write the closed rows as CSV (header = :class:`GenerationStats` fields)."""
        names = [f.name for f in dataclasses.fields(GenerationStats)]
        with open(path, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=names)
            writer.writeheader()
            writer.writerows(self.to_records())

    def state(self) -> dict[str, Any]:
        """The recorder's complete state as plain data: the open generations' tallies (in
        insertion order), the closed rows and the late-event counter (docs/design.md §10)."""
        return {
            "open": [[generation, tally.state()] for generation, tally in self._open.items()],
            "accept_late": self.accept_late,
            "late": self.late,
            "rows": [dataclasses.asdict(row) for row in self.rows],
            "robot_rows": [dataclasses.asdict(row) for row in self.robot_rows],
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """Replace this recorder's state with a :meth:`state`."""
        self._open = {int(g): _Tally.from_state(tally) for g, tally in state["open"]}
        self.accept_late = bool(state["accept_late"])
        self.late = int(state["late"])
        self.rows = [_row(GenerationStats, row) for row in state["rows"]]
        self.robot_rows = [_row(RobotGenerationStats, row) for row in state["robot_rows"]]


def _row(cls: type[_Row], values: dict[str, Any]) -> _Row:
    """A statistics row from its ``dataclasses.asdict`` form (exactly its fields)."""
    names = [f.name for f in dataclasses.fields(cls)]
    if sorted(values) != sorted(names):
        raise ValueError(f"{cls.__name__} row has fields {sorted(values)}")
    return cls(**values)
