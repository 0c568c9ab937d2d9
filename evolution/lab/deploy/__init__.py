"""Deployment bundles: everything a real Cyber Rodent needs to run evolved agents.

A bundle is a directory:

- ``mate.pt2``, ``forage.pt2``, ``search.pt2``: the behaviours' greedy policies exported with
  ``torch.export`` (:mod:`behaviours.export`; float64 (batch, 2) inputs in [0, 1] → int64
  wheel command index);
- ``controller_weights.npy``: (n_agents, 39) float64 genomes of the agents to run (layout:
  recharge weights ``[0:3]``, selection weights ``[3:39]`` output-major; with more inputs in the
  input table, 3 more weights per input);
- ``bundle.json``: the control period, the robot frame and sign conventions, the sensors'
  geometry and units, every input's normalisation, the controller, the wheel command table, the
  exact torch version and the load call, the survival bookkeeping a robot runs itself (energy,
  recharging, reflex, time sharing, IR mating), how the agents were chosen and the run's whole
  resolved config (:mod:`evolution.lab.deploy.spec`);
- ``README.md``: the same for a reader, with runnable loading code and the bookkeeping as
  pseudo-code (:mod:`evolution.lab.deploy.readme`);
- ``reference_step.py``: a plain-Python reference of one control step that loads the bundle with
  numpy and torch only (:mod:`evolution.lab.deploy.reference_step`, copied verbatim).

A bundle is written into a temporary directory beside its destination and renamed into place,
so a failure never leaves a half-written bundle. :func:`record_decisions` records a simulated
run's raw observations and decisions, which ``tests/test_deploy.py`` replays through the
reference step to show that both decide alike.

A bundle holds the paper's controller (``evolution.controller = paper``) over inputs a robot
computes from its observations (each row of the input table states which); a run of another
controller, or with an input that states none, is refused with one line saying so
(:func:`~evolution.lab.deploy.spec.check_deployable`).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cyber_rodent.atomic import TEMP_MARK, write_text
from evolution.genome import Genome
from evolution.lab.deploy.readme import render_readme
from evolution.lab.deploy.spec import BUNDLE_FORMAT, bundle_spec, check_deployable
from evolution.runner.config import RunConfig

if TYPE_CHECKING:
    from behaviours.action_values import ActionValues
    from evolution.runner.config import RunConfig

BUNDLE_FILE = "bundle.json"
README_FILE = "README.md"
WEIGHTS_FILE = "controller_weights.npy"
REFERENCE_FILE = "reference_step.py"
_REFERENCE_SOURCE = Path(__file__).with_name(REFERENCE_FILE)


def _genome_matrix(genomes: Sequence[Genome] | np.ndarray, length: int) -> np.ndarray:

    if isinstance(genomes, np.ndarray):
        matrix = np.asarray(genomes, dtype=np.float64)
    else:
        genomes = list(genomes)
        if not all(isinstance(g, Genome) for g in genomes):
            raise ValueError(f"genomes must be Genome objects or an (n, {length}) array")
        matrix = np.stack([g.weights for g in genomes]) if genomes else np.zeros((0, 0))
    if matrix.ndim != 2 or matrix.shape[0] < 1 or matrix.shape[1] != length:
        raise ValueError(
            f"genomes must be at least one genome of {length} weights, got shape "
            f"{matrix.shape}"
        )
    if not np.isfinite(matrix).all():
        raise ValueError("genomes must have finite weights")
    return matrix


def check_bundle_dir(out: str | os.PathLike[str], option: str = "out") -> Path:
    """``out`` as a path a bundle may be written to, checked without touching the disk.

    A bundle goes to a new or empty directory, or replaces an earlier bundle (a directory with
    ``bundle.json``); anything else is refused, so no user file is ever deleted.

    Raises:
        ValueError: ``out`` is a file, or a non-empty directory that holds no bundle.
    """
    path = Path(out).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {path} is a file; it must be a new directory, an empty "
                         "one or an earlier bundle")  # fmt: skip
    if path.is_dir() and any(path.iterdir()) and not (path / BUNDLE_FILE).is_file():
        raise ValueError(
            f"{option} {path} is a non-empty directory without {BUNDLE_FILE}; it must be a "
            "new directory, an empty one or an earlier bundle"
        )
    return path


@contextlib.contextmanager
def staged_directory(target: Path) -> Iterator[Path]:
    """Yield a temporary directory beside ``target``; on success it replaces ``target``.

    The temporary is named like :mod:`cyber_rodent.atomic`'s temporaries; on any exception it
    is deleted and ``target`` is left as it was. An earlier ``target`` is moved aside, the new
    one renamed into place, and the old one deleted.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    temp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=TEMP_MARK, dir=target.parent))
    try:
        yield temp
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(temp, 0o777 & ~mask)  # mkdtemp makes it owner-only
        old = None
        if target.exists():
            old = temp.with_name(f"{temp.name}.old")
            os.replace(target, old)
        try:
            os.replace(temp, target)
        except BaseException:
            if old is not None:
                os.replace(old, target)
            raise
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def write_bundle(
    out: str | os.PathLike[str],
    genomes: Sequence[Genome] | np.ndarray,
    *,
    config: RunConfig | None = None,
    values: Mapping[str, ActionValues] | None = None,
    values_dir: str | os.PathLike[str] | None = None,
    selection: dict[str, Any] | None = None,
    provenance: dict[str, Any] | None = None,
) -> Path:
    """Write a deployment bundle (see the module docstring) and return its directory.

    Args:
        out: the bundle directory: new, empty, or an earlier bundle (replaced as a whole).
        genomes: the agents' controller weights, (n, 39) or Genome objects (39: the paper's
            controller over the paper's inputs).
        config: the run's resolved configuration; every number of the bundle comes from it
            (default: the paper's, ``RunConfig()``).
        values: the behaviours' action values by name (the run's own); default: loaded from
            ``values_dir``.
        values_dir: where to load the values from (default: the shipped ones).
        selection: how the agents were chosen (``bundle.json`` ``selection``).
        provenance: where the agents came from (run, checkpoint, per-agent records).

    Raises:
        ValueError: bad genomes, config or destination, or a controller or input a bundle
            cannot hold (nothing is written).
        FileNotFoundError: the behaviours' values are missing.
    """
    from behaviours.definitions import load_values
    from behaviours.export import export_greedy_policy
    from behaviours.inputs import BEHAVIOUR_NAMES

    if config is None:
        config = RunConfig()
    if not isinstance(config, RunConfig):
        raise ValueError(f"config must be a RunConfig, got {type(config).__name__}")
    matrix = _genome_matrix(genomes, check_deployable(config).length)
    root = check_bundle_dir(out)
    chosen = {
        name: values[name] if values is not None else load_values(name, values_dir)
        for name in BEHAVIOUR_NAMES
    }
    with staged_directory(root.absolute()) as temp:
        files, checksums = {}, {}
        for name, action_values in chosen.items():
            files[name] = export_greedy_policy(action_values, temp / f"{name}.pt2").name
            checksums[name] = action_values.checksum
        np.save(temp / WEIGHTS_FILE, matrix)
        shutil.copyfile(_REFERENCE_SOURCE, temp / REFERENCE_FILE)
        spec = bundle_spec(
            config, matrix, files, checksums, selection=selection, provenance=provenance
        )
        text = json.dumps(spec, indent=2, sort_keys=True, default=repr) + "\n"
        write_text(temp / BUNDLE_FILE, text)

        write_text(temp / README_FILE, render_readme(json.loads(text)))
    return root


def record_decisions(runner: Any, steps: int) -> dict[str, np.ndarray]:
    """Step ``runner`` (an :class:`~evolution.runner.EvolutionRunner`) and record, per step and
    robot, the raw observations the step used and the decisions it took.

    Returns:
        Arrays with a leading (steps, n_robots) shape: observations ``ranges`` (8),
        ``bearing``/``distance``/``visible`` (3), ``energy``, ``led_previous``, ``docked``,
        ``recharge_steps``, ``weights`` (39; the active agent's genome); decisions
        ``behaviour``, ``led`` (shown), ``led_selection``, ``command``, ``continue_recharge``
        and ``inputs`` (12; one per row of the input table).
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
    "README_FILE",
    "REFERENCE_FILE",
    "WEIGHTS_FILE",
    "check_bundle_dir",
    "record_decisions",
    "staged_directory",
    "write_bundle",
]
