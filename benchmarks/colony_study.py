"""The colony study: do 100 virtual agents on 4 robots evolve like 100 robots, one agent each?

The paper's colony is 4 robots, each time-sharing 25 of the 100 virtual agents. This study keeps
the population (100), Tables 1 and 2 (the defaults, so every agent lives 400 steps of its
robot's time, in slots of 100 steps wherever robots time-share) and the paper's density, and
varies the robots:

=====  ================  ===============  =====  ================
N      agents per robot  field side (m)   packs  methods
=====  ================  ===============  =====  ================
4      25                2.3              5      EE, CE
10     10                3.6366           13     EE
25     4                 5.75             31     EE
50     2                 8.1317           63     EE
100    1                 11.5             125    EE, CE
=====  ================  ===============  =====  ================

(field 2.3 m x sqrt(N / 4), 5 N / 4 packs rounded half up, as ``benchmarks/colony_scale.py``:
:func:`cell_settings`). Seeds 0-4, 60 generations each: 35 runs. At N = 100 there is no time
sharing: a robot's only agent has one slot of its whole 400-step life (with Table 1's 100-step
slots its robot would switch back to it every 100 steps, ending a recharge under way as a
switch to another agent does at N = 4).

    .venv/bin/python -m benchmarks.colony_study --run [--workers 2] [--ray ADDRESS]
    .venv/bin/python -m benchmarks.colony_study          # publish and analyse what finished

``--run`` runs the study as one sweep (:mod:`evolution.lab.sweep`, an explicit cell list, seed
by seed so that partial results cover every cell), or resumes it: finished runs are skipped,
interrupted runs continue from their checkpoints. Every setting is checked before anything
starts (a bad one exits with status 2 and one line), and a cost estimate is printed first (a
short-lifetime generation timed at each N, :func:`measure_step_costs`). As each run finishes
its small tables are published to ``--published`` (``results/colony_scale/<cell>/<method>-
seed<NNN>/``): ``statistics.csv``, ``statistics_per_robot.csv``, ``run.json`` and
``matings.csv``, a per-generation table derived from the run's ``events.csv`` (several MB per
run, not published; :func:`mating_table`).

Without ``--run`` (and after it) the analysis reads the published tables only and writes
``summary.csv`` (per cell and method), ``runs.csv`` (per run) and ``tests.csv`` (the
Mann-Whitney tests and Spearman trends) into ``--published``, the figure
``docs/images/colony_scale.png``, and prints a Markdown table. Each run contributes its mean
over generations 50-59 (:data:`FINAL_WINDOW`; the last 10 generations every run reached, if
fewer); cells with fewer seeds are reported with their ``runs``. The questions:

1. per generation: batteries and matings per life (over the agents that completed the task)
   against N; N = 4 against N = 100 for EE and for CE;
2. per unit of robot time: the generation, and the simulated robot-hours (world control steps
   x N x ``survival.control_dt`` / 3600, to the step at which the generation closed), at which
   a run's batteries reach :data:`REACH_SHARE` of its cell's final level (the mean over the
   cell's runs of their means over the window), and of the paper colony's level (the cell of
   :data:`PAPER_ROBOTS` robots, same method; a run that never reaches it is censored at the
   study's end and ranks above every run that did), batteries smoothed by a trailing mean
   over :data:`REACH_SMOOTHING` generations (:func:`reach_generation`); with the starting
   level (the mean over generations 0-4, :data:`FIRST_WINDOW`), which says whether there was
   a rise to reach at all;
3. who mates with whom: distinct partners per agent and life, and the distinct parents behind
   each generation's offspring and their effective number (:func:`mating_table`);
4. EE against CE at N = 100 (the paper: CE captures more batteries, EE mates more);
5. deaths and completions against N, and the share of newborns that are random genomes (EE
   replaces an agent that died, or lived without mating, from its robot's spare list, or with a
   random genome when that list is empty; descriptive, not tested).

``--walls`` checks question 1's reading: where are the robots? It replays the last generation
of each finished run in ``--out`` from its checkpoint (the replay must close it at the step
the run did), samples robots and packs every :data:`POSITION_EVERY` world steps, and writes
``walls.csv``: the share of robot centres within :data:`WALL_BAND` of a wall, against the
share of the reachable field there (:func:`wall_share`) and the packs' share, for the robots
running a random genome and the others, and the share of robots running an agent at all. It
needs the run directories, and takes about a sixtieth of the study's time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from benchmarks.colony_scale import paper_density  # noqa: E402
from benchmarks.publish_runs import finished, publish_run  # noqa: E402
from cyber_rodent.atomic import atomic_output, write_text  # noqa: E402
from cyber_rodent.robot import robot_model  # noqa: E402
from evolution.agent import Origin  # noqa: E402
from evolution.config import EvolutionConfig  # noqa: E402
from evolution.lab.api import RunOutput  # noqa: E402
from evolution.lab.comparison import available_window, rank_test  # noqa: E402
from evolution.lab.grid import Cell  # noqa: E402
from evolution.lab.sweep import (  # noqa: E402
    STEPS_PER_LIFE,
    Execution,
    SweepFailed,
    SweepRun,
    SweepSpec,
    check_ray_address,
    parse_seeds,
    run_dir,
    sweep,
)

#: Robots per colony, and the sizes CE runs at.
SIZES = (4, 10, 25, 50, 100)
CE_SIZES = (4, 100)
#: The paper's population, kept at every size.
POPULATION = 100
SEEDS = "0-4"
GENERATIONS = 60
#: Generations each run's mean is taken over (inclusive).
FINAL_WINDOW = (50, 59)
#: The paper's colony: question 2's practical target is its final level (same method).
PAPER_ROBOTS = 4
#: Generations whose mean is a run's starting level (question 2: how far batteries rose).
FIRST_WINDOW = (0, 4)
#: Share of the final level batteries must reach (question 2), and the trailing mean's width.
REACH_SHARE = 0.9
REACH_SMOOTHING = 5
#: Control steps of an agent's life (Table 1), and its setting: a cell of one agent per robot
#: gives it one slot of that length (:func:`cell_settings`).
LIFETIME = EvolutionConfig().lifetime_steps
LIFETIME_KEY = "evolution.lifetime_steps"
#: The settings each cell sets itself; ``--set`` may not touch them.
CELL_KEYS = ("evolution.n_robots", "evolution.population_size", "world.field_size",
             "world.n_packs")  # fmt: skip
#: The study's record in ``--out``: a resumed study must have the same plan.
STUDY_FILE = "study.json"
#: The per-generation table derived from a run's events.csv.
MATINGS_FILE = "matings.csv"
EVENTS_FILE = "events.csv"
#: Resamples of the Spearman trend's permutation test: exact (every ordering) up to 7 runs,
#: else drawn with a fixed seed, so that the p-value is the same at every analysis.
TREND_RESAMPLES = 19_999
TREND_SEED = 0
#: Robot-steps timed per size by the cost estimate (after a warm-up generation).
ESTIMATE_ROBOT_STEPS = 4_000
PROG = "colony_study"


class StudyError(ValueError):
    """A setting or argument the study refuses (exit status 2, one line)."""


# --- the cells ---------------------------------------------------------------------------------
def cell_name(n_robots: int) -> str:
    """The directory name of the cell with ``n_robots`` robots: ``n004``, ``n100``."""
    return f"n{n_robots:03d}"


def cell_settings(
    n_robots: int, population: int = POPULATION, lifetime: int = LIFETIME
) -> dict[str, Any]:
    """The settings of the cell with ``n_robots`` robots: ``population`` agents,
    ``population / n_robots`` per robot, at the paper's density (:func:`paper_density`).

    Where each robot carries one agent there is no time sharing: the agent's one slot lasts
    its whole ``lifetime``. With slots of Table 1's 100 steps the robot would switch back to
    the same agent every 100 steps, which ends a recharge in progress as a switch to another
    agent does, an artefact of time sharing the cell exists to leave out.
    """
    field_size, n_packs = paper_density(n_robots)
    settings: dict[str, Any] = {
        "evolution.n_robots": n_robots,
        "evolution.population_size": population,
        "world.field_size": field_size,
        "world.n_packs": n_packs,
    }
    if population == n_robots:
        settings["evolution.time_sharing_steps"] = lifetime
    return settings


def study_cells(
    sizes: Sequence[int] = SIZES,
    ce_sizes: Sequence[int] = CE_SIZES,
    population: int = POPULATION,
    lifetime: int = LIFETIME,
) -> tuple[Cell, ...]:
    """One cell per size: EE everywhere, CE at ``ce_sizes`` too."""
    return tuple(
        Cell(
            cell_name(n),
            cell_settings(n, population, lifetime),
            ("ee", "ce") if n in ce_sizes else ("ee",),
        )
        for n in sizes
    )


def study_spec(
    sizes: Sequence[int] = SIZES,
    ce_sizes: Sequence[int] = CE_SIZES,
    seeds: Sequence[int] = tuple(range(5)),
    generations: int = GENERATIONS,
    overrides: Mapping[str, Any] | None = None,
    population: int = POPULATION,
    members: Sequence[SweepRun] | None = None,
) -> SweepSpec:
    """The study as a sweep, seed by seed (every cell's seed 0 first).

    Raises:
        StudyError: sizes that repeat, CE sizes that are not sizes, a population a size does not
            divide, or ``overrides`` that set a cell's own keys.
    """
    if not sizes or len(set(sizes)) != len(sizes):
        raise StudyError(f"--sizes must be distinct robot counts, got {list(sizes)}")
    if any(n not in sizes for n in ce_sizes):
        raise StudyError(f"--ce-sizes {list(ce_sizes)} must be among --sizes {list(sizes)}")
    for n in sizes:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1 or population % n:
            raise StudyError(
                f"--sizes: {n} robots must divide the population ({population}) into equal "
                "subpopulations"
            )
    clash = sorted(set(overrides or {}) & set(CELL_KEYS))
    if clash:
        raise StudyError(f"--set {clash[0]}: every cell sets it (use --sizes or --population)")
    return SweepSpec(
        methods=("ee", "ce") if ce_sizes else ("ee",),
        seeds=tuple(seeds),
        generations=generations,
        overrides=dict(overrides or {}),
        cell_list=study_cells(
            sizes, ce_sizes, population, int((overrides or {}).get(LIFETIME_KEY, LIFETIME))
        ),
        order="seed",
        members=None if members is None else tuple(members),
    )


def n_robots_of(spec: SweepSpec, cell: str) -> int:
    """The robots of ``cell``."""
    return int(spec.settings_of(cell)["evolution.n_robots"])


# --- running and publishing ---------------------------------------------------------------------
def run_finished(path: Path) -> bool:
    """Has the run in ``path`` finished, its event log written (the last thing a run writes)?"""
    return finished(path) and (path / EVENTS_FILE).is_file()


def pending_runs(spec: SweepSpec, out: Path) -> list[SweepRun]:
    """The runs of ``spec`` not finished in ``out``, in the study's order."""
    return [m for m in spec.runs if not run_finished(run_dir(out, *m))]


def study_record(spec: SweepSpec, population: int) -> dict[str, Any]:
    """What ``study.json`` holds: the plan a resumed study must share."""
    return {
        "methods": list(spec.methods),
        "seeds": list(spec.seeds),
        "generations": spec.generations,
        "population": population,
        "overrides": {k: spec.overrides[k] for k in sorted(spec.overrides)},
        "cells": [
            {"name": c.name, "settings": dict(c.settings), "methods": list(spec.methods_of(c))}
            for c in spec.cells
        ],
    }


def check_study_dir(out: Path, record: Mapping[str, Any]) -> None:
    """Refuse an ``--out`` holding another study (or something else).

    Raises:
        StudyError: ``out`` is a file, holds another plan, or holds files but no study.
    """
    if out.exists() and not out.is_dir():
        raise StudyError(f"--out {out} is a file, not a directory")
    file = out / STUDY_FILE
    if file.exists():
        try:
            existing = json.loads(file.read_text())
        except (OSError, ValueError) as err:
            raise StudyError(f"{file}: unreadable ({err})") from None
        if existing != json.loads(json.dumps(record)):
            raise StudyError(
                f"--out {out} holds a study with another plan ({STUDY_FILE}); use the same "
                "arguments or another --out"
            )
    elif out.is_dir() and any(out.iterdir()):
        raise StudyError(f"--out {out} is not empty and holds no {STUDY_FILE}")


def publish_member(out: Path, published: Path, member: SweepRun) -> bool:
    """Publish one finished run's tables and its mating table; True if anything changed."""
    source = run_dir(out, *member)
    target = run_dir(published, *member)
    copied = publish_run(source, target)
    derived = target / MATINGS_FILE
    if copied or not derived.exists():
        record = json.loads((source / "run.json").read_text())
        statistics = pd.read_csv(source / "statistics.csv")
        closed_at = dict(zip(statistics["generation"].astype(int),
                             statistics["closed_at_step"].astype(int), strict=True))  # fmt: skip
        table = mating_table(pd.read_csv(source / EVENTS_FILE), record["config"], closed_at)
        target.mkdir(parents=True, exist_ok=True)
        with atomic_output(derived) as temp:
            table.to_csv(temp, index=False, float_format="%.6g")
        return True
    return copied


def publish_finished(out: Path, published: Path, spec: SweepSpec) -> list[SweepRun]:
    """Publish every finished run of ``spec`` in ``out`` not yet published as it stands; a run
    that cannot be published is named on stderr and left for the next call."""
    done = []
    for member in spec.runs if out.is_dir() else []:
        if run_finished(run_dir(out, *member)) and publish_quietly(out, published, member):
            done.append(member)
    return done


def publish_quietly(out: Path, published: Path, member: SweepRun) -> bool:
    """:func:`publish_member`, an error reported in one line instead of raised."""
    try:
        return publish_member(out, published, member)
    except (OSError, ValueError, KeyError, pd.errors.ParserError) as err:
        print(f"{PROG}: could not publish {run_dir('', *member)}: {err}", file=sys.stderr)
        return False


# --- question 3: the mating network and the parents, from events.csv ---------------------------
def _config_value(config: Mapping[str, Any], section: str, key: str, default: Any = None) -> Any:
    part = config.get(section, {})
    return part.get(key, default) if isinstance(part, Mapping) else default


def life_span(events: pd.DataFrame) -> int:
    """The ``L`` of :func:`life_ids`: more than any slot's births in ``events``."""
    return len(events) + 1


def life_ids(events: pd.DataFrame, agents_per_robot: int) -> np.ndarray:
    """Each event's agent as one integer per life: ``(robot x k + slot) x L + life``, where
    ``life`` counts the births in that robot's slot up to and including the row (the log
    writes a step's world events before its births, so a mating on the step an agent's
    successor is born is the predecessor's), and ``L`` is :func:`life_span`.
    """
    slot_key = events["robot"].to_numpy(np.int64) * agents_per_robot + events["slot"].to_numpy(
        np.int64
    )
    born = (events["kind"].astype(str) == "birth").to_numpy(np.int64)
    life = pd.Series(born).groupby(slot_key).cumsum().to_numpy(np.int64)
    ids: np.ndarray = slot_key * life_span(events) + life
    return ids


def replay_ages(events: pd.DataFrame, config: Mapping[str, Any]) -> np.ndarray:
    """EE only: the age (steps lived, after the row's step) of the agent behind each dock,
    mating and death row, by replaying the time sharing from the log (-1 on other rows).

    A robot runs its slots in round robin; a slot ends after ``time_sharing_steps`` steps of
    it, at a mating, a death, or at ``lifetime_steps`` (docs/design.md §5). The log shows every
    end but the time shares, which follow from the counts, so the ages follow too. The replay
    checks itself against the log: the active slot of every world event, a death's logged age,
    and a full lifetime at every birth that follows no death.

    Raises:
        ValueError: the log and the replay disagree (the rules changed, or the log is not of
            one EE run from its start).
    """
    evo = config["evolution"]
    k = int(evo["population_size"]) // int(evo["n_robots"])
    lifetime, share = int(evo["lifetime_steps"]), int(evo["time_sharing_steps"])
    kinds = events["kind"].astype(str).to_numpy()
    steps = events["step"].to_numpy(np.int64)
    robots = events["robot"].to_numpy(np.int64)
    slots = events["slot"].to_numpy(np.int64)
    values = events["value"].to_numpy(np.int64)
    ages = np.full(len(events), -1, dtype=np.int64)
    order = np.argsort(robots, kind="stable")
    bounds = np.flatnonzero(np.diff(robots[order])) + 1
    for rows in np.split(order, bounds) if len(order) else []:
        age = [0] * k
        active, in_slot, done = 0, 0, 0  # active slot, its steps in this slot, steps replayed
        i = 0
        while i < len(rows):
            step = int(steps[rows[i]])
            # the steps before ``step`` have no event of this robot: time shares only
            gap = step - 1 - done
            while gap > 0:
                d = min(gap, share - in_slot)
                age[active] += d
                in_slot += d
                gap -= d
                if age[active] >= lifetime:
                    raise ValueError(f"events do not replay: a life ended unlogged by step {step}")
                if in_slot >= share:
                    active, in_slot = (active + 1) % k, 0
            age[active] += 1
            in_slot += 1
            done = step
            ends, died = False, False
            j = i
            while j < len(rows) and steps[rows[j]] == step:
                row = rows[j]
                kind = kinds[row]
                if kind in ("dock", "mate", "death"):
                    if slots[row] != active:
                        raise ValueError(
                            f"events do not replay: robot {robots[row]} step {step} logs slot "
                            f"{slots[row]}, the replay has {active}"
                        )
                    ages[row] = age[active]
                    if kind == "mate":
                        ends = True
                    elif kind == "death":
                        ends = died = True
                        if values[row] != age[active]:
                            raise ValueError(
                                f"events do not replay: a death at age {values[row]}, the "
                                f"replay has {age[active]}"
                            )
                j += 1
            ends = ends or in_slot >= share or age[active] >= lifetime
            for row in rows[i:j]:
                if kinds[row] != "birth":
                    continue
                if slots[row] != active or not (died or age[active] >= lifetime):
                    raise ValueError(
                        f"events do not replay: a birth in robot {robots[row]} slot "
                        f"{slots[row]} at step {step} follows neither a death nor a full life"
                    )
                age[active] = 0
            if ends:
                active, in_slot = (active + 1) % k, 0
            i = j
    return ages


def ee_close_quorum(config: Mapping[str, Any]) -> int:
    """EE: the slots that must have passed a generation for its statistics row to close
    (``EvolutionConfig.ee_close_quorum`` of all slots, as the scheduler counts them)."""
    evo = config["evolution"]
    share = evo.get("ee_close_quorum", EvolutionConfig().ee_close_quorum)
    n_slots = int(evo["population_size"]) // int(evo["n_robots"]) * int(evo["n_robots"])
    return max(1, math.ceil(float(share) * n_slots - 1e-9))


def ee_closing_robots(
    lives: pd.DataFrame, span: int, agents_per_robot: int, quorum: int,
    closed_at: Mapping[int, int],
) -> dict[int, int]:  # fmt: skip
    """EE: generation -> the robot whose full life closed its statistics row, at the step
    ``closed_at`` names (docs/design.md §9.17).

    A slot passes generation g when a full life ends in it, its successor born into g + 1; the
    row of g closes at the ``quorum``-th such birth, in the order the scheduler ends slots: by
    step, then robot. ``lives`` is indexed by :func:`life_ids` (``span``: :func:`life_span`),
    with every life's ``generation``, ``born`` step and whether it ``died``.

    Raises:
        ValueError: a row closed at another step than the quorum-th such birth.
    """
    ids = lives.index.to_numpy()
    births = ids[ids % span != 0]
    died = lives["died"].reindex(births - 1).to_numpy(dtype=bool)
    passed = births[~died]  # born of a full life
    order = pd.DataFrame({"generation": lives["generation"].reindex(passed).to_numpy(np.int64),
                          "step": lives["born"].reindex(passed).to_numpy(np.int64),
                          "robot": passed // (span * agents_per_robot)})  # fmt: skip
    order = order.sort_values(["step", "robot"], kind="stable")
    closers: dict[int, int] = {}
    for generation, step in closed_at.items():
        past = order[order["generation"] == int(generation) + 1]
        if len(past) < quorum or int(past["step"].iloc[quorum - 1]) != int(step):
            at = f"step {int(past['step'].iloc[quorum - 1])}" if len(past) >= quorum else "no step"
            raise ValueError(
                f"events do not replay: generation {generation}'s row closed at step {step}, "
                f"{quorum} slots passed it at {at}"
            )
        closers[int(generation)] = int(past["robot"].iloc[quorum - 1])
    return closers


def mating_table(
    events: pd.DataFrame,
    config: Mapping[str, Any],
    closed_at: Mapping[int, int] | None = None,
) -> pd.DataFrame:
    """Per generation: the lives, their matings, distinct partners, and the parents of the
    offspring they left, from a run's event log.

    A life is one agent in one slot from its birth (or the run's start) to its death or its
    successor's birth (:func:`life_ids`); its generation is its slot's generation at birth. Its
    partners are the agents active on the partner robot at each mating (the partner's row of
    the same step). A life counts in its generation's row once it ended, and, with
    ``closed_at`` (generation -> the world step its statistics row closed, ``closed_at_step``),
    only if it ended by then and the row closed: the lives the statistics row counts (an EE row
    closes when 90 % of the slots passed it, docs/design.md §9.17, in the middle of its step: a
    life ending at that step on a robot after the closing one is late,
    :func:`ee_closing_robots`). Columns, per generation g:

    - ``lives`` (that count), ``deaths``, ``full_lives``, ``mated`` (lives with a mating),
      ``matings`` (one per side), ``completed`` (full lives with a mating: the statistics'
      ``completed``), ``positive_fitness`` (completed with a battery: what a CE tournament can
      prefer to a random pick);
    - ``partners_per_life`` (distinct partner agents, mean over the lives),
      ``partners_per_mated_life``, ``matings_per_mated_life``,
      ``partner_robots_per_mated_life`` (distinct partner robots) and ``repeat_share`` (the
      share of matings with an agent the life had already mated with);
    - ``offspring``: EE, the offspring of g's completed lives (born into g + 1, the statistics'
      ``reproductions``); CE, the selected population of g + 1;
    - EE only (NaN in CE, whose tournament winners the log does not record): ``parents``, the
      distinct agents behind those offspring, each offspring's predecessor in its slot and that
      agent's fittest partner (the highest fitness at the mating, the earliest on a tie; ages
      replayed by :func:`replay_ages`), the latter of any generation; and
      ``parents_effective``, their inverse Simpson number ``(sum c)^2 / sum c^2`` over each
      parent's number ``c`` of offspring (``2 x offspring`` when no agent is a parent twice).
      Spare-list genomes (the unused children) are left out: which one a slot draws is not
      logged.

    Raises:
        ValueError: a log this cannot read (another capture rule, matings without a partner's
            row, or an EE log the time sharing does not replay).
    """
    evo = config["evolution"]
    method = str(config.get("method", "ee"))
    n_robots = int(evo["n_robots"])
    k = int(evo["population_size"]) // n_robots
    if _config_value(config, "survival", "capture_rule", "docking") != "docking":
        raise ValueError("the mating table counts dockings as captures: capture_rule 'docking'")
    events = events.reset_index(drop=True)
    kinds = events["kind"].astype(str).to_numpy()
    life = life_ids(events, k)
    frame = events.assign(life=life)

    # every life: its generation (at birth; 0 for the initial agents), and how and when it ended
    births = frame[kinds == "birth"]
    span = life_span(events)
    initial = pd.DataFrame({"life": np.arange(n_robots * k, dtype=np.int64) * span,
                            "generation": 0, "origin": -1, "born": 0})  # fmt: skip
    born = pd.DataFrame({"life": births["life"].to_numpy(np.int64),
                         "generation": births["generation"].to_numpy(np.int64),
                         "origin": births["value"].to_numpy(np.int64),
                         "born": births["step"].to_numpy(np.int64)})  # fmt: skip
    lives = pd.concat([initial, born], ignore_index=True).set_index("life")
    if not lives.index.is_unique:
        raise ValueError("two births of one life in the event log")
    ids = lives.index.to_numpy()
    death_step = frame.loc[kinds == "death"].groupby("life")["step"].first()
    lives["died"] = lives.index.isin(death_step.index)
    successor_born = lives["born"].reindex(ids + 1).to_numpy(dtype=float)  # NaN: none yet
    lives["end"] = np.where(lives["died"], death_step.reindex(ids).to_numpy(dtype=float),
                            successor_born)  # fmt: skip
    counted = ~np.isnan(lives["end"].to_numpy())
    if closed_at is not None:
        end = lives["end"].to_numpy()
        close = lives["generation"].map(lambda g: closed_at.get(int(g), -1)).to_numpy(float)
        counted &= end <= close
        if method == "ee":
            # The robots end their slots in index order within a step, and a row closes at the
            # full life that brings the quorum of slots past it: a life of its generation that
            # ends at that step on a later robot is late, outside the row.
            closers = ee_closing_robots(lives, span, k, ee_close_quorum(config), closed_at)
            closer = lives["generation"].map(lambda g: closers.get(int(g), -1)).to_numpy()
            robot = lives.index.to_numpy() // (span * k)
            counted &= ~((end == close) & (robot > closer))
    origin_of = lives["origin"]  # of every life, counted or not (a CE successor)
    lives = lives[counted].copy()
    lives["full"] = ~lives["died"]
    docks = frame.loc[kinds == "dock"].groupby("life").size()
    lives["batteries"] = docks.reindex(lives.index, fill_value=0)

    # matings, each with the partner's row of the same step
    mate = frame.loc[kinds == "mate", ["step", "robot", "value", "life"]]
    partner = mate.rename(columns={"robot": "value", "value": "robot", "life": "partner"})
    pairs = mate.merge(partner[["step", "robot", "value", "partner"]], on=["step", "robot",
                       "value"], how="left", validate="one_to_one")  # fmt: skip
    if pairs["partner"].isna().any():
        raise ValueError("a mating without its partner's row in the event log")
    pairs["partner"] = pairs["partner"].astype(np.int64)
    per_life = pairs.groupby("life").agg(
        matings=("partner", "size"), partners=("partner", "nunique"),
        partner_robots=("value", "nunique"),
    )  # fmt: skip
    lives = lives.join(per_life)
    for column in ("matings", "partners", "partner_robots"):
        lives[column] = lives[column].fillna(0).astype(np.int64)
    lives["completed"] = lives["full"] & (lives["matings"] > 0)
    lives["positive_fitness"] = lives["completed"] & (lives["batteries"] > 0)

    # the parents of each generation's offspring (EE): a completed life and its fittest partner
    parents: dict[int, list[int]] = {}
    traced = method == "ee" and not _config_value(evo, "reproduction", "energy_dependent", False)
    if traced:
        frame["age"] = replay_ages(events, config)
        frame["batteries"] = (
            pd.Series((kinds == "dock").astype(np.int64)).groupby(life).cumsum().to_numpy()
        )
        at_mating = frame.loc[kinds == "mate", ["step", "robot", "age", "batteries"]]
        unit = float(evo["fitness_time_unit"])
        fitness = at_mating.assign(fitness=at_mating["batteries"] / (at_mating["age"] / unit))
        # the fitness a side stores is its partner's at the mating: the partner's row
        own = pairs.merge(
            fitness[["step", "robot", "fitness"]].rename(columns={"robot": "value"}),
            on=["step", "value"], how="left", validate="one_to_one",
        )  # fmt: skip
        own["order"] = np.arange(len(own))
        best = own.sort_values(["life", "fitness", "order"], ascending=[True, False, True])
        fittest = best.drop_duplicates("life").set_index("life")["partner"]
        for mother in lives.index[lives["completed"].to_numpy()]:
            parents.setdefault(int(lives.at[mother, "generation"]), []).extend(
                [int(mother), int(fittest[mother])]
            )

    rows = []
    generations = sorted(set(lives["generation"]) | set((closed_at or {}).keys()))
    for g in generations:
        group = lives[lives["generation"] == g]
        mated = group[group["matings"] > 0]
        row: dict[str, Any] = {
            "generation": int(g),
            "lives": len(group),
            "deaths": int(group["died"].sum()),
            "full_lives": int(group["full"].sum()),
            "mated": len(mated),
            "matings": int(group["matings"].sum()),
            "completed": int(group["completed"].sum()),
            "positive_fitness": int(group["positive_fitness"].sum()),
            "partners_per_life": _mean(group["partners"]),
            "partners_per_mated_life": _mean(mated["partners"]),
            "matings_per_mated_life": _mean(mated["matings"]),
            "partner_robots_per_mated_life": _mean(mated["partner_robots"]),
            "repeat_share": (1.0 - mated["partners"].sum() / mated["matings"].sum())
            if len(mated) else math.nan,
        }  # fmt: skip
        if traced:
            contributions = pd.Series(parents.get(g, []), dtype=np.int64).value_counts()
            row["offspring"] = int(group["completed"].sum())
            row["parents"] = len(contributions)
            row["parents_effective"] = (
                float(contributions.sum() ** 2 / (contributions**2).sum())
                if len(contributions) else math.nan
            )  # fmt: skip
        else:
            successors = origin_of.reindex(group.index.to_numpy() + 1)
            row["offspring"] = (
                int((successors == int(Origin.SELECTED)).sum()) if method == "ce" else math.nan
            )
            row["parents"] = math.nan
            row["parents_effective"] = math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def _mean(values: pd.Series) -> float:
    return float(values.mean()) if len(values) else math.nan


# --- analysis of the published tables -----------------------------------------------------------
#: Per-run quantities: (name, source table, column) averaged over the window.
WINDOW_QUANTITIES = (
    ("batteries", "statistics", "batteries_mean"),
    ("matings", "statistics", "matings_mean"),
    ("completed", "statistics", "completed"),
    ("full_lifetimes", "statistics", "full_lifetimes"),
    ("deaths", "statistics", "deaths"),
    ("random_share", "statistics", "random_share"),
    ("partners_per_mated_life", "matings", "partners_per_mated_life"),
    ("matings_per_mated_life", "matings", "matings_per_mated_life"),
    ("partner_robots_per_mated_life", "matings", "partner_robots_per_mated_life"),
    ("repeat_share", "matings", "repeat_share"),
    ("eligible", "matings", "eligible"),
    ("parents", "matings", "parents"),
    ("parents_effective", "matings", "parents_effective"),
)
#: The per-run quantities of the summary and the tests, in the order they are reported.
QUANTITIES = tuple(name for name, _, _ in WINDOW_QUANTITIES) + (
    "first_level", "final_level", "reach_generation", "reach_robot_hours", "paper_level",
    "reached_paper", "reach_paper_generation", "reach_paper_robot_hours",
    "robot_hours_per_generation",
)  # fmt: skip


class PublishedRun:
    """One published run: its identity and its tables."""

    def __init__(self, path: Path) -> None:
        self.path = path
        record = json.loads((path / "run.json").read_text())
        config = record["config"]
        self.method = str(config["method"])
        self.seed = int(record["seed"])
        self.n_robots = int(config["evolution"]["n_robots"])
        self.agents_per_robot = int(config["evolution"]["population_size"]) // self.n_robots
        self.control_dt = float(config["survival"]["control_dt"])
        self.cell = path.parent.name
        self.statistics = pd.read_csv(path / "statistics.csv")
        matings = path / MATINGS_FILE
        self.matings = pd.read_csv(matings) if matings.exists() else None


def load_published(published: Path) -> list[PublishedRun]:
    """Every published run under ``published`` (``<cell>/<method>-seed<NNN>/``)."""
    if not published.is_dir():
        return []
    found = [
        PublishedRun(run)
        for run in sorted(published.glob("*/*-seed*"))
        if (run / "run.json").is_file() and (run / "statistics.csv").is_file()
    ]
    return sorted(found, key=lambda r: (r.n_robots, r.method != "ee", r.seed))


def window_mean(table: pd.DataFrame | None, column: str, window: tuple[int, int]) -> float:
    """The mean of ``column`` over the window's generations (NaN skipped; NaN without any)."""
    if table is None or column not in table:
        return math.nan
    rows = table["generation"].between(*window)
    values = table.loc[rows, column].to_numpy(dtype=float)
    values = values[~np.isnan(values)]
    return float(values.mean()) if len(values) else math.nan


def reach_generation(
    table: pd.DataFrame,
    final_level: float,
    share: float = REACH_SHARE,
    smoothing: int = REACH_SMOOTHING,
    column: str = "batteries_mean",
) -> int | None:
    """The first generation at which ``column``'s trailing mean over ``smoothing`` generations
    (``g - smoothing + 1 .. g``, those present, NaN skipped) reaches ``share x final_level``;
    None if it never does (or the level is NaN)."""
    if math.isnan(final_level):
        return None
    curve = table.sort_values("generation").set_index("generation")[column].astype(float)
    smoothed = curve.rolling(smoothing, min_periods=1).mean()
    reached = smoothed.index[smoothed.to_numpy() >= share * final_level]
    return int(reached[0]) if len(reached) else None


def robot_hours(run: PublishedRun, generation: int) -> float:
    """Simulated robot-hours until ``generation`` closed: its closing world step x robots x the
    control period."""
    table = run.statistics.set_index("generation")
    step = float(table.at[generation, "closed_at_step"])
    return step * run.n_robots * run.control_dt / 3600.0


def per_run_table(runs: Sequence[PublishedRun], window: tuple[int, int]) -> pd.DataFrame:
    """One row per run: its cell, its means over ``window``, and question 2's numbers."""
    rows = []
    for run in runs:
        row: dict[str, Any] = {
            "cell": run.cell, "n_robots": run.n_robots, "agents_per_robot": run.agents_per_robot,
            "method": run.method, "seed": run.seed, "window": f"{window[0]}-{window[1]}",
            "generations": int(run.statistics["generation"].max()) + 1,
        }  # fmt: skip
        for name, source, column in WINDOW_QUANTITIES:
            table = run.statistics if source == "statistics" else run.matings
            row[name] = window_mean(table, column, window)
        row["first_level"] = window_mean(run.statistics, "batteries_mean", FIRST_WINDOW)
        first, last = window
        stats = run.statistics.set_index("generation")
        before = float(stats.at[first - 1, "closed_at_step"]) if first > 0 else 0.0
        steps = (float(stats.at[last, "closed_at_step"]) - before) / (last - first + 1)
        row["robot_hours_per_generation"] = steps * run.n_robots * run.control_dt / 3600.0
        rows.append(row)
    table = pd.DataFrame(rows)
    if not len(table):
        return table
    # question 2: the cell's final level (the mean over its runs), and the paper colony's (the
    # smallest colony's, same method)
    levels = table.groupby(["n_robots", "method"])["batteries"].mean()
    for i, run in enumerate(runs):
        level = float(levels[(run.n_robots, run.method)])
        paper = levels.get((PAPER_ROBOTS, run.method), math.nan)
        table.loc[i, "final_level"] = level
        table.loc[i, "paper_level"] = paper
        for prefix, target in (("reach", level), ("reach_paper", float(paper))):
            reached = reach_generation(run.statistics, target)
            table.loc[i, f"{prefix}_generation"] = math.nan if reached is None else reached
            table.loc[i, f"{prefix}_robot_hours"] = (
                math.nan if reached is None else robot_hours(run, reached)
            )
        reached_paper = not math.isnan(table.loc[i, "reach_paper_generation"])
        table.loc[i, "reached_paper"] = float(reached_paper)
    return table


def summary_table(per_run: pd.DataFrame) -> pd.DataFrame:
    """Per cell and method: runs, and the mean and std (ddof 1) over runs of every quantity."""
    rows = []
    for (n, method), group in per_run.groupby(["n_robots", "method"], sort=False):
        row: dict[str, Any] = {"cell": group["cell"].iloc[0], "n_robots": int(n),
                               "agents_per_robot": int(group["agents_per_robot"].iloc[0]),
                               "method": method, "runs": len(group),
                               "seeds": ",".join(str(s) for s in group["seed"])}  # fmt: skip
        for quantity in QUANTITIES:
            values = group[quantity].to_numpy(dtype=float)
            values = values[~np.isnan(values)]
            row[quantity] = float(values.mean()) if len(values) else math.nan
            row[f"{quantity}_std"] = float(values.std(ddof=1)) if len(values) > 1 else math.nan
            if len(values) != len(group):
                row[f"{quantity}_runs"] = len(values)
        rows.append(row)
    return pd.DataFrame(rows)


#: The tests of tests.csv: (question, quantity, group a, group b), a group being a method and
#: ``"small"`` or ``"large"``: the fewest and the most robots CE ran at (N = 4 and N = 100), or
#: EE where CE ran at none.
#: Question 2's times to the paper colony's level: a run that never reached it is censored at
#: the study's end, and ranks above every run that did (infinite in the rank tests).
CENSORED = ("reach_paper_generation", "reach_paper_robot_hours")
TESTS = (
    *((1, q, (m, "small"), (m, "large")) for m in ("ee", "ce") for q in ("batteries", "matings")),
    *((2, q, ("ee", "small"), ("ee", "large")) for q in ("reach_generation",
                                                         "reach_robot_hours")),
    *((2, q, (m, "small"), (m, "large")) for m in ("ee", "ce") for q in CENSORED),
    *((3, q, ("ee", "small"), ("ee", "large")) for q in ("partners_per_mated_life", "parents",
                                                         "parents_effective")),
    (3, "partners_per_mated_life", ("ce", "small"), ("ce", "large")),
    *((4, q, ("ee", "large"), ("ce", "large")) for q in ("batteries", "matings", "completed")),
    *((5, q, (m, "small"), (m, "large")) for m in ("ee", "ce") for q in ("deaths", "completed")),
)  # fmt: skip
#: EE quantities whose trend over every N tests.csv gives (Spearman's rank correlation).
TREND_QUESTIONS = {"batteries": 1, "matings": 1, "reach_generation": 2, "reach_robot_hours": 2,
                   "reach_paper_generation": 2, "reach_paper_robot_hours": 2,
                   "partners_per_mated_life": 3, "parents_effective": 3, "completed": 5,
                   "deaths": 5}  # fmt: skip
TRENDS = tuple(TREND_QUESTIONS)


def trend_test(x: np.ndarray, y: np.ndarray) -> tuple[float, float, str]:
    """Spearman's rank correlation of ``y`` with ``x`` (ties at their mean rank) and its
    two-sided permutation p-value: twice the smaller share of pairings of ``y`` with ``x`` whose
    rho is at least, or at most, the observed one (at most 1).

    Every ordering is tried when there are at most :data:`TREND_RESAMPLES` of them (7 runs
    or fewer; ``"exact"``), else that many drawn with :data:`TREND_SEED` (``"permutation"``,
    whose smallest p-value is about ``2 / TREND_RESAMPLES``, 1e-4).
    The t approximation scipy's ``spearmanr`` reports is not used: with 3 runs it gives p = 0
    for a perfect order, which is 1 in 3 orderings. Returns ``(nan, nan, "none")`` when either
    side is constant or there are fewer than 3 runs.
    """
    from scipy.stats import permutation_test, rankdata

    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if len(x) < 3 or len(np.unique(x)) < 2 or len(np.unique(y)) < 2:
        return math.nan, math.nan, "none"
    rank_x = rankdata(x)

    def rho(ranks_y: np.ndarray, axis: int = -1) -> np.ndarray:
        centred_x = rank_x - rank_x.mean()
        centred_y = ranks_y - ranks_y.mean(axis=axis, keepdims=True)
        numerator = np.sum(centred_x * centred_y, axis=axis)
        denominator = np.sqrt(np.sum(centred_x**2) * np.sum(centred_y**2, axis=axis))
        return np.asarray(numerator / denominator)

    exact = math.factorial(len(x)) <= TREND_RESAMPLES
    result = permutation_test(
        (rankdata(y),), rho, permutation_type="pairings", vectorized=True,
        n_resamples=TREND_RESAMPLES, alternative="two-sided",
        rng=np.random.default_rng(TREND_SEED),
    )  # fmt: skip
    return float(result.statistic), float(result.pvalue), "exact" if exact else "permutation"


def _ranked(values: np.ndarray, quantity: str) -> np.ndarray:
    """A quantity's per-run values for a rank test: a censored time (NaN: never reached) as
    infinite, else the NaNs dropped."""
    if quantity in CENSORED:
        return np.where(np.isnan(values), np.inf, values)
    kept: np.ndarray = values[~np.isnan(values)]
    return kept


def _finite_mean(values: np.ndarray) -> float:
    """The mean of the finite values (a censored time is infinite); NaN without any."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if len(finite) else math.nan


def test_table(
    per_run: pd.DataFrame, compared: tuple[int, int] = (min(CE_SIZES), max(CE_SIZES))
) -> pd.DataFrame:
    """Two-sided Mann-Whitney U of each pair in :data:`TESTS` over per-run values (exact
    without ties, :func:`evolution.lab.comparison.rank_test`), and Spearman's trend over N of
    each EE quantity in :data:`TRENDS`.

    ``compared``: the small and the large colony of the tests (the study's CE sizes), whether
    or not their runs are published yet: a size with no run gives n = 0 and no p-value, never a
    test of another size."""
    rows = []
    size = {"small": int(compared[0]), "large": int(compared[1])}

    def values(method: str, n: int, quantity: str) -> np.ndarray:
        chosen = per_run[(per_run["method"] == method) & (per_run["n_robots"] == n)]
        array = chosen[quantity].to_numpy(dtype=float) if len(chosen) else np.zeros(0)
        return _ranked(array, quantity)

    for question, quantity, (method_a, which_a), (method_b, which_b) in TESTS:
        n_a, n_b = size[which_a], size[which_b]
        a, b = values(method_a, n_a, quantity), values(method_b, n_b, quantity)
        u, p, effect, test = rank_test(a, b)
        rows.append({
            "question": question, "quantity": quantity, "test": f"mann-whitney {test}",
            "a": f"{method_a.upper()} N={n_a}", "b": f"{method_b.upper()} N={n_b}",
            "n_a": len(a), "n_b": len(b), "mean_a": _finite_mean(a), "mean_b": _finite_mean(b),
            "never_a": int(np.isinf(a).sum()), "never_b": int(np.isinf(b).sum()),
            "statistic": u, "p_value": p, "effect": effect,
        })  # fmt: skip
    ee = per_run[per_run["method"] == "ee"]
    for quantity in TRENDS:
        y = ee[quantity].to_numpy(float)
        kept = ~np.isnan(y) if quantity not in CENSORED else np.ones(len(y), dtype=bool)
        rho, p, kind = trend_test(ee["n_robots"].to_numpy(float)[kept],
                                  _ranked(y, quantity))  # fmt: skip
        rows.append({
            "question": TREND_QUESTIONS[quantity], "quantity": quantity,
            "test": f"spearman over N {kind}", "a": "EE, every N", "b": "",
            "n_a": int(kept.sum()), "n_b": 0, "mean_a": math.nan, "mean_b": math.nan,
            "statistic": rho, "p_value": p, "effect": rho,
        })  # fmt: skip
    return pd.DataFrame(rows)


def plot_study(runs: Sequence[PublishedRun], path: Path) -> Path:
    """Batteries and matings per life, and the agents that completed the task, against
    generation (mean over seeds), one line per N, EE and CE side by side."""
    from evolution.lab.figures import styled_pyplot

    plt = styled_pyplot()
    sizes = sorted({r.n_robots for r in runs})
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, max(2, len(sizes))))
    quantities = ("batteries_mean", "matings_mean", "completed")
    fig, axes = plt.subplots(3, 2, figsize=(11, 10), sharex=True, sharey="row", squeeze=False)
    for column, method in enumerate(("ee", "ce")):
        for n, colour in zip(sizes, colours, strict=False):
            chosen = [r for r in runs if r.method == method and r.n_robots == n]
            if not chosen:
                continue
            for row, quantity in enumerate(quantities):
                curve = pd.concat(
                    [r.statistics.set_index("generation")[quantity] for r in chosen], axis=1
                ).mean(axis=1)
                runs_label = "1 run" if len(chosen) == 1 else f"{len(chosen)} runs"
                label = f"N = {n}, {chosen[0].agents_per_robot} per robot ({runs_label})"
                axes[row][column].plot(
                    curve.index, curve.to_numpy(), color=colour, lw=1.5, label=label
                )
        axes[0][column].set_title(f"{method.upper()}")
        axes[-1][column].set_xlabel("generation")
    population = runs[0].agents_per_robot * runs[0].n_robots
    axes[0][0].set_ylabel("batteries per life")
    axes[1][0].set_ylabel("matings per life")
    axes[2][0].set_ylabel(f"agents completing the task (of {population})")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    for ax in axes[0]:  # one legend per method: the rows share their lines
        if ax.get_legend_handles_labels()[0]:
            ax.legend(frameon=False, fontsize=8)
    fig.suptitle(f"{population} agents on N robots at the paper's density, mean over seeds; "
                 "batteries and matings over each generation's agents that completed the task",
                 fontsize=11)  # fmt: skip
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        fig.savefig(temp, bbox_inches="tight", dpi=120)
    plt.close(fig)
    return path


def fmt_mean(mean: float, std: float, digits: int = 2) -> str:
    if math.isnan(mean):
        return "–"
    return f"{mean:.{digits}f}" + ("" if math.isnan(std) else f" ± {std:.{digits}f}")


def markdown(summary: pd.DataFrame, tests: pd.DataFrame, window: tuple[int, int]) -> str:
    """The summary and the tests as Markdown tables."""
    columns = (("batteries", 1), ("matings", 2), ("completed", 1), ("deaths", 1),
               ("random_share", 2), ("reach_generation", 1), ("reached_paper", 2),
               ("reach_paper_generation", 1), ("reach_paper_robot_hours", 1),
               ("partners_per_mated_life", 2), ("parents_effective", 1))  # fmt: skip
    heads = ("batteries", "matings", "completed", "deaths", "random newborns",
             "gen. to 90 % of own cell", f"share reaching 90 % of N = {PAPER_ROBOTS}",
             "gen. to it (those reaching)", "robot-h to it", "partners / mated life",
             "eff. parents")  # fmt: skip
    lines = [f"Per-run means over generations {window[0]}-{window[1]}, mean ± std over runs:",
             "", "| N | agents/robot | method | runs | " + " | ".join(heads) + " |",
             "|" + " --- |" * (4 + len(heads))]  # fmt: skip
    for _, row in summary.iterrows():
        cells = [fmt_mean(row[c], row[f"{c}_std"], d) for c, d in columns]
        lines.append(f"| {row['n_robots']} | {row['agents_per_robot']} | "
                     f"{str(row['method']).upper()} | {row['runs']} | " + " | ".join(cells)
                     + " |")  # fmt: skip
    lines += ["", "| Q | quantity | test | a | b | n | mean a | mean b | U or ρ | p |",
              "|" + " --- |" * 10]  # fmt: skip
    for _, t in tests.iterrows():
        lines.append(
            f"| {t['question']} | {t['quantity']} | {t['test']} | {t['a']} | {t['b']} | "
            f"{t['n_a']}/{t['n_b']} | {_censored(t['mean_a'], t['never_a'])} | "
            f"{_censored(t['mean_b'], t['never_b'])} | "
            f"{_num(t['statistic'])} | {_num(t['p_value'], 2, 'g')} |"
        )
    return "\n".join(lines)


def _num(value: float, digits: int = 2, style: str = "f") -> str:
    return "–" if math.isnan(value) else f"{value:.{digits}{style}}"


def _censored(mean: float, never: float) -> str:
    """A mean over the runs that reached a level, and how many never did."""
    if math.isnan(never) or not never:
        return _num(mean)
    return f"{_num(mean)} ({int(never)} never)"


def write_csv(table: pd.DataFrame, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        table.to_csv(temp, index=False, float_format="%.6g")
    return path


def analyse(published: Path, figure: Path) -> tuple[list[Path], str]:
    """Write the analysis of the published runs; return the files and the Markdown text.

    Raises:
        StudyError: no published run.
    """
    runs = load_published(published)
    if not runs:
        raise StudyError(f"no published run in {published}")
    window = available_window([r.statistics for r in runs], FINAL_WINDOW)
    if window is None:
        raise StudyError(f"no run in {published} closed a generation")
    per_run = per_run_table(runs, window)
    summary = summary_table(per_run)
    tests = test_table(per_run)
    written = [
        write_csv(summary, published / "summary.csv"),
        write_csv(per_run, published / "runs.csv"),
        write_csv(tests, published / "tests.csv"),
        plot_study(runs, figure),
    ]
    return written, markdown(summary, tests, window)


# --- question 1's check: do the robots crowd the walls? ----------------------------------------
#: A robot or pack whose centre is closer than this to a wall (m) counts as at the wall.
WALL_BAND = 0.5
#: World control steps between two position samples.
POSITION_EVERY = 50
WALLS_FILE = "walls.csv"


def wall_share(half: float, band: float = WALL_BAND, clearance: float | None = None) -> float:
    """The share of the square a centre can reach (``half - clearance`` either side of the
    middle; default clearance: the paper's robot's) that lies within ``band`` of a wall: where
    uniformly spread robots would be."""
    if clearance is None:
        clearance = robot_model().body_radius
    reach = half - clearance
    if reach <= 0:
        return 1.0
    inner = min(max(0.0, half - band), reach)
    return 1.0 - (inner / reach) ** 2


def near_wall(xy: np.ndarray, half: float, band: float = WALL_BAND) -> np.ndarray:
    """Which of the ``(n, 2)`` centres of a field of half side ``half`` are within ``band`` of a
    wall."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    distance: np.ndarray = half - np.abs(xy).max(axis=1)
    return distance < band


def sample_walls(path: Path, every: int = POSITION_EVERY) -> dict[str, Any]:
    """Replay the last generation of the finished run in ``path`` from its checkpoint and
    sample where its robots and packs are every ``every`` world steps.

    The replay must close the generation at the step the run's ``statistics.csv`` records.

    Raises:
        StudyError: the run has no checkpoint of its last generation's start, or the replay
            closes it at another step.
    """
    from evolution.runner import EvolutionRunner

    statistics = pd.read_csv(path / "statistics.csv")
    last = int(statistics["generation"].max())
    checkpoint = path / "checkpoints" / f"gen_{last:05d}.ckpt"
    if not checkpoint.is_file():
        raise StudyError(f"{path}: no checkpoint {checkpoint.name} to replay generation {last}")
    # samples and those at the wall: robots whose active agent has a random genome, the other
    # robots, and packs
    counts = np.zeros((3, 2), dtype=np.int64)
    active = 0  # robot-samples running an agent (a CE robot whose agents all finished idles)
    random_origins = (int(Origin.INITIAL), int(Origin.RANDOM))
    with EvolutionRunner.from_checkpoint(checkpoint) as runner:
        world, scheduler = runner.world, runner.scheduler
        half = world.config.field_size / 2
        while runner.completed_generations <= last:
            runner.step()
            if runner.steps % every == 0:
                at_wall = near_wall(world.poses()[:, :2], half)
                random = np.array([
                    int(scheduler.slots[r][int(slot)].origin) in random_origins
                    for r, slot in enumerate(scheduler.active_slot)
                ])  # fmt: skip
                for row, chosen in enumerate((random, ~random)):
                    counts[row] += (int(chosen.sum()), int(at_wall[chosen].sum()))
                active += int(np.count_nonzero(scheduler.active))
                packs = near_wall(world.pack_positions(), half)
                counts[2] += (len(packs), int(packs.sum()))
        closed = runner.generation_steps[last]
    expected = int(statistics.set_index("generation").at[last, "closed_at_step"])
    if closed != expected:
        raise StudyError(f"{path}: the replay closed generation {last} at step {closed}, the run "
                         f"at {expected}")  # fmt: skip
    field = wall_share(half)
    robot_samples = int(counts[:2, 0].sum())
    robot_share = counts[:2, 1].sum() / max(1, robot_samples)

    def share(row: int) -> float:
        return float(counts[row, 1] / counts[row, 0]) if counts[row, 0] else math.nan

    return {"generation": last, "field_side": 2 * half, "robot_samples": robot_samples,
            "robots_at_wall": robot_share, "packs_at_wall": share(2), "field_at_wall": field,
            "robots_over_field": robot_share / field,
            "random_genomes": counts[0, 0] / max(1, robot_samples),
            "random_at_wall": share(0), "others_at_wall": share(1),
            "active_robots": active / max(1, robot_samples)}  # fmt: skip


def wall_table(spec: SweepSpec, out: Path, every: int = POSITION_EVERY) -> pd.DataFrame:
    """:func:`sample_walls` of every finished run of ``spec`` in ``out``, one row per run."""
    rows = []
    members = sorted(spec.runs, key=lambda m: (n_robots_of(spec, m.cell), m.method != "ee", m.seed))
    for member in members:
        path = run_dir(out, *member)
        if not run_finished(path):
            continue
        print(f"{PROG}: replaying the last generation of {run_dir('', *member)}", flush=True)
        n = n_robots_of(spec, member.cell)
        rows.append({"cell": member.cell, "n_robots": n, "method": member.method,
                     "seed": member.seed, **sample_walls(path, every)})  # fmt: skip
    return pd.DataFrame(rows)


def walls_markdown(table: pd.DataFrame) -> str:
    """Per cell and method: the runs' mean shares at the wall."""
    lines = [f"Centres within {WALL_BAND} m of a wall, sampled every {POSITION_EVERY} steps of "
             "each run's last generation (mean ± std over runs):", "",
             "| N | method | runs | robots at the wall | packs at the wall | robots running a "
             "random genome | of those, at the wall | the others at the wall | field at the "
             "wall | robots / field | robots running an agent |", "|" + " --- |" * 11]  # fmt: skip
    for (n, method), group in table.groupby(["n_robots", "method"], sort=False):
        cells = [fmt_mean(group[c].mean(), group[c].std(), 3)
                 for c in ("robots_at_wall", "packs_at_wall", "random_genomes",
                           "random_at_wall", "others_at_wall")]  # fmt: skip
        ratio, active = group["robots_over_field"], group["active_robots"]
        lines.append(f"| {n} | {str(method).upper()} | {len(group)} | {' | '.join(cells)} | "
                     f"{group['field_at_wall'].iloc[0]:.3f} | "
                     f"{fmt_mean(ratio.mean(), ratio.std(), 2)} | "
                     f"{fmt_mean(active.mean(), active.std(), 3)} |")  # fmt: skip
    return "\n".join(lines)


# --- the cost estimate ---------------------------------------------------------------------------
def measure_step_costs(
    spec: SweepSpec, cells: Iterable[str], robot_steps: int = ESTIMATE_ROBOT_STEPS
) -> dict[str, dict[str, float]]:
    """Per cell: seconds to build its runner, and seconds per world control step, timed over
    ``robot_steps`` robot-steps after one warm-up generation of a short life (40 steps in slots
    of 10, so that it closes quickly; the robots have docked, mated and died by then)."""
    from evolution.lab.api import make_config
    from evolution.runner import EvolutionRunner, default_policies

    policies = default_policies()
    costs: dict[str, dict[str, float]] = {}
    for cell in cells:
        settings = {**spec.settings_of(cell), "evolution.lifetime_steps": 40,
                    "evolution.time_sharing_steps": 10}  # fmt: skip
        config = make_config("ee", **settings)
        start = time.perf_counter()
        runner = EvolutionRunner(config, 0, policies)
        built = time.perf_counter() - start
        with runner:
            runner.run(1)
            n = config.evolution.n_robots
            steps = max(20, math.ceil(robot_steps / n))
            start = time.perf_counter()
            for _ in range(steps):
                runner.step()
            step_seconds = (time.perf_counter() - start) / steps
        costs[cell] = {"build_s": built, "step_s": step_seconds,
                       "robot_step_us": 1e6 * step_seconds / n}  # fmt: skip
    return costs


def projected_hours(
    spec: SweepSpec, members: Sequence[SweepRun], costs: Mapping[str, Mapping[str, float]]
) -> dict[SweepRun, float]:
    """Core-hours of each run: generations x agents per robot x 400 steps x the steps per life
    of its method (:data:`evolution.lab.sweep.STEPS_PER_LIFE`) x the measured step cost."""
    hours = {}
    for member in members:
        settings = spec.settings_of(member.cell)
        k = int(settings["evolution.population_size"]) // int(settings["evolution.n_robots"])
        lifetime = int(spec.overrides.get("evolution.lifetime_steps", 400))
        steps = spec.generations * k * lifetime * STEPS_PER_LIFE[member.method]
        cost = costs[member.cell]
        hours[member] = (steps * cost["step_s"] + cost["build_s"]) / 3600
    return hours


def print_estimate(spec: SweepSpec, members: Sequence[SweepRun], workers: int) -> None:
    """Time each pending cell's step and print the projected core-hours and wall-clock time."""
    cells = list(dict.fromkeys(m.cell for m in members))
    print(f"{PROG}: timing one short generation and {ESTIMATE_ROBOT_STEPS} robot-steps per cell "
          "for the cost estimate ...", flush=True)  # fmt: skip
    costs = measure_step_costs(spec, cells)
    hours = projected_hours(spec, members, costs)
    print("| cell | robots | build s | ms / step | µs / robot-step | h per EE run | h per CE run |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for cell in cells:
        per_method = {m.method: h for m, h in hours.items() if m.cell == cell}
        c = costs[cell]
        print(f"| {cell} | {n_robots_of(spec, cell)} | {c['build_s']:.1f} | "
              f"{1e3 * c['step_s']:.2f} | {c['robot_step_us']:.0f} | "
              f"{_num(per_method.get('ee', math.nan))} | "
              f"{_num(per_method.get('ce', math.nan))} |")  # fmt: skip
    total = sum(hours.values())
    longest = max(hours.values())
    wall = max(total / max(1, min(workers, len(members))), longest)
    print(f"{PROG}: {len(members)} runs to do, about {total:.1f} core-hours: about {wall:.1f} h "
          f"on {workers} workers (generation 0, with its many deaths, runs longer; the machine's "
          "load moves it too)", flush=True)  # fmt: skip


# --- the command line ----------------------------------------------------------------------------
def _parse_sizes(text: str, what: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise StudyError(f"{what} must be a comma list of robot counts, got {text!r}") from None
    if any(n < 1 for n in sizes):
        raise StudyError(f"{what} must be robot counts of at least 1, got {text!r}")
    return sizes


def build(args: argparse.Namespace) -> SweepSpec:
    """The study's sweep from the arguments, every setting checked.

    Raises:
        StudyError, ValueError: the first argument or setting refused.
    """
    from cyber_rodent.validation import check_integer
    from evolution.runner.settings import parse_set

    sizes = _parse_sizes(args.sizes, "--sizes")
    ce_sizes = _parse_sizes(args.ce_sizes, "--ce-sizes") if args.ce_sizes else ()
    check_integer("--population", args.population, 1)
    check_integer("--workers", args.workers, 1, 4096)
    spec = study_spec(
        sizes, ce_sizes, parse_seeds(args.seeds), args.generations, parse_set(args.set),
        args.population,
    )  # fmt: skip
    spec.check()
    if args.ray is not None:
        check_ray_address(args.ray)
    return spec


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--run", action="store_true", help="run or resume the study first")
    parser.add_argument("--out", type=Path, default=Path("runs/colony_scale"),
                        help="the study's run directories")  # fmt: skip
    parser.add_argument("--workers", type=int, default=2, help="runs at a time")
    parser.add_argument("--ray", metavar="ADDRESS", default=None,
                        help="run on Ray: auto, HOST:PORT or local (default: local processes)")
    parser.add_argument("--published", type=Path, default=Path("results/colony_scale"),
                        help="where finished runs' tables and the analysis go")  # fmt: skip
    parser.add_argument("--figure", type=Path, default=Path("docs/images/colony_scale.png"))
    parser.add_argument("--sizes", default=",".join(map(str, SIZES)), help="robot counts")
    parser.add_argument("--ce-sizes", default=",".join(map(str, CE_SIZES)),
                        help="robot counts CE runs at too ('' for none)")  # fmt: skip
    parser.add_argument("--population", type=int, default=POPULATION)
    parser.add_argument("--seeds", default=SEEDS)
    parser.add_argument("--generations", type=int, default=GENERATIONS)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="change a setting of every run (not a cell's own keys)")
    parser.add_argument("--walls", action="store_true",
                        help="replay each finished run's last generation in --out from its "
                        f"checkpoint, and write where its robots are ({WALLS_FILE})")
    parser.add_argument("--no-estimate", action="store_true",
                        help="start without timing the cost estimate first")  # fmt: skip
    args = parser.parse_args(argv)
    try:
        spec = build(args)
        record = study_record(spec, args.population)
        if args.run:
            check_study_dir(args.out, record)
    except ValueError as err:  # StudyError too: one line, status 2, before anything starts
        print(f"{PROG}: error: {str(err).splitlines()[0]}", file=sys.stderr)
        return 2
    failed = False
    if args.run:
        args.out.mkdir(parents=True, exist_ok=True)
        write_text(args.out / STUDY_FILE, json.dumps(record, indent=2, sort_keys=True) + "\n")
        for member in publish_finished(args.out, args.published, spec):
            print(f"published {run_dir('', *member)}")
        todo = pending_runs(spec, args.out)
        print(f"{PROG}: {len(spec.runs)} runs, {len(spec.runs) - len(todo)} finished, "
              f"{len(todo)} to run", flush=True)  # fmt: skip
        if todo:
            if not args.no_estimate:
                print_estimate(spec, todo, args.workers)

            def publish_one(member: SweepRun) -> None:
                if publish_quietly(args.out, args.published, member):
                    print(f"published {run_dir('', *member)}", flush=True)

            pending = dataclasses.replace(spec, members=tuple(todo))
            try:
                executor = "ray" if args.ray is not None else "local"
                sweep(
                    pending, RunOutput(args.out, progress=True),
                    Execution(executor, args.workers, args.ray or "local"),
                    on_run_done=publish_one,
                )  # fmt: skip
            except KeyboardInterrupt:
                print(f"{PROG}: interrupted; the same command continues the study",
                      file=sys.stderr)  # fmt: skip
                return 130
            except SweepFailed as err:  # the other runs finished: publish and analyse them
                print(f"{PROG}: {err}", file=sys.stderr)
                failed = True
    for member in publish_finished(args.out, args.published, spec):
        print(f"published {run_dir('', *member)}")
    try:
        written, text = analyse(args.published, args.figure)
    except StudyError as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 1
    for path in written:
        print(f"wrote {path}")
    print(text)
    if args.walls:
        try:
            walls = wall_table(spec, args.out)
        except StudyError as err:
            print(f"{PROG}: {err}", file=sys.stderr)
            return 1
        print(f"wrote {write_csv(walls, args.published / WALLS_FILE)}")
        print(walls_markdown(walls))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
