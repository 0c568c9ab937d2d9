"""The three learned behaviours: their tile coders, action set and shipped action values.

One :class:`BehaviourSpec` per behaviour fixes everything that a saved action-value table
depends on: the input mapping (:mod:`behaviours.inputs`, version ``INPUTS_VERSION``), the tile
coder that indexes the weights, and the discrete wheel commands (:mod:`cyber_rodent.commands`,
version ``COMMAND_SET_VERSION``). Loading a table checks all of them, so a table trained for
another coder, input mapping or command set fails loudly instead of driving a robot into walls.

Tile coders (8 tilings each; the paper gives no numbers):

* **Mate, Forage**: ``[bearing, distance]``; bearing periodic with 24 tiles (15° wide, so with 8
  offset tilings the policy resolves about 2°, finer than the ±15° that docking and the IR
  exchange tolerate), distance 12 tiles of 0.27 m (resolving about 3.4 cm near the target).
* **Search**: ``[largest, second largest]`` proximity, 10 × 10 tiles, not periodic.

Hash tables of 8192 entries keep collisions between the ≤ 2,600 reachable tiles rare; a table is
8 actions × 8192 float64 = 512 KiB before compression.

Shipped values live in ``behaviours/data/<name>.npz`` (package data, in the wheel). Each file
carries the format version, a SHA-256 checksum (:mod:`behaviours.action_values`) and metadata:
the behaviour, :data:`VALUES_VERSION`, the input and command-set versions, and how it was
trained (seed, episodes).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from behaviours.action_values import ActionValues, IncompatibleActionValuesError
from behaviours.inputs import BEHAVIOUR_NAMES, FORAGE, INPUTS_VERSION, MATE, SEARCH
from behaviours.tile_coding import TileCoderConfig
from cyber_rodent.commands import COMMAND_NAMES, COMMAND_SET_VERSION, N_COMMANDS

#: Version of the shipped action values (bump when retraining changes what is shipped).
VALUES_VERSION = 1
#: Environment variable that points :func:`default_values_dir` somewhere else (tests, users
#: who keep their own trained values).
VALUES_DIR_ENV_VAR = "CYBER_RODENT_BEHAVIOUR_VALUES"


@dataclass(frozen=True)
class BehaviourSpec:
    """What defines one learned behaviour.

    Attributes:
        name: ``"mate"``, ``"forage"`` or ``"search"``.
        index: its behaviour index (the controller's output order).
        coder: the tile coder of its Q table.
        input_names: meaning of its two input dimensions.
        episodes: training episodes of a full run (what the shipped values were trained with);
            the episodes themselves are the task of the same name
            (:func:`cyber_rodent.tasks.spec.task_spec`).
    """

    name: str
    index: int
    coder: TileCoderConfig
    input_names: tuple[str, str]
    episodes: int


#: Mate's and Forage's coder, each with its own hash seed.
_TARGET_CODER = TileCoderConfig(
    resolution=(24, 12), n_tilings=8, table_size=8192, wrap=(True, False)
)

SPECS: tuple[BehaviourSpec, ...] = (
    BehaviourSpec(
        "mate",
        MATE,
        dataclasses.replace(_TARGET_CODER, seed=MATE + 1),
        ("bearing of the nearest LED (else face)", "distance of the nearest LED (else face)"),
        2000,
    ),
    BehaviourSpec(
        "forage",
        FORAGE,
        dataclasses.replace(_TARGET_CODER, seed=FORAGE + 1),
        ("bearing of the nearest pack", "distance of the nearest pack"),
        2000,
    ),
    BehaviourSpec(
        "search",
        SEARCH,
        TileCoderConfig(resolution=(10, 10), n_tilings=8, table_size=8192, seed=SEARCH + 1),
        ("largest proximity", "second largest proximity"),
        1500,
    ),
)
assert tuple(s.name for s in SPECS) == BEHAVIOUR_NAMES


def spec(name: str) -> BehaviourSpec:
    """The spec of behaviour ``name``.

    Raises:
        ValueError: for an unknown name (the message lists the allowed ones).
    """
    for s in SPECS:
        if s.name == name:
            return s
    raise ValueError(
        f"behaviour: unknown behaviour {name!r}; allowed: {', '.join(BEHAVIOUR_NAMES)}"
    )


def values_metadata(name: str, **training: object) -> dict[str, object]:
    """Metadata stored with a behaviour's trained values (checked when loading)."""
    return {
        "behaviour": name,
        "values_version": VALUES_VERSION,
        "inputs_version": INPUTS_VERSION,
        "command_set_version": COMMAND_SET_VERSION,
        **training,
    }


def default_values_dir() -> Path:
    """Where the shipped values live: ``behaviours/data``, or ``$CYBER_RODENT_BEHAVIOUR_VALUES``."""
    override = os.environ.get(VALUES_DIR_ENV_VAR)
    if override:
        return Path(override)
    return Path(str(resources.files("behaviours") / "data"))


def values_path(name: str, directory: str | os.PathLike[str] | None = None) -> Path:
    """Path of behaviour ``name``'s values file in ``directory`` (default: the shipped ones)."""
    spec(name)
    return Path(directory if directory is not None else default_values_dir()) / f"{name}.npz"


def load_values(name: str, directory: str | os.PathLike[str] | None = None) -> ActionValues:
    """Load and verify behaviour ``name``'s trained action values.

    Args:
        name: the behaviour.
        directory: where ``<name>.npz`` lives; default the shipped package data.

    Raises:
        ValueError: unknown behaviour name.
        FileNotFoundError: the file is missing (the message says how to make it).
        CorruptActionValuesError: unreadable or checksum mismatch.
        IncompatibleActionValuesError: made for another coder, command set, input mapping or
            behaviour.
    """
    s = spec(name)
    path = values_path(name, directory)
    if not path.is_file():
        raise FileNotFoundError(
            f"action values of behaviour {name!r} not found: {path} (reinstall the package, or "
            f"train them with `cyber-rodent train-behaviours --behaviour {name}`)"
        )
    values = ActionValues.load(path, expect_coder=s.coder, expect_n_actions=N_COMMANDS)
    check_compatible(values, name, path)
    return values


def check_compatible(values: ActionValues, name: str, where: object = "values") -> None:
    """Raise :class:`IncompatibleActionValuesError` unless ``values`` fit behaviour ``name``."""
    meta = values.metadata
    expected = {
        "behaviour": name,
        "inputs_version": INPUTS_VERSION,
        "command_set_version": COMMAND_SET_VERSION,
    }
    for key, want in expected.items():
        if meta.get(key) != want:
            raise IncompatibleActionValuesError(
                f"{where}: {key} is {meta.get(key)!r}, behaviour {name!r} of this code needs "
                f"{want!r}"
            )
    if tuple(values.action_names) != COMMAND_NAMES:
        raise IncompatibleActionValuesError(
            f"{where}: actions {values.action_names} differ from the wheel commands {COMMAND_NAMES}"
        )
