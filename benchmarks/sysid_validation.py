"""System identification without a robot: recover 3 hidden "true robots" and measure the gap.

Each true robot (:func:`cyber_rodent.sysid.synthetic.true_robot`, seeds 1001-1003; the fit's
development used seed 101 only) drives 3 simulated Cyber Rodents for ``--seconds`` under a
scripted wander, logged with tracker dropouts, encoder glitches and clock jitter. ``sysid`` fits
a profile to each log; the gap report compares the hand-set profile (the hardware profile's noise,
the model's drive) with the fitted one on the held-out segments.

Writes ``results/sysid/recovery.csv`` (true value, fit, bootstrap standard error, |error| / se),
``results/sysid/fitted_<seed>.json`` (each fitted profile, a file ``--profile`` accepts),
``results/sysid/gap.csv``, ``results/sysid/run.json`` (commit, command, settings) and
``docs/images/sysid_gap.png``::

    python benchmarks/sysid_validation.py
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from cyber_rodent.atomic import write_json, write_text
from cyber_rodent.profiles import HardwareProfile, save_profile
from cyber_rodent.sysid.fit import SysidConfig, sysid
from cyber_rodent.sysid.gap import gap_figure, gap_samples, gap_table
from cyber_rodent.sysid.log import read_log, write_log
from cyber_rodent.sysid.synthetic import LogFaults, simulate_log, true_robot

ROOT = Path(__file__).resolve().parents[1]
SEEDS = (1001, 1002, 1003)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=80.0, help="log length per robot, s")
    parser.add_argument("--bootstrap", type=int, default=8)
    parser.add_argument("--out", default=str(ROOT / "results" / "sysid"))
    parser.add_argument("--figure", default=str(ROOT / "docs" / "images" / "sysid_gap.png"))
    args = parser.parse_args()
    config = SysidConfig(bootstrap=args.bootstrap, max_evals=150, bootstrap_evals=60)
    faults = LogFaults()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recovery, gaps = [], []
    pooled: dict[str, dict[str, list[np.ndarray]]] = {"hand-set": {}, "fitted": {}}
    started = time.time()
    for seed in SEEDS:
        truth = true_robot(seed)
        table, field, packs = simulate_log(truth, args.seconds, seed=seed + 50_000, faults=faults)
        with tempfile.TemporaryDirectory() as tmp:
            log = read_log(write_log(Path(tmp) / "log.csv", table, field, packs))
        result = sysid([log], config)
        save_profile(
            out / f"fitted_{seed}.json",
            result.profile,
            {"true_robot_seed": seed, "log_seed": seed + 50_000, "seconds": args.seconds},
        )  # the fitted profile the pretraining study (benchmarks/sysid_pretraining.py) reads
        hidden = truth.parameters()
        for name, (value, se) in result.parameters.items():
            recovery.append({"true_robot": seed, "parameter": name, "true": hidden[name],
                             "fitted": value, "se": se,
                             "abs_error_over_se":
                                 abs(value - hidden[name]) / se if se > 0 else np.inf})  # fmt: skip
        samples = {
            "hand-set": gap_samples([log], HardwareProfile(), config, all_segments=False),
            "fitted": gap_samples([log], result.profile, config, all_segments=False),
        }
        t = gap_table(samples)
        t.insert(0, "true_robot", seed)
        gaps.append(t)
        for label, s in samples.items():
            for k, v in s.items():
                pooled[label].setdefault(k, []).append(v)
        print(f"true robot {seed}: fitted in {time.time() - started:.0f} s", flush=True)
    rec = pd.DataFrame(recovery)
    gap = pd.concat(gaps, ignore_index=True)
    write_text(out / "recovery.csv", rec.to_csv(index=False, float_format="%.5g"))
    write_text(out / "gap.csv", gap.to_csv(index=False, float_format="%.5g"))
    merged = {label: {k: np.concatenate(v) for k, v in s.items()} for label, s in pooled.items()}
    for s in merged.values():  # the miss rates: one per true robot, averaged
        s["cam_miss_observed"] = np.array([s["cam_miss_observed"].mean()])
        s["cam_miss_predicted"] = np.array([s["cam_miss_predicted"].mean()])
    title = "Reality gap on held-out segments, 3 hidden true robots: hand-set vs fitted"
    gap_figure(merged, args.figure, title)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()  # fmt: skip
    dirty = bool(subprocess.run(["git", "status", "--porcelain", "--", "cyber_rodent"], cwd=ROOT,
                                capture_output=True, text=True).stdout.strip())  # fmt: skip
    write_json(out / "run.json", {
        "command": "python benchmarks/sysid_validation.py " + " ".join(sys.argv[1:]),
        "commit": commit, "cyber_rodent_modified": dirty, "true_robot_seeds": list(SEEDS),
        "log_seeds": [s + 50_000 for s in SEEDS], "seconds_per_robot": args.seconds,
        "sysid": dataclasses.asdict(config), "faults": dataclasses.asdict(faults),
        "wall_s": round(time.time() - started, 1),
    })  # fmt: skip
    within = (rec["abs_error_over_se"] <= 2).mean()
    print(rec.to_string(index=False))
    print(gap[gap["metric"].isin(["pose_5s", "pose_10s", "wheel", "ir_w1", "cam_bearing_w1"])]
          .to_string(index=False))  # fmt: skip
    print(f"parameters within 2 standard errors: {within:.0%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
