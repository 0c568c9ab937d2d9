"""Atomic, verified checkpoints of a run's full state.

A checkpoint holds whatever the runner needs to continue bit-identically (the scheduler with its
agents, spare lists, statistics and random generators; the physics state; the runner's own
counters), pickled into one payload. The file is::

    MAGIC (8 bytes) | header length (4 bytes, big-endian) | header (JSON) | payload

The JSON header names the format version, the kind of run, a fingerprint of the configuration,
the payload's length and its SHA-256. Loading checks all of them *before* unpickling, so a
truncated, corrupt or incompatible file is rejected with a :class:`CheckpointError` that says
which check failed, and the file is never modified.

Writing is atomic: the bytes go to a temporary file in the same directory, are flushed and
fsync'ed, and only then renamed over the target (``os.replace``, atomic on POSIX and Windows), so
a process killed mid-write leaves the previous checkpoint intact and at most a stray temporary
file, which :func:`save_checkpoint` ignores and :func:`remove_stale_temporaries` cleans.

Pickle runs code from the file it loads: load only checkpoints you (or your own runs) wrote. The
checksum guards against corruption, not against a malicious file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import pickle
import tempfile
from pathlib import Path
from typing import Any

MAGIC = b"CRCKPT\x00\x01"
FORMAT_VERSION = 1
_TEMP_SUFFIX = ".tmp-ckpt"


class CheckpointError(ValueError):
    """A checkpoint file is missing, truncated, corrupt or incompatible with this run."""


def config_fingerprint(config: Any) -> str:
    """A stable SHA-256 of a (nested) config dataclass's field values.

    Two configs with equal fields have the same fingerprint in every process and Python run
    (JSON of the fields with sorted keys; no ``hash()``), so a resumed run can prove it continues
    the same experiment.
    """
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        fields = dataclasses.asdict(config)
    else:
        fields = config
    text = json.dumps(fields, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def save_checkpoint(
    path: str | os.PathLike[str], state: Any, *, kind: str, fingerprint: str
) -> None:
    """Write ``state`` to ``path`` atomically.

    Args:
        path: target file; its directory must exist.
        state: any picklable object (the run's full state).
        kind: what the state is (e.g. ``"ee"`` or ``"ce"``); checked at load.
        fingerprint: the run's :func:`config_fingerprint`; checked at load.
    """
    path = Path(path)
    payload = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    header = json.dumps(
        {
            "format_version": FORMAT_VERSION,
            "kind": kind,
            "fingerprint": fingerprint,
            "payload_bytes": len(payload),
            "sha256": hashlib.sha256(payload).hexdigest(),
        },
        sort_keys=True,
    ).encode()
    fd, temp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=_TEMP_SUFFIX, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(MAGIC)
            handle.write(len(header).to_bytes(4, "big"))
            handle.write(header)
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temp_name, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temp_name)
        raise
    _fsync_directory(path.parent)


def _fsync_directory(directory: Path) -> None:
    """Make the rename durable (POSIX); a no-op where directories cannot be opened."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def read_header(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The checkpoint's JSON header, after checking the magic bytes (payload not read)."""
    with open(path, "rb") as handle:
        header, _ = _read_header(handle, Path(path))
    return header


def _read_header(handle: Any, path: Path) -> tuple[dict[str, Any], int]:
    magic = handle.read(len(MAGIC))
    if magic != MAGIC:
        raise CheckpointError(f"{path}: not a cyber-rodent checkpoint (bad magic bytes)")
    size_bytes = handle.read(4)
    if len(size_bytes) != 4:
        raise CheckpointError(f"{path}: truncated checkpoint (no header length)")
    size = int.from_bytes(size_bytes, "big")
    raw = handle.read(size)
    if len(raw) != size:
        raise CheckpointError(f"{path}: truncated checkpoint (header cut short)")
    try:
        header = json.loads(raw)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CheckpointError(f"{path}: corrupt checkpoint header ({error})") from error
    if not isinstance(header, dict):
        raise CheckpointError(f"{path}: corrupt checkpoint header (not an object)")
    return header, len(MAGIC) + 4 + size


def load_checkpoint(
    path: str | os.PathLike[str],
    *,
    kind: str | None = None,
    fingerprint: str | None = None,
) -> Any:
    """Read, verify and unpickle a checkpoint written by :func:`save_checkpoint`.

    Args:
        path: the checkpoint file.
        kind: if given, the checkpoint's kind must match.
        fingerprint: if given, the checkpoint's config fingerprint must match.

    Raises:
        CheckpointError: missing file, wrong magic, truncated or corrupt bytes (checksum), a
            different format version, kind or config. The file is left untouched.
    """
    path = Path(path)
    try:
        handle = open(path, "rb")  # noqa: SIM115 (closed below, errors re-raised as ours)
    except FileNotFoundError as error:
        raise CheckpointError(f"{path}: checkpoint file not found") from error
    with handle:
        header, _ = _read_header(handle, path)
        payload = handle.read()
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        raise CheckpointError(
            f"{path}: checkpoint format_version {version!r} is not supported "
            f"(this version reads {FORMAT_VERSION})"
        )
    if len(payload) != header.get("payload_bytes"):
        raise CheckpointError(
            f"{path}: truncated checkpoint ({len(payload)} of "
            f"{header.get('payload_bytes')} payload bytes)"
        )
    if hashlib.sha256(payload).hexdigest() != header.get("sha256"):
        raise CheckpointError(f"{path}: corrupt checkpoint (SHA-256 mismatch)")
    if kind is not None and header.get("kind") != kind:
        raise CheckpointError(
            f"{path}: checkpoint kind {header.get('kind')!r} does not match this run ({kind!r})"
        )
    if fingerprint is not None and header.get("fingerprint") != fingerprint:
        raise CheckpointError(
            f"{path}: checkpoint was written with a different configuration "
            "(config fingerprint mismatch)"
        )
    try:
        return pickle.loads(payload)
    except Exception as error:  # the checksum matched: the file is ours but unreadable here
        raise CheckpointError(
            f"{path}: checkpoint cannot be restored by this code version ({error!r})"
        ) from error


def remove_stale_temporaries(directory: str | os.PathLike[str]) -> list[Path]:
    """Delete temporary files left by writers that were killed mid-write; return them."""
    removed = []
    for candidate in Path(directory).glob(f".*{_TEMP_SUFFIX}"):
        with contextlib.suppress(OSError):
            candidate.unlink()
            removed.append(candidate)
    return removed
