"""One Cyber Rodent control step for a real robot's controller: standalone, numpy only.

This file is the robot side of the simulator, and the one implementation of it: it is copied
verbatim into every deployment bundle as ``reference_step.py`` (``cyber-rodent deploy``), and
the PettingZoo colony's baseline policy (:mod:`cyber_rodent.colony_baseline`) runs it on the
baseline bundle shipped in ``cyber_rodent/baseline/``. It must stay standalone: it imports only
the Python standard library and numpy (torch only when asked for, ``backend="torch"``), so a
robot's computer can run it, and a port to another language can be checked against the bundle's
recorded test vectors with it.

One step, for one robot (the simulator's ``EvolutionRunner.step`` for each robot):

1. proximity: the six proximity sensors (``proximity_sensors`` of the 8 range readings), as
   ``clip(1 - range / range_max, 0, 1)`` (larger = closer);
2. vision: per class (LED, face, battery) the nearest target's bearing (rad, robot frame, left
   positive), distance (m) and whether one is seen; normalised as ``clip((bearing + pi) / 2 pi,
   0, 1)`` (unseen: bearing 0) and ``clip(distance / max_distance, 0, 1)`` (unseen: 1);
3. controller inputs, one per entry of ``bundle.json`` ``controller.inputs`` in order, each
   computed from the observation it names (``energy``: energy / max_energy; ``proximity``: one
   of the six proximities; ``distance``: one class's normalised distance; ``constant``: its
   value; ``led_previous``: own LED at the previous step, 0 or 1); activations ``W (3 x n) @ x``;
   the available behaviour (Mate needs a face or LED in view, Forage a battery, Search always)
   with the largest activation wins, ties to the lower index; LED on iff activation(Mate) >
   activation(Forage);
4. recharge decision (used while docked): ``w0 energy / max_energy + w1 steps / max_recharge_steps
   + w2 <= 0`` means keep recharging; a robot that keeps recharging shows a dark LED;
5. the chosen behaviour's greedy policy maps its two inputs (Mate: the nearest LED if one is
   seen, else the nearest face, as (bearing, distance); Forage: the battery; Search: the largest
   and second largest proximity) to a wheel command index; ``commands`` gives the wheel rim
   speeds in m/s.

Step 5 has three implementations (``backend``), which give the same command for every input:

- ``"numpy"``: the tile-coded action values of ``behaviours.npz`` (``<name>_q``) indexed as
  ``behaviours.json`` describes (tilings, offsets, the ``lowbias32`` hash): the algorithm a
  port to another language follows;
- ``"table"``: the greedy tables of ``behaviours.npz`` (``<name>_greedy``), one lookup per step;
- ``"torch"``: the ``torch.export`` programs (``<name>.pt2``), with torch of the version in
  ``bundle.json`` ``torch.version``;
- ``"auto"`` (default): ``"numpy"`` if the bundle holds the action values, else ``"table"``.

The survival bookkeeping around this step (energy, recharging, the rotation reflex, time
sharing between the agents, the IR mating exchange) is the robot's own; the bundle's
``README.md`` gives it as pseudo-code with the run's numbers (``bundle.json`` ``survival``).

Usage::

    from reference_step import ReferenceController
    robot = ReferenceController("bundle_dir", agent=0)
    decision = robot.step(ranges=..., bearing=..., distance=..., visible=..., energy=...,
                          led_previous=..., docked=..., recharge_steps=...)

A robot running the bundle logs what it did in the form the simulator's system identification
reads (``cyber-rodent sysid``; columns :data:`LOG_COLUMNS`)::

    log = StepLog("run.csv", groups=("encoders", "ir", "led", "camera"), packs=[...])
    log.write_decision(step, t, robot_id, decision, ranges, bearing, distance, visible,
                       wheel_left=..., wheel_right=...)   # encoders, m/s
    log.close()

Every argument is checked: a wrong length, NaN or inf, or a value out of its range raises one
``ValueError`` naming the argument, what it must be and the value given.

Command line, in the bundle directory (exit status 0 on success, 1 on a mismatch, 2 on bad
use)::

    python reference_step.py --check                  # replay test_vectors.npz: PASS n/n
    python reference_step.py --check --backend all    # every backend installed
    python reference_step.py --check --log run.csv    # and write the steps as a run log
    python reference_step.py                          # what the bundle holds
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: Bundle format this file reads.
BUNDLE_FORMAT = 2
#: Format of the portable behaviours (``behaviours.json`` ``format``) this file reads.
PORTABLE_FORMAT = 1
MATE, FORAGE, SEARCH = 0, 1, 2
LED, FACE, BATTERY = 0, 1, 2
#: What a controller input may be computed from (``bundle.json`` ``controller.inputs``).
OBSERVATIONS = ("energy", "proximity", "distance", "constant", "led_previous")
#: The implementations of the behaviours (see the module docstring).
BACKENDS = ("auto", "numpy", "table", "torch")
#: What the test vectors' decisions hold, compared row by row by :func:`check_vectors`.
DECISION_FIELDS = ("behaviour", "led", "led_selection", "command", "continue_recharge")
#: Largest difference allowed between a recorded controller input and the recomputed one (the
#: simulator's compiled code may round the last bit differently).
INPUT_TOLERANCE = 1e-12
_MASK32 = 0xFFFFFFFF

# --- the run log (what a robot did, in the form ``cyber-rodent sysid`` reads) ------------------
#: First characters of a run log's first line; the rest of that line is a JSON object with the
#: schema ``version`` and the field (``field_size``, m; ``packs``, [[x, y], ...] m).
LOG_MARK = "# cyber-rodent-log "
#: Version of the log's columns; a reader refuses other versions.
LOG_VERSION = 1
#: The log's columns: name, unit, lowest and highest value, group. One row is one robot's
#: control step. A group's columns come all together or not at all; ``base`` is required.
#: An empty cell (NaN) is allowed only where its group's flag says the value is absent
#: (``x``, ``y``, ``yaw`` where ``tracked`` is 0; a camera class's bearing, distance and area
#: where its ``seen`` is 0).
LOG_COLUMNS: tuple[tuple[str, str, float, float, str], ...] = (
    ("step", "control steps", 0, 1e12, "base"),
    ("t", "s", 0.0, 1e9, "base"),
    ("robot", "index", 0, 199, "base"),
    ("cmd_left", "m/s", -1.3, 1.3, "base"),
    ("cmd_right", "m/s", -1.3, 1.3, "base"),
    ("wheel_left", "m/s", -5.0, 5.0, "encoders"),
    ("wheel_right", "m/s", -5.0, 5.0, "encoders"),
    ("tracked", "flag", 0, 1, "tracker"),
    ("x", "m", -50.0, 50.0, "tracker"),
    ("y", "m", -50.0, 50.0, "tracker"),
    ("yaw", "rad", -math.pi, math.pi, "tracker"),
    *((f"ir{i}", "m", 0.0, 10.0, "ir") for i in range(8)),
    ("led", "flag", 0, 1, "led"),
    *(
        (f"cam_{c}_{what}", unit, low, high, "camera")
        for c in ("led", "face", "battery")
        for what, unit, low, high in (
            ("seen", "flag", 0, 1),
            ("bearing", "rad", -math.pi, math.pi),
            ("distance", "m", 0.0, 100.0),
            ("area", "px", 0.0, 1e7),
        )
    ),
    ("energy", "energy units", 0.0, 1e9, "energy"),
    ("battery_v", "V", 0.0, 100.0, "battery"),
    ("docked", "flag", 0, 1, "events"),
    ("mated", "flag", 0, 1, "events"),
)
LOG_COLUMN_NAMES = tuple(c[0] for c in LOG_COLUMNS)


class StepLog:
    """Writes a run log (:data:`LOG_COLUMNS`) row by row; the file appears complete at
    :meth:`close` (written as ``PATH.partial`` and renamed), never half-written.

    A row is stored as numbers in a preallocated block of ``flush_rows`` rows (a full block is
    kept and a new one started) and the text is written at :meth:`close`, so a control step
    pays for a few array writes, not for text formatting.

    Args:
        path: the log file (``.csv``).
        groups: the column groups the robot records (``base`` always).
        field_size: side of the field, m.
        packs: the packs' (x, y), m.
        flush_rows: rows per stored block.
    """

    def __init__(
        self,
        path: str | Path,
        groups: tuple[str, ...] = ("base",),
        field_size: float = 2.3,
        packs: list[tuple[float, float]] | None = None,
        flush_rows: int = 1000,
    ) -> None:
        known = {c[4] for c in LOG_COLUMNS}
        unknown = [g for g in groups if g not in known]
        if unknown:
            raise ValueError(f"log groups must be among {', '.join(sorted(known))}, got {unknown}")
        chosen = [c for c in LOG_COLUMNS if c[4] == "base" or c[4] in groups]
        self.columns = [c[0] for c in chosen]
        self.index = {name: i for i, name in enumerate(self.columns)}
        #: columns written as integers: the step, the robot and the flags
        self._whole = [c[1] in ("control steps", "index", "flag") for c in chosen]
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        header = {"version": LOG_VERSION, "field_size": float(field_size),
                  "packs": [[float(x), float(y)] for x, y in (packs or [])]}  # fmt: skip
        self._file = open(self.partial, "w")  # noqa: SIM115 (closed by close())
        self._file.write(LOG_MARK + json.dumps(header) + "\n" + ",".join(self.columns) + "\n")
        self.flush_rows = int(flush_rows)
        self._blocks: list[np.ndarray] = []
        self._block = np.full((self.flush_rows, len(self.columns)), np.nan)
        self._rows = 0
        index = self.index
        self._ir = [index[f"ir{i}"] for i in range(8)] if "ir0" in index else None
        self._camera = (
            [[index[f"cam_{c}_{w}"] for w in ("seen", "bearing", "distance")]
             for c in ("led", "face", "battery")]
            if "cam_led_seen" in index else None
        )  # fmt: skip

    def _row(self) -> np.ndarray:
        """The next row of the current block (all NaN: a missing value is empty)."""
        if self._rows == self.flush_rows:
            self._blocks.append(self._block)
            self._block = np.full_like(self._block, np.nan)
            self._rows = 0
        row: np.ndarray = self._block[self._rows]
        self._rows += 1
        return row

    def write(self, **values: float) -> None:
        """One row: every column of the log's groups by name (missing ones are empty)."""
        row = self._row()
        index = self.index
        for name, value in values.items():
            row[index[name]] = value

    def write_decision(
        self, step: int, t: float, robot: int, decision: Decision, ranges: np.ndarray,
        bearing: np.ndarray, distance: np.ndarray, visible: np.ndarray, **measured: float,
    ) -> None:  # fmt: skip
        """A row from one :meth:`ReferenceController.step`: its inputs, its wheel command and
        LED, and what the robot measured (``measured``: encoders, tracker, energy...)."""
        row = self._row()
        index = self.index
        row[0], row[1], row[2] = step, t, robot  # the base columns come first
        row[3], row[4] = decision.wheels
        for name, value in measured.items():
            row[index[name]] = value
        if self._ir is not None:
            row[self._ir] = ranges
        if "led" in index:
            row[index["led"]] = decision.led
        if self._camera is not None:
            for c, (seen, at, far) in enumerate(self._camera):
                row[seen] = bool(visible[c])
                if visible[c]:
                    row[at], row[far] = bearing[c], distance[c]

    def close(self) -> Path:
        """Write the rows and give the file its name; returns the path."""
        whole = self._whole
        blocks = [*self._blocks, self._block[: self._rows]]
        for block in blocks:
            lines = (
                ",".join(
                    "" if v != v else str(int(v)) if whole[j] else repr(float(v))
                    for j, v in enumerate(row.tolist())
                )
                for row in block
            )
            text = "\n".join(lines)
            if text:
                self._file.write(text + "\n")
        self._blocks.clear()
        self._rows = 0
        self._file.close()
        self.partial.replace(self.path)
        return self.path


@dataclass(frozen=True)
class Decision:
    """What one control step decides for one robot.

    Attributes:
        behaviour: 0 Mate, 1 Forage, 2 Search.
        led: the LED the robot shows (dark while it keeps recharging).
        led_selection: the selection part's LED output (activation(Mate) > activation(Forage)).
        command: wheel command index.
        wheels: (left, right) wheel rim speeds, m/s.
        continue_recharge: the recharge part's decision (meaningful while docked).
        inputs: the controller inputs (``controller.input_order``).
        behaviour_input: the chosen behaviour's 2 inputs.
    """

    behaviour: int
    led: bool
    led_selection: bool
    command: int
    wheels: tuple[float, float]
    continue_recharge: bool
    inputs: np.ndarray
    behaviour_input: np.ndarray


# --- the behaviours ----------------------------------------------------------------------------
def mix32(x: int, multipliers: tuple[int, int] = (0x7FEB352D, 0x846CA68B)) -> int:
    """Wellons' ``lowbias32`` mixer of an unsigned 32-bit integer (``behaviours.json`` ``hash``):
    ``x ^= x >> 16; x *= m1; x ^= x >> 15; x *= m2; x ^= x >> 16``, every product mod 2**32."""
    x ^= x >> 16
    x = (x * multipliers[0]) & _MASK32
    x ^= x >> 15
    x = (x * multipliers[1]) & _MASK32
    return x ^ (x >> 16)


class TileCodedPolicy:
    """A behaviour's greedy policy from its tile-coded action values (``backend="numpy"``).

    Args:
        spec: the behaviour's entry of ``behaviours.json`` ``behaviours``.
        values: (table_size, n_actions) float64 action values (``<name>_q``).
        multipliers: the hash's two multipliers (``behaviours.json`` ``hash.multipliers``).
    """

    def __init__(self, spec: dict[str, Any], values: np.ndarray, multipliers: tuple[int, int]):
        self.scale = [float(s) for s in spec["scale"]]
        self.n_tilings = int(spec["n_tilings"])
        self.table_size = int(spec["table_size"])
        self.offsets = [[int(o) for o in row] for row in spec["offsets"]]
        self.coordinate_count = [int(c) for c in spec["coordinate_count"]]
        self.multipliers = multipliers
        seed = mix32(int(spec["seed"]), multipliers)
        self.tiling_hash = [mix32(seed ^ t, multipliers) for t in range(self.n_tilings)]
        if self.tiling_hash != [int(h) for h in spec["tiling_hash"]]:
            raise ValueError(f"behaviours.json: {spec['name']}: tiling_hash does not follow "
                             "from its seed")  # fmt: skip
        self.values = np.asarray(values, dtype=np.float64)
        if self.values.shape[0] != self.table_size:
            raise ValueError(
                f"behaviours.npz: {spec['name']}_q must have {self.table_size} rows, got "
                f"shape {self.values.shape}"
            )

    def rows(self, state: np.ndarray) -> list[int]:
        """The hashed table row of each tiling's active tile, in tiling order."""
        q = [math.floor(float(x) * s) for x, s in zip(state, self.scale, strict=True)]
        rows = []
        for t in range(self.n_tilings):
            h = self.tiling_hash[t]
            for d, count in enumerate(self.coordinate_count):
                coordinate = ((q[d] + self.offsets[t][d]) // self.n_tilings) % count
                h = mix32(h ^ coordinate, self.multipliers)
            rows.append(h % self.table_size)
        return rows

    def act(self, state: np.ndarray) -> int:
        """The greedy command: the tilings' rows added in tiling order, argmax (ties: lowest)."""
        rows = self.rows(state)
        q = self.values[rows[0]].copy()
        for row in rows[1:]:
            q += self.values[row]
        return int(np.argmax(q))


class GreedyTable:
    """A behaviour's greedy policy as one lookup (``backend="table"``): the command of every
    cell ``(floor(x0 * scale0), floor(x1 * scale1))``, computed from the action values."""

    def __init__(self, spec: dict[str, Any], table: np.ndarray) -> None:
        self.scale = [float(s) for s in spec["scale"]]
        self.table = np.asarray(table)
        expected = tuple(int(s) + 1 for s in self.scale)
        if self.table.shape != expected:
            raise ValueError(
                f"behaviours.npz: {spec['name']}_greedy must have shape {expected}, got "
                f"{self.table.shape}"
            )

    def act(self, state: np.ndarray) -> int:
        cell = tuple(math.floor(float(x) * s) for x, s in zip(state, self.scale, strict=True))
        return int(self.table[cell])


class TorchPolicy:
    """A behaviour's ``torch.export`` program (``backend="torch"``)."""

    def __init__(self, path: Path) -> None:
        try:
            import torch
        except ImportError as err:
            raise ValueError(
                "backend 'torch' needs torch (the version in bundle.json torch.version; the "
                "README's install commands); the numpy backends need none"
            ) from err
        self._torch = torch
        self.module = torch.export.load(path).module()

    def act(self, state: np.ndarray) -> int:
        with self._torch.no_grad():
            return int(self.module(self._torch.from_numpy(state[None, :]))[0])


def _backends_available(root: Path, spec: dict[str, Any]) -> list[str]:
    """The backends this bundle (and this installation) can run, in :data:`BACKENDS` order."""
    found = []
    portable = spec.get("portable")
    if portable and (root / portable["arrays"]).is_file():
        with np.load(root / portable["arrays"]) as arrays:
            names = spec["behaviours"]["order"]
            if all(f"{n}_q" in arrays.files for n in names):
                found.append("numpy")
            if all(f"{n}_greedy" in arrays.files for n in names):
                found.append("table")
    files = spec["behaviours"].get("files") or {}
    if files and all((root / f).is_file() for f in files.values()):
        try:
            import torch  # noqa: F401
        except ImportError:
            pass
        else:
            found.append("torch")
    return found


def load_behaviours(root: Path, spec: dict[str, Any], backend: str) -> tuple[str, list[Any]]:
    """The backend that runs (``"auto"`` resolved) and the three behaviours' policies (Mate,
    Forage, Search) of the bundle in ``root``.

    Raises:
        ValueError: an unknown backend, or one this bundle cannot run (the message says why).
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    names = spec["behaviours"]["order"]
    if backend == "torch":
        files = spec["behaviours"].get("files") or {}
        missing = [n for n in names if n not in files or not (root / files[n]).is_file()]
        if missing:
            raise ValueError(f"backend 'torch': this bundle has no .pt2 program of "
                             f"{', '.join(missing)}")  # fmt: skip
        return backend, [TorchPolicy(root / files[n]) for n in names]
    portable = spec.get("portable")
    if not portable or not (root / portable["arrays"]).is_file():
        raise ValueError(
            f"backend {backend!r}: this bundle has no portable behaviours (behaviours.json and "
            "behaviours.npz; bundles written before them run with backend 'torch')"
        )
    described = json.loads((root / portable["spec"]).read_text())
    if described.get("format") != PORTABLE_FORMAT:
        raise ValueError(f"behaviours.json format {described.get('format')!r} is not supported "
                         f"(this file reads {PORTABLE_FORMAT})")  # fmt: skip
    multipliers = tuple(int(m) for m in described["hash"]["multipliers"])
    assert len(multipliers) == 2
    specs = {b["name"]: b for b in described["behaviours"]}
    with np.load(root / portable["arrays"]) as arrays:
        have_values = all(f"{n}_q" in arrays.files for n in names)
        if backend == "auto":
            backend = "numpy" if have_values else "table"
        key = "q" if backend == "numpy" else "greedy"
        missing = [n for n in names if f"{n}_{key}" not in arrays.files]
        if missing:
            raise ValueError(f"backend {backend!r}: behaviours.npz has no {key} array of "
                             f"{', '.join(missing)}")  # fmt: skip
        if backend == "numpy":
            pair = (multipliers[0], multipliers[1])
            return backend, [TileCodedPolicy(specs[n], arrays[f"{n}_q"], pair) for n in names]
        return backend, [GreedyTable(specs[n], arrays[f"{n}_greedy"]) for n in names]


# --- checking the arguments ------------------------------------------------------------------
def _shown(value: Any) -> str:
    try:
        return repr(np.asarray(value).tolist())
    except Exception:  # pragma: no cover - whatever it is, say what it is
        return repr(value)


def _vector(name: str, value: Any, length: int, what: str) -> np.ndarray:
    """``value`` as a float64 vector of ``length``, else a ValueError naming ``name``."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != (length,):
        shape = "?" if array is None else array.shape
        raise ValueError(f"{name} must be {what}, shape ({length},); got shape {shape}: "
                         f"{_shown(value)}")  # fmt: skip
    return array


def _flags(name: str, value: Any, length: int) -> np.ndarray:
    array = np.asarray(value)
    ok = array.shape == (length,) and (
        array.dtype == np.bool_
        or (array.dtype.kind in "iuf" and bool(np.isin(array, (0, 1)).all()))
    )
    if not ok:
        raise ValueError(f"{name} must be {length} flags (bool, or 0 / 1), shape ({length},); "
                         f"got {_shown(value)}")  # fmt: skip
    return array.astype(bool)


def _flag(name: str, value: Any) -> bool:
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | float | np.integer | np.floating) and value in (0, 1):
        return bool(value)
    raise ValueError(f"{name} must be a flag (bool, or 0 / 1); got {value!r}")


def _number(name: str, value: Any, low: float, high: float, unit: str = "") -> float:
    real = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )
    number = float(value) if real else math.nan
    if not (math.isfinite(number) and low <= number <= high):
        raise ValueError(f"{name} must be a finite number in [{low:g}, {high:g}]{unit}; "
                         f"got {value!r}")  # fmt: skip
    return number


def _count(name: str, value: Any, low: int, high: int) -> int:
    whole = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
    if not (whole and low <= int(value) <= high):
        raise ValueError(f"{name} must be an integer in [{low}, {high}]; got {value!r}")
    return int(value)


class ReferenceController:
    """Loads a deployment bundle and runs the control step of one robot's agent.

    Args:
        bundle_dir: the bundle directory (``bundle.json``, ``controller_weights.npy``, the
            behaviours: ``behaviours.json`` and ``behaviours.npz``, or the ``.pt2`` programs).
        agent: row of ``controller_weights.npy`` to run (the bundle lists the individuals).
        backend: how the behaviours run: ``"auto"``, ``"numpy"``, ``"table"`` or ``"torch"``
            (the module docstring).

    Raises:
        ValueError: a bundle this file cannot read, a bad agent or backend.
    """

    def __init__(self, bundle_dir: str | Path, agent: int = 0, backend: str = "auto") -> None:
        root = Path(bundle_dir)
        if not (root / "bundle.json").is_file():
            raise ValueError(f"{root} holds no bundle.json: not a deployment bundle")
        self.root = root
        self.spec = json.loads((root / "bundle.json").read_text())
        if self.spec.get("format") != BUNDLE_FORMAT:
            raise ValueError(
                f"bundle format {self.spec.get('format')!r} is not supported (this file reads "
                f"{BUNDLE_FORMAT})"
            )
        self.all_weights = np.asarray(
            np.load(root / self.spec["controller"]["file"]), dtype=np.float64
        )
        norm = self.spec["normalisation"]
        self.max_energy = float(norm["max_energy"])
        self.max_recharge_steps = int(norm["max_recharge_steps"])
        self.max_distance = float(norm["max_distance"])
        self.n_ranges = len(norm["range_sensors"])
        self.proximity_sensors = np.asarray(norm["proximity_sensors"], dtype=np.intp)
        self.range_max = np.asarray(norm["range_max"], dtype=np.float64)
        self.commands = np.asarray(self.spec["commands"]["speeds"], dtype=np.float64)
        self.inputs = [
            (row["observation"], row["arg"], row["high"])
            for row in self.spec["controller"]["inputs"]
        ]
        for observation, _, _ in self.inputs:
            if observation not in OBSERVATIONS:
                raise ValueError(f"controller input observation {observation!r} is not known")
        self.use_agent(agent)
        #: The backend that runs the behaviours (``"auto"`` resolved).
        self.backend, self.policies = load_behaviours(root, self.spec, backend)

    def use_agent(self, agent: int) -> None:
        """Run the agent in row ``agent`` of the bundle's weights (time sharing)."""
        n = len(self.all_weights)
        if (
            not isinstance(agent, int | np.integer)
            or isinstance(agent, bool)
            or not (0 <= agent < n)
        ):
            raise ValueError(f"agent must be an integer in [0, {n - 1}], got {agent!r}")
        self.agent = int(agent)
        self.weights = self.all_weights[self.agent]
        recharge = self.spec["controller"]["recharge_weights"]
        selection = self.spec["controller"]["selection_weights"]
        self.w_recharge = self.weights[recharge[0] : recharge[1]]
        self.w_select = self.weights[selection[0] : selection[1]].reshape(3, len(self.inputs))

    def step(
        self,
        ranges: np.ndarray,
        bearing: np.ndarray,
        distance: np.ndarray,
        visible: np.ndarray,
        energy: float,
        led_previous: bool,
        docked: bool = False,
        recharge_steps: int = 0,
    ) -> Decision:
        """One control step (see the module docstring).

        Args:
            ranges: the 8 range readings, m, finite and >= 0 (sensor order of ``bundle.json``;
                a reading beyond a sensor's range counts as nothing in range).
            bearing: (3,) rad in [-pi, pi], nearest LED, face, battery (ignored where not
                visible: any value, e.g. the simulator's 0).
            distance: (3,) m, finite and >= 0 where visible (ignored where not: e.g. inf).
            visible: (3,) flags.
            energy: the agent's energy, in [0, max_energy].
            led_previous: the LED as it was lit during the previous step.
            docked: the robot is docked and recharging.
            recharge_steps: consecutive steps recharged so far, in [0, max_recharge_steps].

        Raises:
            ValueError: an argument of the wrong shape, NaN or inf, or out of its range (one
                line naming it, what it must be and the value).
        """
        ranges = _vector("ranges", ranges, self.n_ranges, "range readings in m, finite and >= 0")
        if not (np.isfinite(ranges).all() and (ranges >= 0.0).all()):
            raise ValueError(f"ranges must be {self.n_ranges} range readings in m, finite and "
                             f">= 0, shape ({self.n_ranges},); got {_shown(ranges)}")  # fmt: skip
        visible = _flags("visible", visible, 3)
        bearing = _vector("bearing", bearing, 3, "bearings in rad (LED, face, battery)")
        distance = _vector("distance", distance, 3, "distances in m (LED, face, battery)")
        seen_bearing, seen_distance = bearing[visible], distance[visible]
        if not (np.isfinite(seen_bearing).all() and (np.abs(seen_bearing) <= math.pi).all()):
            raise ValueError(
                "bearing must be 3 bearings in [-pi, pi] rad, finite where visible, shape (3,); "
                f"got {_shown(bearing)} (visible {_shown(visible)})"
            )
        if not (np.isfinite(seen_distance).all() and (seen_distance >= 0.0).all()):
            raise ValueError(
                "distance must be 3 distances in m, finite and >= 0 where visible, shape (3,); "
                f"got {_shown(distance)} (visible {_shown(visible)})"
            )
        energy = _number("energy", energy, 0.0, self.max_energy)
        led_previous = _flag("led_previous", led_previous)
        docked = _flag("docked", docked)
        recharge_steps = _count("recharge_steps", recharge_steps, 0, self.max_recharge_steps)

        proximity = np.clip(1.0 - ranges[self.proximity_sensors] / self.range_max, 0.0, 1.0)
        seen_b = np.where(visible, bearing, 0.0)
        seen_d = np.where(visible, distance, np.inf)
        nb = np.clip((seen_b + math.pi) / (2 * math.pi), 0.0, 1.0)
        nd = np.clip(seen_d / self.max_distance, 0.0, 1.0)
        x = np.empty(len(self.inputs))
        for column, (observation, arg, value) in enumerate(self.inputs):
            if observation == "energy":
                x[column] = energy / self.max_energy
            elif observation == "proximity":
                x[column] = proximity[arg]
            elif observation == "distance":
                x[column] = nd[arg]
            elif observation == "constant":
                x[column] = value
            else:  # led_previous
                x[column] = float(led_previous)
        activation = self.w_select @ x
        masked = activation.copy()
        if not (visible[LED] or visible[FACE]):
            masked[MATE] = -np.inf
        if not visible[BATTERY]:
            masked[FORAGE] = -np.inf
        behaviour = int(np.argmax(masked))
        led_selection = bool(activation[MATE] > activation[FORAGE])
        w = self.w_recharge
        out = energy / self.max_energy * w[0]
        out += w[1] * (float(recharge_steps) / self.max_recharge_steps)
        out += w[2]
        continue_recharge = bool(out <= 0.0)
        led = led_selection and not (docked and continue_recharge)
        if behaviour == MATE:
            target = LED if visible[LED] else FACE
            state = np.array([nb[target], nd[target]])
        elif behaviour == FORAGE:
            state = np.array([nb[BATTERY], nd[BATTERY]])
        else:
            ordered = np.sort(proximity)
            state = np.array([ordered[-1], ordered[-2]])
        command = self.policies[behaviour].act(state)
        left, right = self.commands[command]
        return Decision(
            behaviour=behaviour,
            led=led,
            led_selection=led_selection,
            command=command,
            wheels=(float(left), float(right)),
            continue_recharge=continue_recharge,
            inputs=x,
            behaviour_input=state,
        )


# --- the test vectors ------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckResult:
    """The outcome of replaying a bundle's test vectors (:func:`check_vectors`).

    Attributes:
        backend: the backend that ran.
        rows: rows replayed (all of them when passed, up to the first mismatch otherwise).
        total: rows in the file.
        mismatch: None when every row agreed, else one line naming the row and what differs.
    """

    backend: str
    rows: int
    total: int
    mismatch: str | None

    @property
    def passed(self) -> bool:
        return self.mismatch is None

    def line(self) -> str:
        if self.passed:
            return f"PASS {self.rows}/{self.total} (backend {self.backend})"
        return f"FAIL (backend {self.backend}) {self.mismatch}"


def check_vectors(
    bundle_dir: str | Path, backend: str = "auto", log: StepLog | None = None
) -> CheckResult:
    """Replay the bundle's test vectors (``bundle.json`` ``test_vectors``) through the step.

    Each row holds what one simulated robot observed in one control step and what the
    simulator decided; the row passes when the step decides the same behaviour, LED, selection
    LED, wheel command, wheel speeds and recharge decision and recomputes the controller inputs
    to within :data:`INPUT_TOLERANCE`. Stops at the first row that does not.

    With ``log``, every step is also written to it (:class:`StepLog`; time is the step
    number times the bundle's control step).

    Raises:
        ValueError: the bundle has no test vectors, or cannot run ``backend``.
    """
    root = Path(bundle_dir)
    robot = ReferenceController(root, backend=backend)
    described = robot.spec.get("test_vectors")
    if not described or not (root / described["file"]).is_file():
        raise ValueError(f"{root} holds no test vectors (bundle.json test_vectors)")
    name = robot.backend
    with np.load(root / described["file"]) as data:
        v = {k: data[k] for k in data.files}
    total = len(v["agent"])
    control_dt = float(robot.spec.get("survival", {}).get("control_dt", 0.2))
    for i in range(total):
        robot.use_agent(int(v["agent"][i]))
        where = f"row {i} (step {int(v['step'][i])}, robot {int(v['robot'][i])}, agent " \
                f"{int(v['agent'][i])})"  # fmt: skip
        try:
            d = robot.step(
                v["ranges"][i], v["bearing"][i], v["distance"][i], v["visible"][i],
                float(v["energy"][i]), bool(v["led_previous"][i]), bool(v["docked"][i]),
                int(v["recharge_steps"][i]),
            )  # fmt: skip
        except ValueError as err:
            return CheckResult(name, i, total, f"{where}: the step refused its input: {err}")
        if log is not None:
            step = int(v["step"][i])
            log.write_decision(
                step, step * control_dt, int(v["robot"][i]), d, v["ranges"][i], v["bearing"][i],
                v["distance"][i], v["visible"][i], energy=float(v["energy"][i]),
                docked=float(bool(v["docked"][i])),
            )  # fmt: skip
        for field in DECISION_FIELDS:
            expected, got = v[field][i].item(), getattr(d, field)
            if expected != got:
                return CheckResult(
                    name, i, total, f"{where}: {field} expected {expected!r}, got {got!r}"
                )
        if "wheels" in v and tuple(float(w) for w in v["wheels"][i]) != d.wheels:
            return CheckResult(name, i, total, f"{where}: wheels expected "
                               f"{_shown(v['wheels'][i])}, got {list(d.wheels)!r}")  # fmt: skip
        gap = float(np.max(np.abs(d.inputs - v["inputs"][i])))
        if not gap <= INPUT_TOLERANCE:
            detail = f"expected {_shown(v['inputs'][i])}, got {_shown(d.inputs)}"
            return CheckResult(
                name, i, total, f"{where}: controller inputs differ by {gap:.3g} ({detail})"
            )
    return CheckResult(name, total, total, None)


def main(argv: list[str] | None = None) -> int:
    """``python reference_step.py [--check] [--backend B] [--bundle DIR]`` (module docstring)."""
    here = Path(__file__).resolve().parent
    parser = argparse.ArgumentParser(
        prog="reference_step.py",
        description="One Cyber Rodent control step for a real robot. --check replays the "
        "bundle's recorded test vectors (simulator steps) and prints PASS n/n, or FAIL with "
        "the first mismatching row (exit status 1).",
    )
    parser.add_argument("--check", action="store_true", help="replay test_vectors.npz")
    parser.add_argument(
        "--backend", default="auto", choices=(*BACKENDS, "all"),
        help="how the behaviours run: numpy (tile coding, default when the bundle has the "
        "action values), table (greedy lookup), torch (the .pt2 programs; needs torch), all "
        "(every backend this bundle and installation can run)",
    )  # fmt: skip
    parser.add_argument("--bundle", default=str(here), metavar="DIR",
                        help="the bundle directory (default: this file's)")  # fmt: skip
    parser.add_argument("--log", default=None, metavar="FILE",
                        help="with --check: write every replayed step to FILE, a run log "
                        "(CSV; the format cyber-rodent sysid reads)")  # fmt: skip
    args = parser.parse_args(argv)
    root = Path(args.bundle)
    try:
        if not (root / "bundle.json").is_file():
            raise ValueError(f"{root} holds no bundle.json: pass --bundle DIR")
        spec = json.loads((root / "bundle.json").read_text())
        available = _backends_available(root, spec)
        if not args.check:
            vectors = (spec.get("test_vectors") or {}).get("rows", 0)
            print(f"bundle {root}: {spec['controller']['n_agents']} agents, backends available "
                  f"here: {', '.join(available) or 'none'}; {vectors} test vectors "
                  "(--check replays them)")  # fmt: skip
            return 0
        backends = available if args.backend == "all" else [args.backend]
        if not backends:
            raise ValueError("no backend can run this bundle here")
        if args.log is not None and not Path(args.log).parent.is_dir():
            raise ValueError(f"--log {args.log}: no such directory")
        log = None
        if args.log is not None:
            log = StepLog(args.log, ("led", "camera", "ir", "energy", "events"))
        results = [check_vectors(root, b, log if k == 0 else None)
                   for k, b in enumerate(backends)]  # fmt: skip
        if log is not None:
            print(f"wrote {log.close()}")
    except ValueError as err:
        print(f"reference_step.py: error: {err}", file=sys.stderr)
        return 2
    for result in results:
        print(result.line())
    return 0 if all(r.passed for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
