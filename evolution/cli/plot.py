"""``cyber-rodent plot``: Fig. 6 and the EE vs CE statistics of a run or sweep directory."""

from __future__ import annotations

import argparse
from pathlib import Path

from evolution.cli.parsing import CliError

HELP = "Fig. 6 and the EE vs CE statistics of a run or sweep directory"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Draw Fig. 6 and the completed agents per generation (PNG + PDF), and "
        "write the EE vs CE statistics (comparison.csv: Mann-Whitney U, effect size, CE "
        "convergence, EE rise) of a run directory, a sweep directory or a directory of "
        "published run tables into <dir>/figures (or --out); a grid sweep also gets the "
        "comparison of its cells (cells.csv, cells.png)."
    )
    parser.add_argument(
        "dir", help="a run directory, a sweep directory or published run tables"
    )
    parser.add_argument(
        "--out", default=None, help="directory for the figures and tables (default: DIR/figures)"
    )


def run(args: argparse.Namespace) -> int:
    from evolution.lab import experiment

    if not Path(args.dir).is_dir():
        what = "is a file, not" if Path(args.dir).exists() else "is not"
        raise CliError(f"{args.dir} {what} a run or sweep directory")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise CliError(f"--out {args.out} is a file, not a directory")
    for path in experiment.plot_run_dir(args.dir, args.out):
        print(f"wrote {path}")
    return 0
