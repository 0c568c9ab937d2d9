"""What writing a run log costs the bundle's reference step (``reference_step.py --log``).

Writes a bundle of random agents (the paper's config), loads its own ``reference_step.py`` (the
numpy file a robot runs), and times its test-vector replay (``check_vectors``, 400 steps)
without and with a :class:`StepLog`, alternating, ``--repeats`` times each in one process so a
change of the machine's load hits both alike. Prints the median of each and their ratio::

    python -m benchmarks.step_log_cost
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from evolution.lab.deploy import write_bundle


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        bundle = write_bundle(
            Path(tmp) / "bundle", np.random.default_rng(0).uniform(-1, 1, (4, 39))
        )
        path = bundle / "reference_step.py"
        spec = importlib.util.spec_from_file_location("reference_step", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules["reference_step"] = module
        spec.loader.exec_module(module)
        plain, logged = [], []
        for k in range(args.repeats):
            t0 = time.perf_counter()
            result = module.check_vectors(bundle, backend="numpy")
            plain.append(time.perf_counter() - t0)
            groups = ("led", "camera", "ir", "energy", "events")  # what --log writes
            log = module.StepLog(Path(tmp) / f"run{k}.csv", groups=groups)
            t0 = time.perf_counter()
            module.check_vectors(bundle, backend="numpy", log=log)
            log.close()
            logged.append(time.perf_counter() - t0)
        assert result.mismatch is None and result.rows == result.total, result
    a, b = statistics.median(plain), statistics.median(logged)
    steps = result.total
    print(f"reference step, numpy backend, {steps} steps, median of {args.repeats}:")
    print(f"  without a log: {a / steps * 1e6:.1f} us per step")
    print(f"  with --log:    {b / steps * 1e6:.1f} us per step (the file closed and renamed)")
    print(f"  ratio: {b / a:.3f} (limit 1.10)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
