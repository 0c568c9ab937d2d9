"""System identification without a robot: recover 3 hidden "true robots" and measure the gap.

Each true robot (:func:`cyber_rodent.sysid.synthetic.true_robot`, seeds 1001-1003; the fit's
development used seed 101 only) drives 3 simulated Cyber Rodents for ``--seconds`` under a
scripted wander, logged with tracker dropouts, encoder glitches and clock jitter. ``sysid`` fits
a profile to each log; the gap report compares the hand-set profile (the hardware profile's noise,
the model's drive) with the fitted one on the held-out segments.

Writes ``recovery.csv`` (true value, fit, standard error and its parts, |error| / se),
``coverage.csv`` (per kind of parameter: how many true values lie within 2 standard errors,
with a 95 % Clopper-Pearson interval and the exact binomial test against 0.954, the coverage
of +-2 s.e. of a normal error), ``fitted_<seed>.json`` (each fitted profile, a file
``--profile`` accepts), ``gap.csv`` and ``run.json`` (commit, command, settings) in ``--out``,
and the gap figure::

    python benchmarks/sysid_validation.py --replicates 0       # round one (results/sysid)
    python benchmarks/sysid_validation.py --seeds 1004-1007 \
        --out results/sysid/round2/typical --figure docs/images/sysid_gap_round2.png
    python benchmarks/sysid_validation.py --spread worn --seeds 2001-2003 \
        --out results/sysid/round2/worn --figure ''
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from cyber_rodent.atomic import write_json, write_text
from cyber_rodent.profiles import HardwareProfile, save_profile
from cyber_rodent.sysid.fit import SysidConfig, sysid
from cyber_rodent.sysid.gap import gap_figure, gap_samples, gap_table
from cyber_rodent.sysid.log import read_log, write_log
from cyber_rodent.sysid.synthetic import SPREADS, LogFaults, simulate_log, true_robot

ROOT = Path(__file__).resolve().parents[1]
SEEDS = (1001, 1002, 1003)
RECOVERY_COLUMNS = ("true_robot", "parameter", "true", "fitted", "se", "segment_sd",
                    "replicate_sd", "replicate_bias", "abs_error_over_se")  # fmt: skip
#: The coverage of +-2 standard errors for a normally distributed error.
NOMINAL_COVERAGE = 0.954
#: Parameter kinds of the coverage table: name -> what the parameter's name ends with.
KINDS = {
    "wheel gains": ("gain_left", "gain_right"),
    "motor lag": ("motor_lag",),
    "friction": ("friction",),
    "IR noise": ("range_noise.std", "range_noise.dropout"),
    "camera noise": ("vision.bearing_std_deg", "vision.distance_rel_std", "vision.dropout"),
}


def coverage_table(recovery: pd.DataFrame) -> pd.DataFrame:
    """Per kind of parameter and all together: true values within 2 standard errors."""
    rows = []
    for kind, ends in [*KINDS.items(), ("all", tuple(e for v in KINDS.values() for e in v))]:
        part = recovery[recovery["parameter"].str.endswith(ends)]
        k, n = int((part["abs_error_over_se"] <= 2).sum()), len(part)
        test = binomtest(k, n, NOMINAL_COVERAGE)
        ci = test.proportion_ci(0.95, method="exact")
        rows.append({"kind": kind, "values": n, "within_2se": k, "coverage": k / n,
                     "ci_low": ci.low, "ci_high": ci.high, "p_vs_0.954": test.pvalue,
                     "median_abs_error_over_se":
                         float(part["abs_error_over_se"].median())})  # fmt: skip
    return pd.DataFrame(rows)


def seed_list(text: str) -> tuple[int, ...]:
    """``1001,1002`` or ``1004-1007``."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += range(int(a), int(b or a) + 1)
    return tuple(out)


def fit_one(seed: int, args: argparse.Namespace, config: SysidConfig, faults: LogFaults,
            out: Path) -> tuple[list[dict[str, Any]], pd.DataFrame, dict[str, Any]]:  # fmt: skip
    """Log, fit and gap-test true robot ``seed``: its recovery rows, gap table and gap samples
    (its fitted profile written to ``out``)."""
    truth = true_robot(seed, spread=args.spread)
    table, field, packs = simulate_log(truth, args.seconds, seed=seed + 50_000, faults=faults)
    with tempfile.TemporaryDirectory() as tmp:
        log = read_log(write_log(Path(tmp) / "log.csv", table, field, packs))
    result = sysid([log], config)
    save_profile(
        out / f"fitted_{seed}.json",
        result.profile,
        {"true_robot_seed": seed, "spread": args.spread, "log_seed": seed + 50_000,
         "seconds": args.seconds},
    )  # the fitted profile the pretraining study (benchmarks/sysid_pretraining.py) reads
    hidden = truth.parameters()
    rows = []
    for name, (value, se) in result.parameters.items():
        e = result.errors[name]
        rows.append({"true_robot": seed, "parameter": name, "true": hidden[name],
                     "fitted": value, "se": se, "segment_sd": e.segment_sd,
                     "replicate_sd": e.replicate_sd, "replicate_bias": e.replicate_bias,
                     "abs_error_over_se":
                         abs(value - hidden[name]) / se if se > 0 else np.inf})  # fmt: skip
    samples = {
        "hand-set": gap_samples([log], HardwareProfile(), config, all_segments=False),
        "fitted": gap_samples([log], result.profile, config, all_segments=False),
    }
    t = gap_table(samples)
    t.insert(0, "true_robot", seed)
    return rows, t, samples


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=80.0, help="log length per robot, s")
    parser.add_argument("--bootstrap", type=int, default=8)
    parser.add_argument("--replicates", type=int, default=8, help="the error model's replicates")
    parser.add_argument("--seeds", type=seed_list, default=SEEDS,
                        help="true robots, e.g. 1004-1007")  # fmt: skip
    parser.add_argument("--spread", default="typical", choices=sorted(SPREADS))
    parser.add_argument("--out", default=str(ROOT / "results" / "sysid"))
    parser.add_argument("--figure", default=str(ROOT / "docs" / "images" / "sysid_gap.png"),
                        help="the gap figure ('': none)")  # fmt: skip
    parser.add_argument("--cache", default=str(ROOT / "runs" / "sysid_validation"),
                        help="each true robot's fit is kept here, so a stopped run resumes "
                             "('': none)")  # fmt: skip
    args = parser.parse_args()
    config = SysidConfig(bootstrap=args.bootstrap, max_evals=150, bootstrap_evals=60,
                         replicates=args.replicates)  # fmt: skip
    faults = LogFaults()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recovery, gaps = [], []
    pooled: dict[str, dict[str, list[np.ndarray]]] = {"hand-set": {}, "fitted": {}}
    started = time.time()
    cache = Path(args.cache) if args.cache else None
    for seed in args.seeds:
        done = cache / f"{args.spread}_{seed}.json" if cache else None
        if done is not None and done.is_file():  # fitted by an earlier, interrupted run
            kept = json.loads(done.read_text())
            rows, t = kept["rows"], pd.DataFrame(kept["gap"])[kept["gap_columns"]]
            samples = {label: {k: np.asarray(v, dtype=float) for k, v in part.items()}
                       for label, part in kept["samples"].items()}  # fmt: skip
        else:
            rows, t, samples = fit_one(seed, args, config, faults, out)
            if done is not None:
                done.parent.mkdir(parents=True, exist_ok=True)
                write_json(done, {"rows": rows, "gap": t.to_dict("list"),
                                  "gap_columns": list(t.columns),
                                  "samples": {label: {k: np.asarray(v).tolist()
                                                      for k, v in part.items()}
                                              for label, part in samples.items()}})  # fmt: skip
        recovery += rows
        gaps.append(t)
        for label, part in samples.items():
            for k, v in part.items():
                pooled[label].setdefault(k, []).append(v)
        print(f"true robot {seed}: fitted ({time.time() - started:.0f} s)", flush=True)
    rec = pd.DataFrame(recovery)[list(RECOVERY_COLUMNS)]
    gap = pd.concat(gaps, ignore_index=True)
    write_text(out / "recovery.csv", rec.to_csv(index=False, float_format="%.5g"))
    write_text(out / "gap.csv", gap.to_csv(index=False, float_format="%.5g"))
    coverage = coverage_table(rec)
    write_text(out / "coverage.csv", coverage.to_csv(index=False, float_format="%.4g"))
    merged = {label: {k: np.concatenate(v) for k, v in s.items()} for label, s in pooled.items()}
    for s in merged.values():  # the miss rates: one per true robot, averaged
        s["cam_miss_observed"] = np.array([s["cam_miss_observed"].mean()])
        s["cam_miss_predicted"] = np.array([s["cam_miss_predicted"].mean()])
    title = (f"Reality gap on held-out segments, {len(args.seeds)} hidden true robots: "
             "hand-set vs fitted")  # fmt: skip
    if args.figure:
        gap_figure(merged, args.figure, title)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()  # fmt: skip
    dirty = bool(subprocess.run(["git", "status", "--porcelain", "--", "cyber_rodent"], cwd=ROOT,
                                capture_output=True, text=True).stdout.strip())  # fmt: skip
    write_json(out / "run.json", {
        "command": "python benchmarks/sysid_validation.py " + " ".join(sys.argv[1:]),
        "commit": commit, "cyber_rodent_modified": dirty, "true_robot_seeds": list(args.seeds),
        "spread": args.spread, "log_seeds": [s + 50_000 for s in args.seeds],
        "seconds_per_robot": args.seconds,
        "sysid": dataclasses.asdict(config), "faults": dataclasses.asdict(faults),
        "wall_s": round(time.time() - started, 1),
    })  # fmt: skip
    within = (rec["abs_error_over_se"] <= 2).mean()
    print(rec.to_string(index=False))
    print(coverage.to_string(index=False))
    print(gap[gap["metric"].isin(["pose_5s", "pose_10s", "wheel", "ir_w1", "cam_bearing_w1"])]
          .to_string(index=False))  # fmt: skip
    print(f"parameters within 2 standard errors: {within:.0%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
