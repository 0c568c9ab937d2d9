"""Reproduce the paper's Fig. 6 at its scale, publish its tables and draw it; rerun to continue.

The paper ran 20 simulations of each method for 120 generations. This script runs that sweep
(``--run``: ``cyber-rodent sweep --methods ee,ce --seeds 0-19 --generations 120``, resumed if
``--out`` holds it), then publishes and summarises what has finished::

    .venv/bin/python -m benchmarks.paper_fig6 --run [--workers 2] [--out runs/fig6]
    .venv/bin/python -m benchmarks.paper_fig6          # publish and draw from finished runs

1. each finished run's small tables go to ``--published`` (``results/fig6/<method>-seed<NNN>``,
   :func:`benchmarks.publish_runs.publish`), so no finished run is lost with the machine;
2. from the published runs only: ``fig6.{png,pdf}`` and ``fig6_completions.{png,pdf}`` in
   ``--figure-dir``; ``fig6_comparison.csv`` (EE vs CE: per-run means over generations
   100-119, Mann-Whitney U, effect size, CE's convergence generation, EE's rise over
   generations 0-20), ``fig6_runs.csv`` (every run's means over the window) and
   ``fig6_completions.csv`` in ``--table-dir``;
3. the headline numbers beside the paper's, printed as a Markdown table.

The paper's numbers are read from its Fig. 6: EE about 22 batteries and 3.5 matings per
400-step life at generation 120; CE about 25 and 2 after it converged (by about generation 40).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from benchmarks.publish_runs import publish  # noqa: E402
from cyber_rodent.atomic import atomic_output  # noqa: E402
from evolution.lab.comparison import (  # noqa: E402
    LATE_WINDOW,
    available_window,
    completions_by_method,
    run_means,
    summary_table,
)
from evolution.lab.figures import plot_completions, plot_fig6  # noqa: E402
from evolution.lab.sweep import load_sweep  # noqa: E402

#: The paper's headline numbers, read from its Fig. 6 (per 400-step life).
PAPER = {
    ("ee", "batteries"): 22.0,
    ("ee", "matings"): 3.5,
    ("ce", "batteries"): 25.0,
    ("ce", "matings"): 2.0,
}
#: The columns each run's window mean is taken of, by the name the tables use.
QUANTITIES = {"batteries": "batteries_mean", "matings": "matings_mean", "completed": "completed"}
#: The agreement the headline numbers are judged by (relative to the paper's).
TOLERANCE = 0.30


def run_sweep(out: Path, workers: int) -> None:
    """Run (or resume) the full sweep with the package's CLI, exactly as a user would."""
    command = [sys.executable, "-m", "evolution.cli", "sweep", "--methods", "ee,ce",
               "--seeds", "0-19", "--generations", "120", "--workers", str(workers),
               "--out", str(out)]  # fmt: skip
    if (out / "sweep.json").exists():
        command.append("--resume")
    subprocess.run(command, check=True)


def per_run_table(
    runs: Mapping[str, Sequence[pd.DataFrame]], window: tuple[int, int]
) -> pd.DataFrame:
    """One row per published run: its seed and its means over ``window``."""
    rows = []
    for method, tables in runs.items():
        means = {name: run_means(tables, column, *window) for name, column in QUANTITIES.items()}
        for i, table in enumerate(tables):
            row: dict[str, object] = {"method": method, "seed": int(table["seed"].iloc[0]),
                                      "generations": f"{window[0]}-{window[1]}"}  # fmt: skip
            row.update({name: float(values[i]) for name, values in means.items()})
            rows.append(row)
    return pd.DataFrame(rows).sort_values(["method", "seed"], ascending=[False, True])


def headline(runs_table: pd.DataFrame, comparison: pd.DataFrame) -> str:
    """The four headline numbers beside the paper's, as a Markdown table."""
    p_values = comparison.set_index("quantity")["p_value"]
    lines = ["| | ours (mean ± std over runs) | paper | ours / paper | EE vs CE, p |",
             "| --- | --- | --- | --- | --- |"]  # fmt: skip
    for method in ("ee", "ce"):
        rows = runs_table[runs_table["method"] == method]
        for quantity in ("batteries", "matings"):
            values = rows[quantity].dropna()
            paper = PAPER[(method, quantity)]
            ratio = values.mean() / paper
            mark = "" if abs(ratio - 1.0) <= TOLERANCE else " (outside ±30 %)"
            lines.append(
                f"| {method.upper()} {quantity} ({len(values)} runs) | {values.mean():.2f} ± "
                f"{values.std(ddof=1):.2f} | ≈ {paper:g} | {ratio:.2f}{mark} | "
                f"{p_values.get(quantity, float('nan')):.2g} |"
            )
    return "\n".join(lines)


def _write_csv(table: pd.DataFrame, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        table.to_csv(temp, index=False, float_format="%.6g")
    return path


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", action="store_true", help="run or resume the sweep first")
    parser.add_argument("--out", type=Path, default=Path("runs/fig6"), help="the sweep directory")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of the sweep")
    parser.add_argument("--published", type=Path, default=Path("results/fig6"),
                        help="where finished runs' tables are published")  # fmt: skip
    parser.add_argument("--table-dir", type=Path, default=Path("results"))
    parser.add_argument("--figure-dir", type=Path, default=Path("docs/images"))
    args = parser.parse_args(argv)
    if args.run:
        run_sweep(args.out, args.workers)
    if args.out.is_dir():
        for name in publish(args.out, args.published):
            print(f"published {name}")
    runs = {m: t for m, t in load_sweep(args.published).items() if t}
    if not runs:
        sys.exit(f"paper_fig6: error: no published run in {args.published}")
    window = available_window([t for ts in runs.values() for t in ts], LATE_WINDOW)
    if window is None:
        sys.exit(f"paper_fig6: error: no run in {args.published} closed a generation")
    written = plot_fig6(runs, args.figure_dir / "fig6")
    written += plot_completions(runs, args.figure_dir / "fig6_completions")
    comparison = summary_table(runs)
    runs_table = per_run_table(runs, window)
    written += [
        _write_csv(comparison, args.table_dir / "fig6_comparison.csv"),
        _write_csv(runs_table, args.table_dir / "fig6_runs.csv"),
        _write_csv(completions_by_method(runs), args.table_dir / "fig6_completions.csv"),
    ]
    for path in written:
        print(f"wrote {path}")
    print(headline(runs_table, comparison))


if __name__ == "__main__":
    main()
