"""``cyber-rodent sysid``: fit the hardware profile to a real robot's run logs."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from evolution.cli.parsing import CliError, int_arg

HELP = "fit the hardware profile (drive, IR and camera noise) to a robot's run logs"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Replay the logged wheel commands in MuJoCo and fit each robot's wheel gains, motor "
        "lag and friction; fit the IR and camera noise at the logged poses; estimate each "
        "value's error by refitting on resampled log segments and on re-simulations of the "
        "logs with the fitted values (docs/robots.md). Writes a profile file that --profile "
        "accepts (train-behaviours, evolve, transfer). Log format: docs/robots.md."
    )
    parser.add_argument("logs", nargs="+", metavar="LOG", help="run logs (CSV)")
    parser.add_argument("--out", required=True, metavar="PROFILE", help="profile file to write")
    parser.add_argument(
        "--bootstrap", type=int_arg("--bootstrap"), default=20, help="bootstrap resamples"
    )
    parser.add_argument(
        "--replicates", type=int_arg("--replicates"), default=8,
        help="re-simulations of the logs for the error model (0: segment bootstrap only)",
    )  # fmt: skip
    parser.add_argument(
        "--starts", type=int_arg("--starts"), default=3,
        help="searches per drive fit, from the best scanned gains and motor lags (1-24)",
    )  # fmt: skip
    parser.add_argument(
        "--segment", type=float, default=10.0, help="segment length, s (default 10)"
    )
    parser.add_argument(
        "--holdout-every", type=int_arg("--holdout-every"), default=4,
        help="hold one in N segments out of the fit, for 'gap' (0: none)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int_arg("--seed"), default=0, help="bootstrap seed")


def config_from(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from cyber_rodent.sysid.fit import SysidConfig

    try:
        return SysidConfig(
            segment_s=args.segment, holdout_every=args.holdout_every,
            bootstrap=args.bootstrap, seed=args.seed, replicates=args.replicates,
            starts=args.starts,
        )  # fmt: skip
    except ValueError as err:
        text = str(err).replace("sysid.segment_s", "--segment").replace("sysid.", "--")
        raise CliError(text.replace("holdout_every", "holdout-every")) from None


def run(args: argparse.Namespace) -> int:
    from cyber_rodent.profiles import save_profile
    from cyber_rodent.sysid.fit import sysid
    from cyber_rodent.sysid.log import read_log

    config = config_from(args)
    out = Path(args.out)
    if not out.parent.is_dir():
        raise CliError(f"--out {out}: no such directory {out.parent}")
    logs = [read_log(path) for path in args.logs]  # every log checked before any work
    result = sysid(logs, config)
    provenance = {
        "logs": [str(p) for p in args.logs],
        "sysid": dataclasses.asdict(config),
        "parameters": {
            k: {"value": v, "se": s, **dataclasses.asdict(result.errors[k])}
            for k, (v, s) in result.parameters.items()
        },
        "held_out": result.held_out,
    }
    save_profile(out, result.profile, provenance)
    for name, (value, se) in result.parameters.items():
        print(f"{name:28s} {value:10.4g} ± {se:.2g}")
    print(f"wrote {out} ({len(result.held_out)} segments held out for 'cyber-rodent gap')")
    return 0
