"""How much of its commanded motion a robot the watchdog calls stuck achieves, step by step.

Runs the paper's EE for ``--steps`` control steps (seed ``--seed``; 5 is a development seed, not
one of the reported ones) and, for every step in which a robot is stuck, compares what it
achieved in that step (distance, turn) with what it commanded (speed x control step; turn rate
(right - left) / 2 / half wheel base). A held robot achieves nearly nothing; a robot that
dithers left and right on the spot achieves about a third of the turn it commands. This is the
measurement behind ``survival.stuck_progress`` (docs/design.md §9.35)::

    python -m benchmarks.watchdog_progress
"""

from __future__ import annotations

import argparse

import numpy as np

from behaviours import BehaviourPolicies
from evolution.runner import EvolutionRunner, RunConfig


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--steps", type=int, default=12_000)
    args = parser.parse_args()
    run = EvolutionRunner(RunConfig(), args.seed, BehaviourPolicies.load_default())
    dt = run.config.survival.control_dt
    half_base = run.world.robot.half_wheel_base
    turned, travelled = [], []
    for _ in range(args.steps):
        before = run.world.poses().copy()
        run.step()
        after = run.world.poses()
        wheels = run.action.wheels
        for i in np.flatnonzero(run.watchdog.state.stuck_steps > 0):
            turn = abs(wheels[i, 1] - wheels[i, 0]) / (2 * half_base) * dt
            drive = abs(wheels[i, 0] + wheels[i, 1]) / 2 * dt
            if turn > 0.05:
                turned.append(abs(np.angle(np.exp(1j * (after[i, 2] - before[i, 2])))) / turn)
            if drive > 0.01:
                travelled.append(float(np.hypot(*(after[i, :2] - before[i, :2]))) / drive)
    stuck = len(turned) + len(travelled)
    print(f"EE seed {args.seed}, {args.steps} control steps: {stuck} stuck robot-steps")
    for name, shares in (("turn", turned), ("travel", travelled)):
        if shares:
            q = np.quantile(shares, [0.1, 0.5, 0.9])
            print(f"  achieved / commanded {name} ({len(shares)} steps): 10/50/90 % "
                  f"{q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
