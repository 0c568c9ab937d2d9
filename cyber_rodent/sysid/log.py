"""Reading a run log: the columns of :data:`cyber_rodent.robot_step.LOG_COLUMNS`, checked.

A log is a CSV file whose first line is ``# cyber-rodent-log {json}`` (schema version, field
size, pack positions) and whose second line names the columns. Every problem is one
``ValueError`` line naming the file, the column and the data row (1 = the first row after the
column names) and what the value must be: a missing or unknown column, a group with only some
of its columns, NaN or a value out of range, time that does not increase for a robot.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cyber_rodent.robot_step import LOG_COLUMNS, LOG_MARK, LOG_VERSION

#: Groups of columns, in the order of :data:`LOG_COLUMNS`.
GROUPS: dict[str, tuple[str, ...]] = {}
for _name, _unit, _low, _high, _group in LOG_COLUMNS:
    GROUPS[_group] = (*GROUPS.get(_group, ()), _name)
BOUNDS = {name: (low, high, unit) for name, unit, low, high, _ in LOG_COLUMNS}
CAMERA_CLASSES = ("led", "face", "battery")
#: Columns that may be empty where a flag says the value is absent: column -> flag column.
ABSENT_WHERE = {
    "x": "tracked",
    "y": "tracked",
    "yaw": "tracked",
    **{
        f"cam_{c}_{what}": f"cam_{c}_seen"
        for c in CAMERA_CLASSES
        for what in ("bearing", "distance", "area")
    },
}
#: Columns a robot may leave empty in any row: what the fit does not use and not every robot
#: measures (a camera that reports no blob area; a robot that does not know it mated).
OPTIONAL = {
    *(f"cam_{c}_area" for c in CAMERA_CLASSES),
    "energy",
    "battery_v",
    "docked",
    "mated",
}
FLAGS = {name for name, unit, *_ in LOG_COLUMNS if unit == "flag"}
INTEGERS = {"step", "robot"}


@dataclass(frozen=True)
class RunLog:
    """A checked run log.

    Attributes:
        path: where it was read from.
        table: one row per robot and control step, sorted by robot then step; flags as bool.
        field_size: side of the field, m.
        packs: (k, 2) the packs' positions, m.
    """

    path: Path
    table: pd.DataFrame
    field_size: float
    packs: np.ndarray

    @property
    def groups(self) -> tuple[str, ...]:
        return tuple(g for g, cols in GROUPS.items() if cols[0] in self.table.columns)

    @property
    def robots(self) -> tuple[int, ...]:
        return tuple(int(r) for r in np.unique(self.table["robot"]))

    def of_robot(self, robot: int) -> pd.DataFrame:
        """The rows of one robot, in step order (a fresh index)."""
        return self.table[self.table["robot"] == robot].reset_index(drop=True)


def _bad(path: Path, column: str, row: int, what: str) -> ValueError:
    return ValueError(f"{path}: column {column}, row {row}: {what}")


def read_log(path: str | os.PathLike[str]) -> RunLog:
    """Read and check a run log (see the module docstring).

    Raises:
        ValueError: one line naming the column and row at fault and the allowed range.
    """
    p = Path(path)
    try:
        with open(p) as handle:
            first = handle.readline()
            if not first.startswith(LOG_MARK):
                raise ValueError(f"{p}: not a run log (its first line must start {LOG_MARK!r})")
            try:
                header = json.loads(first[len(LOG_MARK) :])
            except ValueError:
                raise ValueError(f"{p}: the header line is not a JSON object") from None
            table = pd.read_csv(handle, dtype=float)
    except OSError as err:
        raise ValueError(f"{p}: cannot read it ({err.strerror or err})") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as err:
        if str(err).startswith(str(p)):
            raise
        raise ValueError(f"{p}: not a CSV table of numbers ({str(err).splitlines()[0]})") from None
    if not isinstance(header, dict) or header.get("version") != LOG_VERSION:
        version = header.get("version") if isinstance(header, dict) else None
        raise ValueError(f"{p}: header version must be {LOG_VERSION}, got {version!r}")
    field_size = header.get("field_size", 2.3)
    if not isinstance(field_size, int | float) or not 0.5 <= field_size <= 50.0:
        raise ValueError(f"{p}: header field_size must be a number in [0.5, 50] m")
    try:
        packs = np.asarray(header.get("packs", []), dtype=float).reshape(-1, 2)
    except ValueError:
        raise ValueError(f"{p}: header packs must be a list of [x, y] pairs in m") from None
    if not np.isfinite(packs).all():
        raise ValueError(f"{p}: header packs must be finite [x, y] pairs in m")
    unknown = [c for c in table.columns if c not in BOUNDS]
    if unknown:
        raise ValueError(f"{p}: column {unknown[0]} is not a log column (schema {LOG_VERSION})")
    for group, columns in GROUPS.items():
        present = [c for c in columns if c in table.columns]
        if (group == "base" or present) and len(present) < len(columns):
            missing = next(c for c in columns if c not in table.columns)
            raise ValueError(
                f"{p}: missing column {missing} (group {group} needs {', '.join(columns)})"
            )
    if not len(table):
        raise ValueError(f"{p}: the log has no rows")
    values = table.to_numpy(dtype=float)
    for j, column in enumerate(table.columns):
        col = values[:, j]
        low, high, unit = BOUNDS[column]
        bad = np.isinf(col) if column in OPTIONAL else ~np.isfinite(col)
        flag = ABSENT_WHERE.get(column)
        if flag is not None:
            bad &= table[flag].to_numpy(dtype=float) != 0  # absent: may be empty
        ok_range = np.isnan(col) | ((col >= low) & (col <= high))
        if column in FLAGS:
            ok_range &= np.isnan(col) | (col == 0) | (col == 1)
        if column in INTEGERS:
            ok_range &= np.isnan(col) | (col == np.round(col))
        for problem, what in ((bad, "NaN or empty"), (~ok_range, "out of range")):
            if problem.any():
                row = int(np.argmax(problem))
                kind = "0 or 1" if column in FLAGS else f"a number in [{low:g}, {high:g}] {unit}"
                if column in INTEGERS:
                    kind = f"an integer in [{low:g}, {high:g}]"
                raise _bad(p, column, row + 1, f"{what} ({float(col[row])!r}); must be {kind}")
    for column in table.columns:
        if column in INTEGERS:
            table[column] = table[column].astype(np.int64)
        elif column in FLAGS:  # an optional flag left empty is missing (<NA>), not True
            has_gaps = bool(table[column].isna().any())
            table[column] = table[column].astype("boolean" if has_gaps else bool)
    robot = table["robot"].to_numpy()
    for column in ("step", "t"):
        v = table[column].to_numpy(dtype=float)
        for r in np.unique(robot):
            rows = np.flatnonzero(robot == r)
            back = np.flatnonzero(np.diff(v[rows]) <= 0)
            if len(back):
                row = int(rows[back[0] + 1]) + 1
                raise _bad(p, column, row, f"must increase for robot {r} (previous row "
                           f"{v[rows[back[0]]]:g}, this {v[rows[back[0] + 1]]:g})")  # fmt: skip
    table = table.sort_values(["robot", "step"], kind="stable").reset_index(drop=True)
    return RunLog(p, table, float(field_size), packs)


def write_log(
    path: str | os.PathLike[str], table: pd.DataFrame, field_size: float, packs: np.ndarray
) -> Path:
    """Write ``table`` (columns of :data:`LOG_COLUMNS`) as a run log, atomically."""
    from cyber_rodent.atomic import atomic_output

    order = [c for c in BOUNDS if c in table.columns]
    header = {"version": LOG_VERSION, "field_size": float(field_size),
              "packs": np.asarray(packs, dtype=float).reshape(-1, 2).tolist()}  # fmt: skip
    out = table[order].copy()
    for column in order:
        if column in FLAGS:
            out[column] = out[column].astype(float).astype(np.int64)
    with atomic_output(path) as temp, open(temp, "w") as handle:
        handle.write(LOG_MARK + json.dumps(header) + "\n")
        out.to_csv(handle, index=False, float_format="%.9g", lineterminator="\n")
    return Path(path)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


__all__ = ["GROUPS", "RunLog", "read_log", "wrap_angle", "write_log"]
