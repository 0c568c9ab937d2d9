"""``cyber-rodent gap``: the reality gap of a profile on run logs, before and after a fit."""

from __future__ import annotations

import argparse
from pathlib import Path

from evolution.cli.parsing import CliError
from evolution.cli.sysid import config_from

HELP = "measure the reality gap of a profile on a robot's run logs (table and figure)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Per-sensor error distributions and pose divergence over 1-10 s of a profile against "
        "run logs, on the segments the fit held out, next to the profile before the fit; "
        "writes a CSV table and a PNG figure."
    )
    parser.add_argument("logs", nargs="+", metavar="LOG", help="run logs (CSV)")
    parser.add_argument("--profile", required=True, help="the fitted profile file (or a name)")
    parser.add_argument(
        "--before", default="hardware", help="the profile before the fit: sim, hardware or a file"
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="directory for gap.csv/png")
    parser.add_argument(
        "--all-segments", action="store_true",
        help="use every segment (logs the fit never saw), not only the held-out ones",
    )  # fmt: skip
    parser.add_argument("--segment", type=float, default=10.0, help="segment length, s")
    parser.add_argument("--holdout-every", type=int, default=4, help="as sysid was given")
    parser.add_argument("--bootstrap", type=int, default=20, help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--replicates", type=int, default=0, help=argparse.SUPPRESS)


def run(args: argparse.Namespace) -> int:
    from cyber_rodent.profiles import profile_from_arg
    from cyber_rodent.sysid.gap import gap_figure, gap_samples, gap_table
    from cyber_rodent.sysid.log import read_log

    config = config_from(args)
    after = profile_from_arg(args.profile)
    before = profile_from_arg(args.before)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out} is a file, not a directory")
    logs = [read_log(path) for path in args.logs]
    samples = {
        "before": gap_samples(logs, before, config, args.all_segments),
        "after": gap_samples(logs, after, config, args.all_segments),
    }
    table = gap_table(samples)
    out.mkdir(parents=True, exist_ok=True)
    from cyber_rodent.atomic import write_text

    write_text(out / "gap.csv", table.to_csv(index=False, float_format="%.5g"))
    gap_figure(samples, str(out / "gap.png"), f"reality gap: {args.before} vs {args.profile}")
    print(table.to_string(index=False))
    print(f"wrote {out / 'gap.csv'}, {out / 'gap.png'}")
    return 0
