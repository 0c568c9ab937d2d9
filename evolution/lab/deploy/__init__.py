"""Deployment bundles: everything a real Cyber Rodent needs to run evolved agents.

A bundle is a directory:

- ``behaviours.json`` and ``behaviours.npz``: the behaviours in a portable form, needing no
  torch (:mod:`behaviours.portable`): the tile-coded action values and the greedy table of each,
  with the tile coding (tilings, offsets, the hash's constants and algorithm in words and
  pseudo-code), the input normalisation and the wheel commands, for a port to another language;
- ``mate.pt2``, ``forage.pt2``, ``search.pt2``: the same greedy policies exported with
  ``torch.export`` (:mod:`behaviours.export`; float64 (batch, 2) inputs in [0, 1] → int64
  wheel command index), loaded with the exact torch version of ``bundle.json``;
- ``controller_weights.npy``: (n_agents, 39) float64 genomes of the agents to run (layout:
  recharge weights ``[0:3]``, selection weights ``[3:39]`` output-major; with more inputs in the
  input table, 3 more weights per input);
- ``test_vectors.npz``: a few hundred real simulator steps of the bundle's own agents, raw
  inputs → behaviour, LEDs, recharge decision, wheel command (:mod:`.vectors`);
- ``bundle.json``: the control period, the robot frame and sign conventions, the sensors'
  geometry and units, every input's normalisation, the controller, the wheel command table, the
  exact torch version and the load call, how to install and check, the survival bookkeeping a
  robot runs itself (energy, recharging, reflex, time sharing, IR mating), how the agents were
  chosen and the run's whole resolved config (:mod:`evolution.lab.deploy.spec`);
- ``README.md``: the same for a reader, with the install commands, runnable loading code and
  the bookkeeping as pseudo-code (:mod:`evolution.lab.deploy.readme`);
- ``reference_step.py``: one control step in plain numpy (torch optional), which loads the
  bundle and, with ``--check``, replays the test vectors: ``cyber_rodent/robot_step.py`` copied
  verbatim (the colony's baseline policy runs the same file).

A bundle is written into a temporary directory beside its destination and renamed into place,
so a failure never leaves a half-written bundle. :func:`record_decisions` records a simulated
run's raw observations and decisions; the bundle's test vectors are such a recording, and
``tests/test_deploy.py`` replays longer ones through the reference step to show that both
decide alike.

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

from cyber_rodent import robot_step
from cyber_rodent.atomic import TEMP_MARK, atomic_output, write_text
from evolution.genome import Genome
from evolution.lab.deploy.readme import render_readme
from evolution.lab.deploy.spec import BUNDLE_FORMAT, bundle_spec, check_deployable
from evolution.lab.deploy.vectors import (
    DEFAULT_STEPS,
    VECTORS_FILE,
    record_decisions,
    record_test_vectors,
)
from evolution.runner.config import RunConfig

if TYPE_CHECKING:
    from behaviours.action_values import ActionValues
    from evolution.runner.config import RunConfig

BUNDLE_FILE = "bundle.json"
README_FILE = "README.md"
WEIGHTS_FILE = "controller_weights.npy"
REFERENCE_FILE = "reference_step.py"
#: The file copied into every bundle as ``reference_step.py``.
REFERENCE_SOURCE = Path(robot_step.__file__)


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
    programs: bool = True,
    action_values: bool = True,
    vector_steps: int = DEFAULT_STEPS,
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
        programs: write the ``.pt2`` programs (needs torch; False: the portable form only).
        action_values: write the tile-coded action values into ``behaviours.npz`` (False:
            the greedy tables only, a few kB; the reference step's ``"table"`` backend).
        vector_steps: control steps of the recorded test vectors (>= 1).

    Raises:
        ValueError: bad genomes, config or destination, or a controller or input a bundle
            cannot hold (nothing is written).
        FileNotFoundError: the behaviours' values are missing.
    """
    from behaviours.definitions import load_values
    from behaviours.inputs import BEHAVIOUR_NAMES
    from behaviours.portable import write_portable

    if config is None:
        config = RunConfig()
    if not isinstance(config, RunConfig):
        raise ValueError(f"config must be a RunConfig, got {type(config).__name__}")
    matrix = _genome_matrix(genomes, check_deployable(config).length)
    root = check_bundle_dir(out)
    if isinstance(vector_steps, bool) or not isinstance(vector_steps, int) or vector_steps < 1:
        raise ValueError(f"vector_steps must be an integer >= 1, got {vector_steps!r}")
    chosen = {
        name: values[name] if values is not None else load_values(name, values_dir)
        for name in BEHAVIOUR_NAMES
    }
    vectors, vectors_record = record_test_vectors(config, matrix, chosen, steps=vector_steps)
    with staged_directory(root.absolute()) as temp:
        files = {}
        if programs:
            from behaviours.export import export_greedy_policy

            for name, v in chosen.items():
                files[name] = export_greedy_policy(v, temp / f"{name}.pt2").name
        checksums = {name: v.checksum for name, v in chosen.items()}
        np.save(temp / WEIGHTS_FILE, matrix)
        with atomic_output(temp / VECTORS_FILE) as staged, open(staged, "wb") as handle:
            np.savez_compressed(handle, **vectors)  # type: ignore[arg-type]  # numpy's stubs
        shutil.copyfile(REFERENCE_SOURCE, temp / REFERENCE_FILE)
        spec = bundle_spec(
            config, matrix, files, checksums, selection=selection, provenance=provenance,
            test_vectors=vectors_record, action_values=action_values,
        )  # fmt: skip
        norm = spec["normalisation"]
        write_portable(
            chosen, temp, spec["commands"], norm["max_distance"], norm["range_max"],
            action_values=action_values,
        )  # fmt: skip
        text = json.dumps(spec, indent=2, sort_keys=True, default=repr) + "\n"
        write_text(temp / BUNDLE_FILE, text)

        write_text(temp / README_FILE, render_readme(json.loads(text)))
    return root


__all__ = [
    "BUNDLE_FILE",
    "BUNDLE_FORMAT",
    "README_FILE",
    "REFERENCE_FILE",
    "REFERENCE_SOURCE",
    "VECTORS_FILE",
    "WEIGHTS_FILE",
    "check_bundle_dir",
    "record_decisions",
    "staged_directory",
    "write_bundle",
]
