"""The behaviours in a portable form: plain arrays and a JSON description, for ports to C.

The ``.pt2`` programs of :mod:`behaviours.export` need the torch version that wrote them. This
form needs nothing: ``behaviours.npz`` holds numpy arrays, ``behaviours.json`` says what they
are and how a step reads them, in words and pseudo-code, with every number a port needs:

- ``<name>_q``: float64 (table_size, n_actions), the tile-coded action values (row = hashed
  tile, column = wheel command), the same numbers as the shipped ``behaviours/data/<name>.npz``;
- ``<name>_greedy``: int8 (scale_0 + 1, scale_1 + 1), the greedy command of every input cell
  ``(floor(x0 * scale_0), floor(x1 * scale_1))``. The tile coder reads an input only through
  these two integers (:class:`~behaviours.tile_coding.TileCoder`), so the table is the greedy
  policy exactly, not an approximation: a port may run it instead of the tile coder.

``cyber_rodent/robot_step.py`` (a bundle's ``reference_step.py``) runs both (backends
``"numpy"`` and ``"table"``) and checks them against the simulator's recorded decisions; the
tests check both against :class:`~behaviours.greedy_policy.GreedyPolicy` on every cell.

The description follows :mod:`behaviours.tile_coding` (version :data:`HASH_VERSION`): change the
coder and its test fails before a port can drift from it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from behaviours.action_values import ActionValues
from behaviours.tile_coding import HASH_VERSION, MIX_MUL_1, MIX_MUL_2, TileCoder
from cyber_rodent.atomic import atomic_output, write_text

#: Version of this description (``behaviours.json`` ``format``).
PORTABLE_FORMAT = 1
SPEC_FILE = "behaviours.json"
ARRAYS_FILE = "behaviours.npz"

#: What each behaviour's two inputs are, normalised to [0, 1] (docs/design.md §5).
INPUTS = {
    "mate": ("bearing of the nearest green LED if one is seen, else of the nearest red face: "
             "clip((bearing_rad + pi) / (2 pi), 0, 1)",
             "its distance: clip(distance_m / max_distance, 0, 1)"),
    "forage": ("bearing of the nearest blue battery pack: clip((bearing_rad + pi) / (2 pi), 0, 1)",
               "its distance: clip(distance_m / max_distance, 0, 1)"),
    "search": ("the largest of the six proximities clip(1 - range_m / range_max_m, 0, 1)",
               "the second largest of them"),
}  # fmt: skip

ALGORITHM = [
    "Inputs: x[0], x[1] in [0, 1] (float64; anything else is a bug upstream).",
    "1. q[d] = floor(x[d] * scale[d]) for d = 0, 1 (float64 product, then floor to an integer; "
    "scale[d] = resolution[d] * n_tilings).",
    "2. For each tiling t = 0 .. n_tilings - 1, for each dimension d: "
    "c[t][d] = floor((q[d] + offsets[t][d]) / n_tilings) mod coordinate_count[d] (integer "
    "division; coordinate_count[d] = resolution[d] for a periodic (wrap) dimension, "
    "resolution[d] + 1 otherwise).",
    "3. For each tiling t: h = tiling_hash[t] (= mix32(mix32(seed) XOR t)); for d = 0, 1: "
    "h = mix32(h XOR c[t][d]); row[t] = h mod table_size.",
    "4. For each command a: Q[a] = q_table[row[0]][a] + q_table[row[1]][a] + ... + "
    "q_table[row[n_tilings - 1]][a], added in float64 in that order (tiling 0 first).",
    "5. command = the a with the largest Q[a]; ties go to the lowest a.",
    "Or, in one step: command = greedy[q[0]][q[1]] with q from step 1.",
]

PSEUDO_CODE = """\
uint32 mix32(uint32 x):            // Wellons' lowbias32; all arithmetic mod 2^32
    x ^= x >> 16;  x *= 0x7FEB352D
    x ^= x >> 15;  x *= 0x846CA68B
    x ^= x >> 16;  return x

int greedy_command(behaviour b, double x0, double x1):
    int q[2] = { floor(x0 * b.scale[0]), floor(x1 * b.scale[1]) }
    double Q[N_ACTIONS] = {0}
    for t in 0 .. b.n_tilings - 1:
        uint32 h = b.tiling_hash[t]
        for d in 0 .. 1:
            int c = floor_div(q[d] + b.offsets[t][d], b.n_tilings) mod b.coordinate_count[d]
            h = mix32(h ^ (uint32) c)
        int row = h mod b.table_size
        for a in 0 .. N_ACTIONS - 1:
            Q[a] += b.q_table[row][a]      // tiling order; float64
    return argmax(Q)                       // first (lowest) index on ties

int greedy_command_table(behaviour b, double x0, double x1):
    return b.greedy[floor(x0 * b.scale[0])][floor(x1 * b.scale[1])]
"""


def greedy_table(values: ActionValues) -> np.ndarray:
    """The greedy command of every input cell of ``values``' tile coder (module docstring).

    Returns:
        int8 array of shape ``scale + 1`` (scale = resolution x n_tilings per dimension): entry
        ``[q0, q1, ...]`` is the command that :class:`~behaviours.greedy_policy.GreedyPolicy`
        chooses for every input ``x`` with ``floor(x * scale) == q``.
    """
    coder = values.make_coder()
    config = values.coder_config
    cells = tuple(int(s) + 1 for s in coder.scale)
    q = np.stack(np.unravel_index(np.arange(int(np.prod(cells))), cells), axis=-1)
    coords = (q.astype(np.int64)[:, None, :] + coder.offsets[None, :, :]) // config.n_tilings
    coords %= coder.coordinate_count
    rows = coder._hash(coords)  # (cells, n_tilings): the hash the coder's indices use
    table = np.ascontiguousarray(values.weights.T)
    # Reduction over a non-innermost axis: numpy adds the tilings strictly in order, as
    # GreedyPolicy.q_values does.
    commands: np.ndarray = np.argmax(table[rows].sum(axis=-2), axis=-1)
    return commands.astype(np.int8).reshape(cells)


def behaviour_record(name: str, index: int, values: ActionValues) -> dict[str, Any]:
    """One behaviour's entry of ``behaviours.json``."""
    coder = TileCoder(values.coder_config)
    config = values.coder_config
    return {
        "name": name,
        "index": index,
        "inputs": list(INPUTS[name]),
        "resolution": list(config.resolution),
        "wrap": list(config.wrap),
        "n_tilings": config.n_tilings,
        "scale": [float(s) for s in coder.scale],
        "offsets": coder.offsets.tolist(),
        "coordinate_count": coder.coordinate_count.tolist(),
        "seed": config.seed,
        "tiling_hash": coder.tiling_hash.tolist(),
        "table_size": config.table_size,
        "n_actions": values.n_actions,
        "q": f"{name}_q",
        "greedy": f"{name}_greedy",
        "values_sha256": values.checksum,
    }


def portable_spec(
    values: Mapping[str, ActionValues],
    commands: Mapping[str, Any],
    max_distance: float,
    range_max: list[float],
) -> dict[str, Any]:
    """The ``behaviours.json`` record of ``values`` (behaviour name → values, in output order).

    Args:
        values: the behaviours' action values, Mate, Forage, Search.
        commands: the wheel command table (``names``, ``speeds``, ``unit``).
        max_distance: the distance normalised to 1, m.
        range_max: the six proximity sensors' ranges, m.
    """
    return {
        "format": PORTABLE_FORMAT,
        "hash_version": HASH_VERSION,
        "arrays": ARRAYS_FILE,
        "normalisation": {
            "bearing": "clip((bearing_rad + pi) / (2 pi), 0, 1); a target not seen: bearing 0 "
            "rad (0.5)",
            "distance": f"clip(distance_m / {max_distance:.6g}, 0, 1); a target not seen: 1",
            "max_distance_m": max_distance,
            "proximity": "clip(1 - range_m / range_max_m, 0, 1) for the six proximity sensors",
            "range_max_m": range_max,
            "domain": "every input must lie in [0, 1] (NaN never)",
        },
        "actions": {
            "names": list(commands["names"]),
            "speeds": [list(s) for s in commands["speeds"]],
            "unit": commands["unit"],
        },
        "hash": {
            "name": "lowbias32 (Chris Wellons), on unsigned 32-bit integers",
            "multipliers": [MIX_MUL_1, MIX_MUL_2],
            "multipliers_hex": [f"0x{MIX_MUL_1:08X}", f"0x{MIX_MUL_2:08X}"],
            "shifts": [16, 15, 16],
            "rule": "x ^= x >> 16; x = (x * multipliers[0]) mod 2^32; x ^= x >> 15; "
            "x = (x * multipliers[1]) mod 2^32; x ^= x >> 16",
        },
        "algorithm": ALGORITHM,
        "pseudo_code": PSEUDO_CODE,
        "arrays_layout": {
            "<name>_q": "float64 (table_size, n_actions): action value of each (hashed tile "
            "row, command)",
            "<name>_greedy": "int8 (scale[0] + 1, scale[1] + 1): the greedy command of each "
            "cell (floor(x0 * scale[0]), floor(x1 * scale[1])); equal to steps 1-5 for every "
            "input",
        },
        "behaviours": [
            behaviour_record(name, i, v) for i, (name, v) in enumerate(values.items())
        ],
    }


def write_portable(
    values: Mapping[str, ActionValues],
    out_dir: str | os.PathLike[str],
    commands: Mapping[str, Any],
    max_distance: float,
    range_max: list[float],
    *,
    action_values: bool = True,
) -> tuple[Path, Path]:
    """Write ``behaviours.json`` and ``behaviours.npz`` into ``out_dir``.

    Args:
        values, commands, max_distance, range_max: as :func:`portable_spec`'s.
        out_dir: an existing directory.
        action_values: write the ``<name>_q`` tables too (False: the greedy tables only, a
            few kB instead of 1.5 MB; the ``"table"`` backend runs them).

    Returns:
        The two paths written.
    """
    out = Path(out_dir)
    spec = portable_spec(values, commands, max_distance, range_max)
    arrays: dict[str, np.ndarray] = {}
    for name, v in values.items():
        if action_values:
            arrays[f"{name}_q"] = np.ascontiguousarray(v.weights.T, dtype="<f8")
        arrays[f"{name}_greedy"] = greedy_table(v)
    if not action_values:
        spec["arrays_layout"].pop("<name>_q")
        for record in spec["behaviours"]:
            record["q"] = None
    json_path = write_text(out / SPEC_FILE, json.dumps(spec, indent=2) + "\n")
    with atomic_output(out / ARRAYS_FILE) as temp, open(temp, "wb") as handle:
        np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]  # numpy's stubs
    return Path(json_path), out / ARRAYS_FILE


__all__ = [
    "ARRAYS_FILE",
    "PORTABLE_FORMAT",
    "SPEC_FILE",
    "behaviour_record",
    "greedy_table",
    "portable_spec",
    "write_portable",
]
