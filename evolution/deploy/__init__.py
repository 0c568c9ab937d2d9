"""Deployment bundles: everything a real Cyber Rodent needs to run evolved agents.

A bundle is a directory:

- ``mate.pt2``, ``forage.pt2``, ``search.pt2``: the behaviours' greedy policies exported with
  ``torch.export`` (:mod:`behaviours.export`; float64 (batch, 2) inputs in [0, 1] → int64
  wheel command index);
- ``controller_weights.npy``: (n_agents, 39) float64 genomes of the agents to run (layout:
  recharge weights ``[0:3]``, selection weights ``[3:39]`` output-major);
- ``bundle.json``: format and package versions, the controller's input order, every
  normalisation constant (energy, recharge steps, vision distance, range-sensor ranges and
  which sensors are the six proximity sensors), the wheel command table, the behaviours' input
  definitions and the values' checksums, and where the agents came from;
- ``reference_step.py``: a plain-Python reference of one control step that loads the bundle with
  numpy and torch only (:mod:`evolution.deploy.reference_step`, copied verbatim).

:func:`record_decisions` records a simulated run's raw observations and decisions, which
``tests/test_deploy.py`` replays through the reference step to show that both decide alike.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from cyber_rodent.atomic import write_text
from evolution.genome import RECHARGE, SELECTION, Genome

#: Bundle layout version (``bundle.json`` ``format``); the reference step checks it.
BUNDLE_FORMAT = 1
BUNDLE_FILE = "bundle.json"
WEIGHTS_FILE = "controller_weights.npy"
REFERENCE_FILE = "reference_step.py"
_REFERENCE_SOURCE = Path(__file__).with_name(REFERENCE_FILE)


def _genome_matrix(genomes: Sequence[Genome] | np.ndarray) -> np.ndarray:
    from evolution.config import GENOME_LENGTH

    if isinstance(genomes, np.ndarray):
        matrix = np.asarray(genomes, dtype=np.float64)
    else:
        genomes = list(genomes)
        if not all(isinstance(g, Genome) for g in genomes):
            raise ValueError("genomes must be Genome objects or an (n, 39) array")
        matrix = np.stack([g.weights for g in genomes]) if genomes else np.zeros((0, 0))
    if matrix.ndim != 2 or matrix.shape[0] < 1 or matrix.shape[1] != GENOME_LENGTH:
        raise ValueError(
            f"genomes must be at least one genome of {GENOME_LENGTH} weights, got shape "
            f"{matrix.shape}"
        )
    if not np.isfinite(matrix).all():
        raise ValueError("genomes must have finite weights")
    return matrix


def write_bundle(
    out: str | os.PathLike[str],
    genomes: Sequence[Genome] | np.ndarray,
    *,
    values_dir: str | os.PathLike[str] | None = None,
    max_energy: float = 200.0,
    max_recharge_steps: int = 40,
    provenance: dict[str, Any] | None = None,
) -> Path:
    """Write a deployment bundle (see the module docstring) and return its directory.

    Args:
        out: the bundle directory (created; existing bundle files are replaced).
        genomes: the agents' controller weights, (n, 39) or Genome objects.
        values_dir: the behaviours' action values (default: the shipped ones).
        max_energy, max_recharge_steps: the controller's normalisation (paper: 200, 40).
        provenance: free-form description of where the agents came from (run, generation).

    Raises:
        ValueError: bad genomes or normalisation constants.
        FileNotFoundError: the behaviours' values are missing.
    """
    from behaviours.export import export_greedy_policy
    from behaviours.inputs import BEHAVIOUR_NAMES
    from cyber_rodent import constants as C
    from cyber_rodent.commands import COMMAND_SET_VERSION, WHEEL_COMMANDS
    from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE
    from evolution.controller import INPUT_NAMES

    matrix = _genome_matrix(genomes)
    if not (isinstance(max_energy, int | float) and max_energy > 0):
        raise ValueError(f"max_energy must be in (0, ∞), got {max_energy!r}")
    if isinstance(max_recharge_steps, bool) or not (
        isinstance(max_recharge_steps, int) and max_recharge_steps > 0
    ):
        raise ValueError(
            f"max_recharge_steps must be an integer in [1, ∞), got {max_recharge_steps!r}"
        )
    from behaviours.definitions import load_values

    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    files, checksums = {}, {}
    for name in BEHAVIOUR_NAMES:
        values = load_values(name, values_dir)
        path = export_greedy_policy(values, root / f"{name}.pt2")
        files[name] = path.name
        checksums[name] = values.checksum
    np.save(root / WEIGHTS_FILE, matrix)
    shutil.copyfile(_REFERENCE_SOURCE, root / REFERENCE_FILE)
    try:
        package_version = metadata.version("cyber-rodent")
    except metadata.PackageNotFoundError:  # pragma: no cover - editable installs have one
        package_version = None
    spec = {
        "format": BUNDLE_FORMAT,
        "package_version": package_version,
        "command_set_version": COMMAND_SET_VERSION,
        "controller": {
            "file": WEIGHTS_FILE,
            "n_agents": int(matrix.shape[0]),
            "weights_sha256": hashlib.sha256(matrix.tobytes()).hexdigest(),
            "input_order": list(INPUT_NAMES),
            "outputs": ["mate", "forage", "search"],
            "recharge_weights": [RECHARGE.start, RECHARGE.stop],
            "selection_weights": [SELECTION.start, SELECTION.stop],
            "selection_layout": "output-major (3, 12): row = output, column = input_order",
            "recharge_rule": "w0*energy/max_energy + w1*steps/max_recharge_steps + w2 <= 0: "
            "continue recharging",
            "led_rule": "on iff activation(mate) > activation(forage); dark while recharging",
        },
        "normalisation": {
            "max_energy": float(max_energy),
            "max_recharge_steps": int(max_recharge_steps),
            "max_distance": float(DEFAULT_MAX_DISTANCE),
            "range_sensors": [name for name, _, _ in C.RANGE_SENSORS],
            "range_max": [float(C.RANGE_SENSORS[i][2]) for i in C.PROXIMITY_SIX],
            "proximity_sensors": list(C.PROXIMITY_SIX),
            "proximity": "clip(1 - range / range_max, 0, 1)",
            "bearing": "clip((bearing_rad + pi) / (2 pi), 0, 1); unseen: bearing 0",
            "distance": "clip(distance_m / max_distance, 0, 1); unseen: 1",
        },
        "behaviours": {
            "order": list(BEHAVIOUR_NAMES),
            "files": files,
            "values_sha256": checksums,
            "inputs": {
                "mate": "(bearing, distance) of the nearest green LED if seen, else the nearest "
                "red face",
                "forage": "(bearing, distance) of the nearest blue battery pack",
                "search": "(largest, second largest) of the six proximity readings",
            },
        },
        "commands": {
            "names": [c.name for c in WHEEL_COMMANDS],
            "speeds": [[c.left, c.right] for c in WHEEL_COMMANDS],
            "unit": "wheel rim speed, m/s (left, right)",
        },
        "provenance": provenance or {},
    }
    write_text(root / BUNDLE_FILE, json.dumps(spec, indent=2, sort_keys=True, default=repr) + "\n")
    return root


def record_decisions(runner: Any, steps: int) -> dict[str, np.ndarray]:
    """Step ``runner`` (an :class:`~evolution.runner.EvolutionRunner`) and record, per step and
    robot, the raw observations the step used and the decisions it took.

    Returns:
        Arrays with a leading (steps, n_robots) shape: observations ``ranges`` (8),
        ``bearing``/``distance``/``visible`` (3), ``energy``, ``led_previous``, ``docked``,
        ``recharge_steps``, ``weights`` (39; the active agent's genome); decisions
        ``behaviour``, ``led`` (shown), ``led_selection``, ``command``, ``continue_recharge``
        and ``inputs`` (12).
    """
    survival, perception, action = runner.survival, runner.perception, runner.action
    keys = ("ranges", "bearing", "distance", "visible", "energy", "led_previous", "docked",
            "recharge_steps", "weights", "behaviour", "led", "led_selection", "command",
            "continue_recharge", "inputs")  # fmt: skip
    rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for _ in range(steps):
        controller = runner.controller
        before = {
            "energy": survival.energy.copy(),
            "led_previous": runner.world.led_on.copy(),
            "docked": survival.docked.copy(),
            "recharge_steps": survival.recharge_steps.copy(),
            "weights": controller.buffers.weights.copy(),
        }
        runner.step()
        for k, v in before.items():
            rows[k].append(v)
        nearest = perception.nearest
        rows["ranges"].append(perception.sensors.ranges.copy())
        rows["bearing"].append(nearest.bearing.copy())
        rows["distance"].append(nearest.distance.copy())
        rows["visible"].append(nearest.visible.copy())
        rows["behaviour"].append(controller.behaviour.copy())
        rows["led_selection"].append(controller.led.copy())
        rows["led"].append(action.led.copy())
        rows["command"].append(action.commands.copy())
        rows["continue_recharge"].append(controller.continue_recharge.copy())
        rows["inputs"].append(controller.buffers.inputs.copy())
    return {k: np.stack(v) for k, v in rows.items()}


__all__ = [
    "BUNDLE_FILE",
    "BUNDLE_FORMAT",
    "REFERENCE_FILE",
    "WEIGHTS_FILE",
    "record_decisions",
    "write_bundle",
]
