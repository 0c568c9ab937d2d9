"""What the rescue would have done: a run continued from a checkpoint, with and without it.

A finished run's checkpoint holds the whole colony mid-run. This continues it twice for
``--steps`` control steps, once as it ran and once with ``survival.rescue`` switched on (and
``--set`` changes to the rescue's settings), and prints, per robot, what the watchdog saw:
its stuck and tipped spells (how many, the steps in all, the longest), its rescues, how far it
got from where it stood at the checkpoint, and the deaths of the agents it ran; and the
generations each continuation closed. Without the rescue the continuation is the run itself,
bit for bit (the checkpoint's guarantee), so a jam the run had shows up in it.

Fig. 6's EE seed 19 of the published model jammed two robots in a corner at its generation 65
(docs/results.md). To see the rescue free them::

    cyber-rodent evolve --method ee --seed 19 --generations 65 --keep-checkpoints 0 \\
      --set world.contacts=published --out runs/jam/ee-seed019
    python -m benchmarks.jam_rescue runs/jam/ee-seed019/checkpoints/gen_00064.ckpt --steps 40000
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

# Run as a script, this file's directory would shadow the ``behaviours`` package: drop it.
if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)

from evolution.checkpoint import load_checkpoint  # noqa: E402
from evolution.runner import EvolutionRunner, run_config_from_record  # noqa: E402
from evolution.runner.checkpoints import restore_runner  # noqa: E402
from evolution.runner.events import EventKind  # noqa: E402
from evolution.runner.settings import apply, parse_set  # noqa: E402


def continue_run(
    checkpoint: Path, steps: int, rescue: bool, settings: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Continue the run saved in ``checkpoint`` for ``steps`` control steps, with the rescue on
    or off (``settings``: more changes, by dotted key); what the watchdog saw, per robot."""
    state = load_checkpoint(checkpoint)
    config = run_config_from_record(state["config"])
    config = apply(config, {**(settings or {}), "survival.rescue": rescue})
    runner = EvolutionRunner(config, int(state["seed"]))
    try:
        restore_runner(runner, state)
        start_step, first = runner.steps, len(runner.events)
        start_xy = runner.world.poses()[:, :2].copy()
        closed = []
        for _ in range(steps):
            if runner.step():
                closed.append(runner.steps)
        events = np.array(runner.events.array[first:])
        end_xy = runner.world.poses()[:, :2]
    finally:
        runner.close()
    robots = []
    for robot in range(config.world.n_robots):
        mine = events[events[:, 1] == robot]
        spells = []
        for kind, end_kind, name in (
            (EventKind.STUCK, EventKind.STUCK_END, "stuck"),
            (EventKind.TIPPED, EventKind.TIPPED_END, "tipped"),
        ):
            starts = mine[mine[:, 2] == kind, 0]
            ends = mine[np.isin(mine[:, 2], (end_kind, EventKind.RESCUE)), 0]
            for begin in starts:
                later = ends[ends >= begin]
                spells.append({
                    "kind": name, "start": int(begin - start_step),
                    "steps": int(later[0] - begin) if len(later) else None,
                })  # fmt: skip
        robots.append({
            "robot": robot,
            "spells": spells,
            "rescues": int((mine[:, 2] == EventKind.RESCUE).sum()),
            "deaths": int((mine[:, 2] == EventKind.DEATH).sum()),
            "moved_m": round(float(np.hypot(*(end_xy[robot] - start_xy[robot]))), 2),
        })  # fmt: skip
    return {"rescue": rescue, "steps": steps, "closed_after": [s - start_step for s in closed],
            "robots": robots}  # fmt: skip


def describe(result: dict[str, Any]) -> str:
    """The continuation in words: one line per robot, then the generations closed."""
    lines = [f"rescue {'on' if result['rescue'] else 'off'}, {result['steps']} control steps:"]
    for robot in result["robots"]:
        parts = []
        for kind in ("stuck", "tipped"):
            spells = [s for s in robot["spells"] if s["kind"] == kind]
            if not spells:
                continue
            lengths = [result["steps"] - s["start"] if s["steps"] is None else s["steps"]
                       for s in spells]  # fmt: skip
            still = " (the last still on at the end)" if spells[-1]["steps"] is None else ""
            parts.append(f"{kind} {len(spells)}x, {sum(lengths)} steps in all, longest "
                         f"{max(lengths)}{still}")  # fmt: skip
        lines.append(
            f"  CR{robot['robot']}: {'; '.join(parts) or 'never stuck or tipped'}; "
            f"rescues {robot['rescues']}; agents died {robot['deaths']}; "
            f"moved {robot['moved_m']} m"
        )
    closed = result["closed_after"]
    lines.append(f"  generations closed: {len(closed)} (after steps {closed[:8]})")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path, help="a run's checkpoint (gen_NNNNN.ckpt)")
    parser.add_argument("--steps", type=int, default=40_000, help="control steps to continue")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a rescue setting, e.g. survival.rescue_after_steps=50",
    )
    args = parser.parse_args(argv)
    try:
        settings = parse_set(args.set)
        if args.steps < 1:
            raise ValueError(f"--steps must be at least 1, got {args.steps}")
    except ValueError as err:
        print(f"jam_rescue: error: {str(err).splitlines()[0]}", file=sys.stderr)
        return 2
    for rescue in (False, True):
        print(describe(continue_run(args.checkpoint, args.steps, rescue, settings)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
