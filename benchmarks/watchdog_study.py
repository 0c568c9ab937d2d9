"""How often robots tip over or jam, from the watchdog's events in finished runs.

For every run directory under the given roots (a run's ``events.csv`` and ``run.json``), this
counts the watchdog's events (``tipped``, ``stuck``, their ends and ``rescue``;
``cyber_rodent/survival/watchdog.py``) and writes, per run and per setting (root):

- robot-hours simulated (control steps x robots x the control step's seconds / 3600);
- tips and jams that began, per robot-hour, and how long they lasted (median and longest, in
  control steps; a trouble still going on at the run's end counts to the end). A robot that is
  let go for a step and held again is a new spell to the watchdog, which needs its 25-step
  window to flag it again; for the counts and durations, spells of one robot separated by fewer
  than ``--merge-gap`` steps (50, twice that window) are one trouble. The spells are counted
  too (``*_spells``), with the share of robot time spent in them (``*_share``) and, with
  ``--window G0-G1``, that share within the window's generations alone (``*_share_window``:
  the steps of each spell between the close of generation G0 - 1 and that of G1), the
  generations a published figure reports;
- the robots concerned;
- whether the run replays its published table: ``--published DIR`` compares each run's
  ``statistics.csv`` with ``DIR/<run>/statistics.csv``, byte for byte over the generations
  both have;
- ``--lagging G0-G1``: the robots that took part in at most 2 of generations G0..G1 (a robot
  "takes part" in a generation when one of its agents completed a life in it,
  ``statistics_per_robot.csv``) and, for each, whether it was tipped or stuck during them.

Run: ``python -m benchmarks.watchdog_study ROOT [ROOT ...] [--published DIR] [--lagging
40-59] [--window 100-119] [--merge-gap 50] [--out results/watchdog]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cyber_rodent.atomic import atomic_output

TROUBLES = (("tip", "tipped", "tipped_end"), ("jam", "stuck", "stuck_end"))


def run_dirs(root: Path) -> list[Path]:
    """The finished run directories under ``root`` (or ``root`` itself), in name order: those
    with an event log, which a run writes when it ends."""
    if (root / "run.json").exists():
        return [root]
    return sorted(p.parent for p in root.glob("*/run.json") if (p.parent / "events.csv").exists())


def episodes(events: pd.DataFrame, start: str, end: str, last_step: int) -> pd.DataFrame:
    """One row per trouble: robot, first step, steps it lasted (to the run's end if open)."""
    rows = []
    for robot, group in events[events["kind"].isin((start, end))].groupby("robot"):
        began = None
        for step, kind, value in group[["step", "kind", "value"]].itertuples(index=False):
            if kind == start:
                began = int(step)
            elif began is not None:
                rows.append((int(robot), began, int(value)))
                began = None
        if began is not None:
            rows.append((int(robot), began, last_step - began + 1))
    return pd.DataFrame(rows, columns=["robot", "step", "steps"])


def merged(spells: pd.DataFrame, gap: int) -> pd.DataFrame:
    """The spells with those of one robot less than ``gap`` steps apart joined into one row,
    which lasts from the first spell's start to the last one's end."""
    joined: list[list[int]] = []  # robot, first step, end step
    ordered = spells.sort_values(["robot", "step"])[["robot", "step", "steps"]]
    for robot, step, steps in ordered.itertuples(index=False):
        if joined and joined[-1][0] == robot and step - joined[-1][2] < gap:
            joined[-1][2] = max(joined[-1][2], int(step + steps))
        else:
            joined.append([int(robot), int(step), int(step + steps)])
    rows = [(robot, first, end - first) for robot, first, end in joined]
    return pd.DataFrame(rows, columns=["robot", "step", "steps"])


def window_steps(path: Path, window: tuple[int, int]) -> tuple[int, int]:
    """The control steps (after ``begin``, up to ``end``) of generations G0..G1 of a run; an
    empty span (0, 0) if the run closed no generation of the window."""
    closed = pd.read_csv(path / "statistics.csv")["closed_at_step"].tolist()
    first, last = window
    if first >= len(closed):
        return 0, 0
    return (closed[first - 1] if first > 0 else 0), closed[min(last, len(closed) - 1)]


def share_within(spells: pd.DataFrame, begin: int, end: int, robots: int) -> float:
    """The share of the robot-steps after ``begin`` up to ``end`` that the spells cover."""
    if end <= begin:
        return float("nan")
    starts = spells["step"].to_numpy()
    ends = starts + spells["steps"].to_numpy()
    covered = np.clip(np.minimum(ends, end + 1) - np.maximum(starts, begin + 1), 0, None)
    return float(covered.sum()) / ((end - begin) * robots)


def summarise_run(path: Path, published: Path | None, lagging: tuple[int, int] | None,
                  merge_gap: int = 50, window: tuple[int, int] | None = None
                  ) -> dict[str, Any]:  # fmt: skip
    record = json.loads((path / "run.json").read_text())
    config = record["config"]
    n = int(config["world"]["n_robots"])
    dt = float(config["survival"]["control_dt"])
    steps = int(record["summary"]["control_steps"])
    hours = steps * n * dt / 3600
    events = pd.read_csv(path / "events.csv")
    row: dict[str, Any] = {
        "run": path.name, "method": config["method"], "seed": record["seed"], "robots": n,
        "generations": int(record["summary"]["completed_generations"]),
        "robot_hours": round(hours, 2), "commit": record["versions"].get("git_commit"),
    }  # fmt: skip
    every_spell = []
    for name, start, end in TROUBLES:
        spells = episodes(events, start, end, steps)
        every_spell.append(spells)
        found = merged(spells, merge_gap)
        row[f"{name}_spells"] = len(spells)
        share = float(spells["steps"].sum()) / (steps * n) if steps else 0.0
        row[f"{name}_share"] = round(share, 5)
        if window is not None:
            within = share_within(spells, *window_steps(path, window), n)
            row[f"{name}_share_window"] = round(within, 5)
        row[f"{name}s"] = len(found)
        row[f"{name}s_per_robot_hour"] = round(len(found) / hours, 4) if hours else float("nan")
        row[f"{name}_median_steps"] = float(found["steps"].median()) if len(found) else 0.0
        row[f"{name}_longest_steps"] = int(found["steps"].max()) if len(found) else 0
        row[f"{name}_robots"] = " ".join(map(str, sorted(set(found["robot"])))) or "-"
    row["rescues"] = int((events["kind"] == "rescue").sum())
    if published is not None:
        row["replays_published"] = replays(path, published / path.name)
    if lagging is not None:
        row.update(lagging_robots(path, events, lagging, pd.concat(every_spell)))
    return row


def replays(path: Path, published: Path) -> str:
    """``yes`` if ``path``'s statistics.csv equals the published one over their common rows,
    ``no``, or ``-`` if nothing is published."""
    theirs = published / "statistics.csv"
    if not theirs.exists():
        return "-"
    ours_lines = (path / "statistics.csv").read_text().splitlines()
    their_lines = theirs.read_text().splitlines()
    common = min(len(ours_lines), len(their_lines))
    return "yes" if common > 1 and ours_lines[:common] == their_lines[:common] else "no"


def lagging_robots(path: Path, events: pd.DataFrame, window: tuple[int, int],
                   spells: pd.DataFrame) -> dict[str, Any]:  # fmt: skip
    """The robots that completed a life in at most 2 of the window's generations, and the
    watchdog's troubles of each within the window's steps: ``robot:<tips>t<jams>j<share>%``,
    the tips and stuck spells that began in the window and the share of its steps the robot
    spent tipped or stuck (``spells``: the run's tips and jams, :func:`episodes`)."""
    per_robot = pd.read_csv(path / "statistics_per_robot.csv")
    first, last = window
    inside = per_robot[(per_robot["generation"] >= first) & (per_robot["generation"] <= last)]
    taking_part = inside[inside["full_lifetimes"] > 0].groupby("robot")["generation"].nunique()
    robots = sorted(set(per_robot["robot"]))
    lagging = [r for r in robots if int(taking_part.get(r, 0)) <= 2]
    begin, end = window_steps(path, window)
    window_events = events[(events["step"] > begin) & (events["step"] <= end)]
    troubled = []
    for robot in lagging:
        mine = window_events[window_events["robot"] == robot]
        tips = int((mine["kind"] == "tipped").sum())
        jams = int((mine["kind"] == "stuck").sum())
        held = share_within(spells[spells["robot"] == robot], begin, end, 1)
        troubled.append(f"{robot}:{tips}t{jams}j{100 * held:.0f}%")
    return {"lagging_robots": len(lagging), "lagging_troubles": " ".join(troubled) or "-",
            "median_generations_taken_part": float(np.median(
                [int(taking_part.get(r, 0)) for r in robots]))}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="watchdog_study", description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=Path, help="sweep or run directories")
    parser.add_argument("--published", type=Path, help="the published tables to compare with")
    parser.add_argument("--lagging", help="generations G0-G1 of the lagging-robots check")
    parser.add_argument("--window", help="generations G0-G1 of the *_share_window columns")
    parser.add_argument("--merge-gap", type=int, default=50,
                        help="spells of one robot fewer than this many steps apart are one trouble")
    parser.add_argument("--out", type=Path, help="write watchdog_runs.csv here")
    args = parser.parse_args(argv)
    if args.merge_gap < 1:
        print(f"{parser.prog}: --merge-gap must be an integer >= 1, got {args.merge_gap}",
              file=sys.stderr)  # fmt: skip
        return 2
    windows: dict[str, tuple[int, int] | None] = {}
    for option in ("lagging", "window"):
        text = getattr(args, option)
        try:
            first, last = (int(x) for x in text.split("-")) if text else (0, 0)
        except ValueError:
            first = last = -1
        if text and not 0 <= first <= last:
            print(f"{parser.prog}: --{option} must be G0-G1 with 0 <= G0 <= G1, got {text!r}",
                  file=sys.stderr)  # fmt: skip
            return 2
        windows[option] = (first, last) if text else None
    rows = []
    for root in args.roots:
        for path in run_dirs(root):
            row = summarise_run(path, args.published, windows["lagging"], args.merge_gap,
                                windows["window"])  # fmt: skip
            row["setting"] = root.name
            rows.append(row)
    if not rows:
        print(f"{parser.prog}: no run directories under {args.roots}", file=sys.stderr)
        return 2
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_columns", 40):
        print(table.to_string(index=False))
    columns = ["robot_hours", "tips", "jams", "tip_spells", "jam_spells", "rescues"]
    totals = table.groupby("setting")[columns].sum()
    totals["tips_per_robot_hour"] = totals["tips"] / totals["robot_hours"]
    totals["jams_per_robot_hour"] = totals["jams"] / totals["robot_hours"]
    for name in ("tip", "jam"):
        weighted = table[f"{name}_share"] * table["robot_hours"]
        totals[f"{name}_share"] = weighted.groupby(table["setting"]).sum() / totals["robot_hours"]
        if f"{name}_share_window" in table:  # the runs' plain mean: windows differ in length
            totals[f"{name}_share_window"] = table.groupby("setting")[f"{name}_share_window"].mean()
    print(totals.to_string())
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        with atomic_output(args.out / "watchdog_runs.csv") as temp:
            table.to_csv(temp, index=False)
        with atomic_output(args.out / "watchdog_summary.csv") as temp:
            totals.to_csv(temp, float_format="%.4g")
    return 0


if __name__ == "__main__":
    sys.exit(main())
