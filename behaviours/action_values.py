"""Learned action values on disk: a small versioned ``.npz`` with a SHA-256 checksum.

The paper saves the action values learned for each basic behaviour and reuses them unchanged for
the embodied evolution and on the hardware (§3.4, §5). We ship them as package data, so a file
must be self-describing (the tile coder that indexes it, the action names) and must fail loudly
when it is missing, truncated, edited or made by an incompatible version of this code: a silently
wrong Q table gives a robot that drives into walls, which is far harder to debug than an error.

File layout (``numpy.savez``, no pickled objects, loaded with ``allow_pickle=False``):

* ``weights``: float64 little-endian, shape (n_actions, table_size): the linear Q weights, one
  row per discrete action, indexed by the hashed tile features.
* ``header``: 0-d unicode array holding canonical JSON: ``format_version``, ``coder`` (the
  :class:`~behaviours.tile_coding.TileCoderConfig` incl. its hash version), ``n_actions``,
  ``action_names`` and free-form ``metadata`` (behaviour name, training seed, episodes, ...).
* ``sha256``: hex digest of ``header`` (UTF-8) + a NUL byte + the raw ``weights`` bytes.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from behaviours.tile_coding import TileCoder, TileCoderConfig
from cyber_rodent.atomic import atomic_output

#: Bump when the file layout or its meaning changes; older files are then rejected.
FORMAT_VERSION = 1
_REQUIRED_KEYS = ("weights", "header", "sha256")


class ActionValuesError(ValueError):
    """An action-values file cannot be used (base class; subclasses say why)."""


class CorruptActionValuesError(ActionValuesError):
    """The file is unreadable, incomplete, or its checksum does not match its content."""


class IncompatibleActionValuesError(ActionValuesError):
    """The file is intact but was made for another format, coder or action set."""


def values_checksum(header: str, weights: np.ndarray) -> str:
    """SHA-256 of a values file's header and its weights (little-endian float64)."""
    digest = hashlib.sha256(header.encode("utf-8"))
    digest.update(b"\0")
    digest.update(np.ascontiguousarray(weights, dtype="<f8").tobytes())
    return digest.hexdigest()


class ActionValues:
    """Linear tile-coded action values: weights plus everything needed to index them.

    Immutable once built: the weights are a read-only copy, so a policy built on them can never
    be changed behind its back (learners keep their own writable arrays and snapshot into this).

    Args:
        coder_config: the tile coder whose hashed indices address the weight columns.
        weights: (n_actions, table_size) float array.
        action_names: one name per row (e.g. the discrete wheel commands); default ``a0, a1..``.
        metadata: JSON-serialisable facts about how the values were made.

    Raises:
        ValueError: weights of the wrong shape, non-finite weights, or wrong number of names.
    """

    def __init__(
        self,
        coder_config: TileCoderConfig,
        weights: np.ndarray,
        action_names: tuple[str, ...] | None = None,
        metadata: dict[str, Any] | None = None,
    ) -> None:
        w = np.array(weights, dtype=np.float64, copy=True)
        if w.ndim != 2 or w.shape[0] < 1 or w.shape[1] != coder_config.table_size:
            raise ValueError(
                f"weights: expected shape (n_actions >= 1, table_size={coder_config.table_size}), "
                f"got {np.shape(weights)}"
            )
        if not np.isfinite(w).all():
            raise ValueError("weights: every action value must be finite (no NaN or inf)")
        names = tuple(f"a{i}" for i in range(w.shape[0])) if action_names is None else action_names
        if len(names) != w.shape[0] or not all(isinstance(n, str) for n in names):
            raise ValueError(
                f"action_names: need {w.shape[0]} strings (one per weight row), got {names!r}"
            )
        w.setflags(write=False)
        self.coder_config = coder_config
        self.weights = w
        self.action_names = tuple(names)
        self.metadata = dict(metadata or {})
        self._header = self._make_header()  # also proves the metadata is JSON-serialisable

    @property
    def n_actions(self) -> int:
        """Number of discrete actions (weight rows)."""
        return int(self.weights.shape[0])

    @property
    def checksum(self) -> str:
        """SHA-256 of the header and weights, as written to and verified from disk."""
        return values_checksum(self._header, self.weights)

    def make_coder(self) -> TileCoder:
        """A tile coder that produces this table's indices."""
        return TileCoder(self.coder_config)

    def _make_header(self) -> str:
        try:
            return json.dumps(
                {
                    "format_version": FORMAT_VERSION,
                    "coder": self.coder_config.to_dict(),
                    "n_actions": self.n_actions,
                    "action_names": list(self.action_names),
                    "metadata": self.metadata,
                },
                sort_keys=True,
                separators=(",", ":"),
            )
        except TypeError as err:
            raise ValueError(f"metadata: must be JSON-serialisable ({err})") from err

    def save(self, path: str | os.PathLike[str], compress: bool = False) -> Path:
        """Write the values atomically and return the path.

        Through :func:`cyber_rodent.atomic.atomic_output`: a crash mid-write never leaves a
        half-written file under the real name.

        Args:
            path: destination ``.npz``.
            compress: deflate the archive (``numpy.savez_compressed``); :meth:`load` reads both.
                Trained tables are mostly zeros (unvisited tiles), so this shrinks shipped files
                several-fold.
        """
        path = Path(path)
        if path.suffix != ".npz":
            raise ValueError(f"path: action values are saved as .npz, got {str(path)!r}")
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(path) as temp, open(temp, "wb") as fh:
            (np.savez_compressed if compress else np.savez)(
                fh,
                weights=self.weights.astype("<f8"),
                header=np.array(self._header),
                sha256=np.array(self.checksum),
            )
        return path

    @classmethod
    def load(
        cls,
        path: str | os.PathLike[str],
        *,
        expect_coder: TileCoderConfig | None = None,
        expect_n_actions: int | None = None,
    ) -> ActionValues:
        """Read and verify a values file.

        Args:
            path: the ``.npz`` file.
            expect_coder: if given, the file's coder config must equal it.
            expect_n_actions: if given, the file must have this many actions.

        Raises:
            FileNotFoundError: no file at ``path``.
            CorruptActionValuesError: unreadable, missing entries, bad JSON, checksum mismatch.
            IncompatibleActionValuesError: other format/hash version, coder or action count.
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"action values file not found: {path}")
        try:
            # Open the file ourselves: np.load leaks its handle when given a path it cannot parse.
            with open(path, "rb") as fh:
                data = np.load(fh, allow_pickle=False)
                if not isinstance(data, np.lib.npyio.NpzFile):
                    raise CorruptActionValuesError(f"{path}: not an .npz archive")
                missing = [k for k in _REQUIRED_KEYS if k not in data.files]
                if missing:
                    raise CorruptActionValuesError(
                        f"{path}: not an action-values file, missing entries {missing}"
                    )
                weights = np.array(data["weights"])
                header = str(data["header"][()])
                stored_sum = str(data["sha256"][()])
        except ActionValuesError:
            raise
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as err:
            raise CorruptActionValuesError(f"{path}: cannot read action values ({err})") from err
        if weights.dtype != np.dtype("<f8") or weights.ndim != 2:
            raise CorruptActionValuesError(
                f"{path}: weights must be a 2-D float64 array, got {weights.dtype} {weights.shape}"
            )
        if values_checksum(header, weights) != stored_sum:
            raise CorruptActionValuesError(
                f"{path}: SHA-256 checksum mismatch, the file is damaged or was edited"
            )
        try:
            info = json.loads(header)
            version = info["format_version"]
        except (ValueError, KeyError, TypeError) as err:
            raise CorruptActionValuesError(f"{path}: unreadable header ({err})") from err
        if version != FORMAT_VERSION:
            raise IncompatibleActionValuesError(
                f"{path}: format_version {version!r}, this code reads version {FORMAT_VERSION}"
            )
        try:
            coder = TileCoderConfig.from_dict(info["coder"])
        except ValueError as err:
            raise IncompatibleActionValuesError(f"{path}: {err}") from err
        except (KeyError, TypeError) as err:
            raise CorruptActionValuesError(f"{path}: bad coder description ({err})") from err
        if expect_coder is not None and coder != expect_coder:
            raise IncompatibleActionValuesError(
                f"{path}: coder {coder} differs from the expected {expect_coder}"
            )
        if expect_n_actions is not None and info["n_actions"] != expect_n_actions:
            raise IncompatibleActionValuesError(
                f"{path}: n_actions {info['n_actions']}, expected {expect_n_actions}"
            )
        try:
            return cls(coder, weights, tuple(info["action_names"]), info.get("metadata"))
        except ValueError as err:
            raise CorruptActionValuesError(f"{path}: {err}") from err
