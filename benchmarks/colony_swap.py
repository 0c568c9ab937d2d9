"""The colony study's swap: do larger colonies evolve worse genomes, or live in a harder world?

The colony study (:mod:`benchmarks.colony_study`) finds that 100 agents on many robots capture
fewer batteries per life after 60 generations than on the paper's 4. That can have two causes:
the larger colony evolved worse controllers, or its world lets the same controllers capture
fewer. This check separates them. For each seed and method run at both sizes (EE and CE, N = 4
and N = 100), it takes the population each run ended with (the 100 genomes at its last
checkpoint) and lets it live one generation in each of the two worlds:

==============================  ==================  ====================
genomes                         world N = 4         world N = 100
==============================  ==================  ====================
evolved on 4 robots             at home             away
evolved on 100 robots           away                at home
==============================  ==================  ====================

The smaller size's EE population also lives a generation in the worlds of the study's other
sizes (10, 25 and 50 robots, time-sharing 10, 4 and 2 agents each in larger fields): what it
loses there, a larger world costs it even where robots still time-share.

Each evaluation is a fresh run of the world's cell (its ``run.json``: the study's settings for
that N) with the run's seed and the chosen genomes as its initial population, robot-major, for
one generation of the run's own method: the world is laid out as in that seed's run, every
agent starts a new life, and the generation's statistics (batteries and matings per life of
the agents that completed the task, completions, deaths) are the genomes' score there. Both
populations of a seed meet the same world, so each comparison is paired by seed. Beside them
``swap.csv`` repeats generation 0 of the study runs themselves, random genomes in the same
worlds.

    .venv/bin/python -m benchmarks.colony_swap --out runs/colony_scale [--workers 2]

It needs the study's run directories (``--out``, for the checkpoints) and its published tables
(``--published``, for the settings), takes about a twentieth of the study's time, and writes
``swap.csv`` and ``swap_tests.csv`` into ``--published``. Each evaluation's row is kept in
``--out/swap/`` as it finishes, so the same command resumes a swap cut short. Every setting
is checked before anything runs: a bad one exits with status 2 and one line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from benchmarks import colony_study  # noqa: E402
from benchmarks.colony_study import (  # noqa: E402
    SEEDS,
    StudyError,
    cell_name,
    fmt_mean,
    run_finished,
    write_csv,
)
from cyber_rodent.atomic import write_text  # noqa: E402
from evolution.lab.comparison import rank_test  # noqa: E402
from evolution.lab.experiment import policies_for_identity, read_run_record  # noqa: E402
from evolution.lab.sweep import parse_seeds, run_dir  # noqa: E402
from evolution.runner.checkpoints import (  # noqa: E402
    genomes_identity,
    latest_checkpoint,
    policy_identity,
    run_fingerprint,
)
from evolution.runner.config import run_config_from_record  # noqa: E402

PROG = "colony_swap"
#: The two sizes whose populations trade worlds: the paper's colony and one robot per agent.
SIZES = (4, 100)
#: The study's other sizes: the smaller size's EE population also lives in their worlds.
BETWEEN = tuple(n for n in colony_study.SIZES if n not in SIZES)
METHODS = ("ee", "ce")
SWAP_FILE = "swap.csv"
#: Where each evaluation's row is kept, under ``--out``.
CACHE = "swap"
#: Generation 0's columns each evaluation reports (``statistics.csv`` names).
COLUMNS = ("completed", "batteries_mean", "matings_mean", "deaths", "new_random",
           "batteries_full_life_mean", "closed_at_step")  # fmt: skip


@dataclass(frozen=True)
class Evaluation:
    """One population living one generation in one world.

    Attributes:
        method: the study's method (the runs' and the evaluation's).
        seed: the runs' seed, and the evaluation's.
        genomes: the directory of the run whose final population lives here.
        world: the published directory of the run whose settings (its cell) make the world.
        cache: where its row is kept once measured (None: nowhere).
    """

    method: str
    seed: int
    genomes: Path
    world: Path
    cache: Path | None = None

    @property
    def name(self) -> str:
        """``ee-seed003-n004-in-n100``."""
        return (f"{self.method}-seed{self.seed:03d}-{self.genomes.parent.name}-in-"
                f"{self.world.parent.name}")  # fmt: skip


def plan(
    out: Path,
    published: Path,
    seeds: Sequence[int],
    sizes: Sequence[int] = SIZES,
    between: Sequence[int] = (),
    cache: Path | None = None,
) -> list[Evaluation]:
    """Every evaluation: per method and seed, each of the two ``sizes``' final populations in
    each of their worlds (genomes' size-major), then, for EE, the smaller size's population in
    the world of each of ``between`` (the study's other sizes, run with EE only).

    Raises:
        StudyError: a run the swap needs has not finished in ``out``, or is not published.
    """

    def finished_run(method: str, seed: int, n: int) -> Path:
        path = run_dir(out, method, seed, cell_name(n))
        if not run_finished(path):
            raise StudyError(f"--out: {path} has not finished; run the study first")
        return path

    def world(method: str, seed: int, n: int) -> Path:
        path = run_dir(published, method, seed, cell_name(n))
        if not (path / "run.json").is_file():
            raise StudyError(f"--published: no {path / 'run.json'}")
        return path

    evaluations = []
    for method in METHODS:
        for seed in seeds:
            runs = {n: finished_run(method, seed, n) for n in sizes}
            evaluations += [Evaluation(method, seed, runs[g], world(method, seed, w), cache)
                            for g in sizes for w in sizes]  # fmt: skip
            if method == "ee":
                evaluations += [Evaluation(method, seed, runs[sizes[0]], world(method, seed, n),
                                           cache) for n in between]  # fmt: skip
    return evaluations


def final_population(path: Path) -> list[Any]:
    """The genomes, robot-major, at the last checkpoint of the finished run in ``path``: the
    population the run ended with."""
    from evolution.runner import EvolutionRunner

    statistics = pd.read_csv(path / "statistics.csv")
    checkpoint = latest_checkpoint(path / "checkpoints")
    expected = f"gen_{len(statistics):05d}.ckpt"
    if checkpoint is None or checkpoint.name != expected:
        raise StudyError(f"{path}: no checkpoint {expected} of the population it ended with")
    record = read_run_record(path)
    with EvolutionRunner.from_checkpoint(
        checkpoint, policies_for_identity(record["policies"])
    ) as runner:
        return runner.scheduler.population()


def evaluate(evaluation: Evaluation, genomes: Sequence[Any]) -> dict[str, Any]:
    """Generation 0 of ``evaluation``'s world with ``genomes``, the final population of its
    genomes' run (:func:`final_population`), as one row.

    With a ``cache`` the row is kept there, under the evaluation's fingerprint (its settings,
    seed, behaviours and genomes: :func:`~evolution.runner.checkpoints.run_fingerprint`), and
    a later call with the same fingerprint reads it back instead of running again: a swap cut
    short resumes where it stopped.
    """
    from evolution.runner import EvolutionRunner

    record = read_run_record(evaluation.world)
    config = run_config_from_record(record["config"])
    if config.method != evaluation.method or len(genomes) != config.evolution.population_size:
        raise StudyError(f"{evaluation.world}: not a {evaluation.method} run of "
                         f"{len(genomes)} agents")  # fmt: skip
    policies = policies_for_identity(record["policies"])
    fingerprint = run_fingerprint(
        config, evaluation.seed, policy_identity(policies), genomes_identity(genomes)
    )
    kept = None if evaluation.cache is None else evaluation.cache / f"{evaluation.name}.json"
    if kept is not None and kept.is_file():
        stored = json.loads(kept.read_text())
        if stored.get("fingerprint") == fingerprint:
            return dict(stored["row"])
    with EvolutionRunner(config, evaluation.seed, policies, initial_genomes=genomes) as runner:
        table = runner.run(1)
        steps = runner.steps
    first = table.iloc[0]
    row = {
        "method": evaluation.method, "seed": evaluation.seed,
        "genomes": evaluation.genomes.parent.name, "world": evaluation.world.parent.name,
        **{c: np.asarray(first[c]).item() for c in COLUMNS},
        "robot_steps": steps * config.evolution.n_robots,
    }  # fmt: skip
    if kept is not None:
        kept.parent.mkdir(parents=True, exist_ok=True)
        write_text(kept, json.dumps({"fingerprint": fingerprint, "row": row}, indent=1) + "\n")
    return row


def random_rows(
    published: Path, seeds: Sequence[int], sizes: Sequence[int] = SIZES
) -> list[dict[str, Any]]:
    """Generation 0 of the study runs themselves: random genomes in the same worlds."""
    rows = []
    for method in METHODS:
        for seed in seeds:
            for n in sizes:
                path = run_dir(published, method, seed, cell_name(n))
                table = pd.read_csv(path / "statistics.csv")
                row = table.iloc[0]
                steps = int(row["closed_at_step"]) * n
                rows.append({"method": method, "seed": seed, "genomes": "random",
                             "world": cell_name(n), **{c: row[c] for c in COLUMNS},
                             "robot_steps": steps})  # fmt: skip
    return rows


def swap_table(
    evaluations: Sequence[Evaluation], workers: int, progress: bool = False
) -> pd.DataFrame:
    """:func:`evaluate` of every evaluation, in order, on ``workers`` processes (the rows do
    not depend on how many); with ``progress``, a line as each one finishes. Each run's final
    population is read once, however many worlds it lives in."""
    start = time.monotonic()
    populations = {path: final_population(path) for path in {e.genomes for e in evaluations}}
    genomes = [populations[e.genomes] for e in evaluations]

    def done(k: int, row: dict[str, Any]) -> dict[str, Any]:
        if progress:
            print(f"{PROG}: {k}/{len(evaluations)} {row['method']} seed {row['seed']}: "
                  f"{row['genomes']} genomes in the {row['world']} world, "
                  f"{time.monotonic() - start:.0f} s", flush=True)  # fmt: skip
        return row

    if workers == 1:
        rows = [done(k, evaluate(e, g))
                for k, (e, g) in enumerate(zip(evaluations, genomes, strict=True), 1)]  # fmt: skip
    else:
        with ProcessPoolExecutor(workers) as pool:
            rows = [done(k, r) for k, r in enumerate(pool.map(evaluate, evaluations, genomes), 1)]
    return pd.DataFrame(rows)


def comparisons(sizes: Sequence[int] = SIZES) -> list[tuple[str, tuple[str, str], tuple[str, str]]]:
    """The comparisons tested, per method: (name, rows a, rows b), rows as (genomes, world):
    the two populations in each world, and each population in the two worlds."""
    small, large = (cell_name(n) for n in sizes)
    ns = dict(zip((small, large), sizes, strict=True))
    return [
        *((f"genomes, in the N = {ns[w]} world", (small, w), (large, w)) for w in (large, small)),
        *((f"world, N = {ns[g]} genomes", (g, small), (g, large)) for g in (small, large)),
    ]


def _values(table: pd.DataFrame, key: tuple[str, str], column: str) -> np.ndarray:
    """The finite values of ``column`` in the rows of ``key`` = (genomes, world)."""
    chosen = table[(table["genomes"] == key[0]) & (table["world"] == key[1])]
    values = chosen[column].to_numpy(dtype=float)
    finite: np.ndarray = values[np.isfinite(values)]
    return finite


def swap_tests(table: pd.DataFrame, sizes: Sequence[int] = SIZES) -> pd.DataFrame:
    """Two-sided Mann-Whitney U of batteries, matings and completions over seeds, for each of
    :func:`comparisons` and method."""
    rows = []
    for method in METHODS:
        own = table[table["method"] == method]
        for name, a, b in comparisons(sizes):
            for column in ("batteries_mean", "matings_mean", "completed"):
                first, second = (_values(own, key, column) for key in (a, b))
                u, p, effect, test = rank_test(first, second)
                rows.append({"method": method, "comparison": name, "quantity": column,
                             "a": "/".join(a), "b": "/".join(b), "n_a": len(first),
                             "n_b": len(second), "mean_a": first.mean() if len(first) else np.nan,
                             "mean_b": second.mean() if len(second) else np.nan, "u": u,
                             "p_value": p, "effect": effect, "test": test})  # fmt: skip
    return pd.DataFrame(rows)


def swap_markdown(table: pd.DataFrame, tests: pd.DataFrame) -> str:
    """Per method, genomes and world: mean ± std over seeds, then the tests."""
    lines = ["Generation 0 of each population in each world (mean ± std over seeds):", "",
             "| method | genomes evolved on | world | seeds | batteries | matings | completed | "
             "deaths | random newborns |", "|" + " --- |" * 9]  # fmt: skip
    for (method, genomes, world), g in table.groupby(["method", "genomes", "world"], sort=False):
        cells = [fmt_mean(g[c].mean(), g[c].std(), d)
                 for c, d in (("batteries_mean", 2), ("matings_mean", 2), ("completed", 1),
                              ("deaths", 1), ("new_random", 1))]  # fmt: skip
        lines.append(f"| {str(method).upper()} | {genomes} | {world} | {len(g)} | "
                     + " | ".join(cells) + " |")  # fmt: skip
    lines += ["", "| method | comparison | quantity | a | b | mean a | mean b | U | p |",
              "|" + " --- |" * 9]  # fmt: skip
    for _, t in tests.iterrows():
        lines.append(f"| {str(t['method']).upper()} | {t['comparison']} | {t['quantity']} | "
                     f"{t['a']} | {t['b']} | {t['mean_a']:.2f} | {t['mean_b']:.2f} | "
                     f"{t['u']:.1f} | {t['p_value']:.3g} |")  # fmt: skip
    return "\n".join(lines)


def parse_sizes(text: str) -> tuple[int, int]:
    """``--sizes``: two distinct robot counts, smaller first.

    Raises:
        StudyError: not two distinct positive integers.
    """
    try:
        sizes = tuple(sorted(int(t) for t in text.split(",")))
    except ValueError:
        sizes = ()
    if len(sizes) != 2 or sizes[0] == sizes[1] or sizes[0] < 1:
        raise StudyError(f"--sizes must be two distinct robot counts >= 1, got {text!r}")
    return sizes[0], sizes[1]


def parse_between(text: str, sizes: Sequence[int]) -> tuple[int, ...]:
    """``--between``: robot counts other than ``sizes`` ('' for none).

    Raises:
        StudyError: not positive integers, or one of ``sizes``.
    """
    try:
        between = tuple(int(t) for t in text.split(",")) if text.strip() else ()
    except ValueError:
        between = (0,)
    if any(n < 1 or n in sizes for n in between):
        raise StudyError(f"--between must be robot counts >= 1 other than --sizes, got {text!r}")
    return between


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("runs/colony_scale"),
                        help="the colony study's run directories")  # fmt: skip
    parser.add_argument("--published", type=Path, default=Path("results/colony_scale"),
                        help="the study's published tables; swap.csv goes here")  # fmt: skip
    parser.add_argument("--seeds", default=SEEDS)
    parser.add_argument(
        "--sizes",
        default=",".join(map(str, SIZES)),
        help="the two robot counts whose populations trade worlds",
    )
    parser.add_argument("--between", default=",".join(map(str, BETWEEN)),
                        help="robot counts whose EE worlds the smaller size's population "
                        "also lives in ('' for none)")  # fmt: skip
    parser.add_argument("--workers", type=int, default=2, help="evaluations at a time")
    args = parser.parse_args(argv)
    try:
        if isinstance(args.workers, bool) or args.workers < 1:
            raise StudyError(f"--workers must be an integer >= 1, got {args.workers}")
        seeds = parse_seeds(args.seeds)
        sizes = parse_sizes(args.sizes)
        between = parse_between(args.between, sizes)
        evaluations = plan(args.out, args.published, seeds, sizes, between, args.out / CACHE)
    except ValueError as err:  # StudyError too: one line, status 2, before anything runs
        print(f"{PROG}: error: {str(err).splitlines()[0]}", file=sys.stderr)
        return 2
    print(f"{PROG}: {len(evaluations)} evaluations of one generation", flush=True)
    table = pd.concat([swap_table(evaluations, args.workers, progress=True),
                       pd.DataFrame(random_rows(args.published, seeds, sizes))],
                      ignore_index=True)  # fmt: skip
    tests = swap_tests(table, sizes)
    print(f"wrote {write_csv(table, args.published / SWAP_FILE)}")
    print(f"wrote {write_csv(tests, args.published / 'swap_tests.csv')}")
    print(swap_markdown(table, tests))
    return 0


if __name__ == "__main__":
    sys.exit(main())
