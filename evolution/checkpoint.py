"""Atomic, verified checkpoints of explicit, versioned state; loading one never runs code.

A checkpoint stores *plain state*: nested dicts (string keys) and lists of JSON scalars (bool,
int of any size, such as a PCG64 generator's state, float, str, None) and numpy arrays of a
numeric or bool dtype. Objects turn themselves into plain state and back with their own
``state()`` / ``load_state()`` (or ``from_state()``) methods (docs/design.md §10); nothing in
the file names a class or a function, so a file, however crafted, can only ever yield numbers,
strings and arrays. The file is::

    MAGIC (8 bytes) | header length (4 bytes, big-endian) | header (JSON) | payload
    payload = document (UTF-8 JSON) | the arrays' bytes

The header names the format version, the kind of run, a fingerprint of its configuration, the
package and MuJoCo versions that wrote it, the document's and the payload's lengths and the
payload's SHA-256. The document is ``{"state": ..., "arrays": {name: {"dtype", "shape",
"offset"}}}``: in the state, an array is ``{"__array__": name}`` (its raw little-endian bytes
are at ``offset`` after the document) and a NaN or infinite float is ``{"__float__": "nan"}``
(``"inf"``, ``"-inf"``). Finite floats are written with Python's shortest round-trip repr, so
every number comes back bit for bit.

Loading checks the magic bytes, the format version, the lengths and the checksum, then parses
the document with a JSON parser and builds the arrays with ``numpy.frombuffer`` from a dtype
whitelist. A truncated, corrupt, incompatible or malformed file is rejected with a
:class:`CheckpointError` whose one-line message says which check failed; the file is never
modified. A file of the first format (a pickled payload) is recognised by its header and
refused without reading the payload.

Writing goes through :func:`cyber_rodent.atomic.atomic_output` (temporary file, fsync,
rename), so a process killed mid-write leaves the previous checkpoint intact.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import json
import math
import os
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from cyber_rodent import __version__ as CODE_VERSION
from cyber_rodent.atomic import atomic_output

MAGIC = b"CRCKPT\x00\x01"
#: Version of the file layout *and* of every state layout stored in it: bump it whenever a
#: ``state()`` method changes what it returns.
FORMAT_VERSION = 2
#: Array dtypes a checkpoint may hold (little-endian; bool and the fixed-size numbers).
ARRAY_DTYPES = frozenset(
    np.dtype(code).str
    for code in ("?", "<i1", "<i2", "<i4", "<i8", "<u1", "<u2", "<u4", "<u8", "<f4", "<f8")
)
_ARRAY_KEY = "__array__"
_FLOAT_KEY = "__float__"
_NON_FINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
_ALIGN = 8
_RESERVED = frozenset((_ARRAY_KEY, _FLOAT_KEY))


class CheckpointError(ValueError):
    """A checkpoint file is missing, truncated, corrupt, malformed or incompatible."""


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


# --- plain state <-> document + arrays ------------------------------------------------------
def _encode(value: Any, path: str, arrays: dict[str, np.ndarray]) -> Any:
    """``value`` with arrays replaced by references (collected in ``arrays``) and non-finite
    floats tagged; TypeError for anything that is not plain state."""
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        number = float(value)
        if math.isfinite(number):
            return number
        return {_FLOAT_KEY: "nan" if math.isnan(number) else "inf" if number > 0 else "-inf"}
    if isinstance(value, np.ndarray):
        if value.dtype.newbyteorder("<").str not in ARRAY_DTYPES:
            raise TypeError(f"{path}: arrays of dtype {value.dtype} cannot be checkpointed")
        name = path if path not in arrays else f"{path}~{len(arrays)}"
        arrays[name] = value
        return {_ARRAY_KEY: name}
    if isinstance(value, dict):
        encoded = {}
        for key, item in value.items():
            if not isinstance(key, str) or key in _RESERVED:
                raise TypeError(f"{path}: dict key {key!r} is not a plain-state key")
            encoded[key] = _encode(item, f"{path}/{key}" if path else key, arrays)
        return encoded
    if isinstance(value, list | tuple):
        return [_encode(item, f"{path}/{i}", arrays) for i, item in enumerate(value)]
    raise TypeError(f"{path}: {type(value).__name__} is not plain state")


def _payload(state: Any) -> tuple[bytes, list[bytes]]:
    """The document and the arrays' byte blocks (each padded to a multiple of 8 bytes)."""
    arrays: dict[str, np.ndarray] = {}
    tree = _encode(state, "", arrays)
    table: dict[str, dict[str, Any]] = {}
    blocks: list[bytes] = []
    offset = 0
    for name, array in arrays.items():
        little = np.asarray(array, dtype=array.dtype.newbyteorder("<"), order="C")
        data = little.tobytes()
        table[name] = {"dtype": little.dtype.str, "shape": list(little.shape), "offset": offset}
        blocks.append(data + bytes(-len(data) % _ALIGN))
        offset += len(blocks[-1])
    document = json.dumps({"state": tree, "arrays": table}, allow_nan=False)
    return document.encode(), blocks


def _array_table(table: object, data: memoryview) -> dict[str, np.ndarray]:
    """The arrays a document's table describes, checked against the whitelist and the bytes."""
    if not isinstance(table, dict):
        raise CheckpointError("malformed array table")
    arrays: dict[str, np.ndarray] = {}
    for name, entry in table.items():
        if not isinstance(entry, dict) or set(entry) != {"dtype", "shape", "offset"}:
            raise CheckpointError(f"array {name!r}: malformed entry")
        dtype, shape, offset = entry["dtype"], entry["shape"], entry["offset"]
        if not isinstance(dtype, str) or dtype not in ARRAY_DTYPES:
            raise CheckpointError(f"array {name!r}: dtype {dtype!r} is not allowed")
        if not (
            isinstance(shape, list)
            and all(type(n) is int and n >= 0 for n in shape)
            and type(offset) is int
            and offset >= 0
        ):
            raise CheckpointError(f"array {name!r}: malformed shape or offset")
        kind = np.dtype(dtype)
        count = math.prod(shape)
        if offset + count * kind.itemsize > len(data):
            raise CheckpointError(f"array {name!r} lies outside the payload")
        array = np.frombuffer(data, dtype=kind, count=count, offset=offset).reshape(shape)
        if kind == np.bool_ and np.frombuffer(data, np.uint8, count, offset).max(initial=0) > 1:
            raise CheckpointError(f"array {name!r}: bool values other than 0 and 1")
        arrays[name] = array.astype(kind.newbyteorder("="), copy=True)
    return arrays


def _decode(document: bytes, data: memoryview) -> Any:
    """The plain state of a document (references resolved)."""

    def no_constants(name: str) -> Any:
        raise CheckpointError(f"bare {name} in the document (non-finite floats are tagged)")

    if document.startswith(b"\x80"):  # a pickle's protocol opcode
        raise CheckpointError("the payload is a pickle, which is never loaded")
    try:
        parsed = json.loads(document, parse_constant=no_constants)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError, ValueError) as error:
        if isinstance(error, CheckpointError):
            raise
        raise CheckpointError(f"malformed document ({error})") from error
    if not isinstance(parsed, dict) or set(parsed) != {"state", "arrays"}:
        raise CheckpointError("malformed document (expected 'state' and 'arrays')")
    arrays = _array_table(parsed["arrays"], data)
    used: set[str] = set()

    def resolve(value: Any) -> Any:
        if isinstance(value, list):
            return [resolve(item) for item in value]
        if not isinstance(value, dict):
            return value
        if _ARRAY_KEY in value or _FLOAT_KEY in value:
            if len(value) != 1:
                raise CheckpointError(f"malformed reference {value!r}")
            if _FLOAT_KEY in value:
                tag = value[_FLOAT_KEY]
                if tag not in _NON_FINITE:
                    raise CheckpointError(f"unknown float tag {tag!r}")
                return _NON_FINITE[tag]
            name = value[_ARRAY_KEY]
            if not isinstance(name, str) or name not in arrays:
                raise CheckpointError(f"the document refers to a missing array {name!r}")
            if name in used:
                raise CheckpointError(f"array {name!r} is referred to twice")
            used.add(name)
            return arrays[name]
        return {key: resolve(item) for key, item in value.items()}

    try:
        return resolve(parsed["state"])
    except RecursionError as error:
        raise CheckpointError("malformed document (nested too deeply)") from error


# --- files ----------------------------------------------------------------------------------
def _installed_version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def save_checkpoint(
    path: str | os.PathLike[str], state: Any, *, kind: str, fingerprint: str
) -> None:
    """Write plain ``state`` to ``path`` atomically.

    Args:
        path: target file; its directory must exist.
        state: plain state (see the module docstring).
        kind: what the state is (e.g. ``"evolution-run-ee"``); checked at load.
        fingerprint: the run's :func:`config_fingerprint`; checked at load.

    Raises:
        TypeError: ``state`` holds something that is not plain state (nothing is written).
    """
    document, blocks = _payload(state)
    digest = hashlib.sha256(document)
    for block in blocks:
        digest.update(block)
    header = json.dumps(
        {
            "format_version": FORMAT_VERSION,
            "kind": kind,
            "fingerprint": fingerprint,
            "code_version": CODE_VERSION,
            "mujoco_version": _installed_version("mujoco"),
            "document_bytes": len(document),
            "payload_bytes": len(document) + sum(len(block) for block in blocks),
            "sha256": digest.hexdigest(),
        },
        sort_keys=True,
    ).encode()
    with atomic_output(path) as temp, open(temp, "wb") as handle:
        handle.write(MAGIC + len(header).to_bytes(4, "big") + header)
        handle.write(document)
        for block in blocks:
            handle.write(block)


def read_header(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The checkpoint's JSON header, after checking the magic bytes and the format version
    (the payload is not read).

    Raises:
        CheckpointError: missing file, not a checkpoint, or a format this version cannot read.
    """
    path = Path(path)
    with _open(path) as handle:
        header, _ = _read_header(handle, path)
    return header


def _open(path: Path) -> BinaryIO:
    try:
        return open(path, "rb")
    except FileNotFoundError as error:
        raise CheckpointError(f"{path}: checkpoint file not found") from error
    except IsADirectoryError as error:
        raise CheckpointError(f"{path}: is a directory, not a checkpoint file") from error


def _read_header(handle: BinaryIO, path: Path) -> tuple[dict[str, Any], int]:
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
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as error:
        raise CheckpointError(f"{path}: corrupt checkpoint header ({error})") from error
    if not isinstance(header, dict):
        raise CheckpointError(f"{path}: corrupt checkpoint header (not an object)")
    _check_version(header, path)
    return header, len(MAGIC) + 4 + size


def _check_version(header: dict[str, Any], path: Path) -> None:
    version = header.get("format_version")
    if version == FORMAT_VERSION:
        return
    if version == 1:
        raise CheckpointError(
            f"{path}: checkpoint format 1 (pickled objects) is no longer read; this version "
            f"reads format {FORMAT_VERSION} — re-run, or resume with cyber-rodent 0.1.0, which "
            "wrote it"
        )
    writer = header.get("code_version")
    by = f"cyber-rodent {writer}" if isinstance(writer, str) else "the release that wrote it"
    raise CheckpointError(
        f"{path}: checkpoint format {version!r} is not read by this version (cyber-rodent "
        f"{CODE_VERSION} reads format {FORMAT_VERSION}) — re-run, or resume with {by}"
    )


def load_checkpoint(
    path: str | os.PathLike[str],
    *,
    kind: str | None = None,
    fingerprint: str | None = None,
) -> Any:
    """Read, verify and decode a checkpoint written by :func:`save_checkpoint`.

    Args:
        path: the checkpoint file.
        kind: if given, the checkpoint's kind must match.
        fingerprint: if given, the checkpoint's config fingerprint must match.

    Returns:
        The plain state (lists where tuples were written; arrays writable, owned copies).

    Raises:
        CheckpointError: missing file, wrong magic, another format version, truncated or
            corrupt bytes (checksum), a different kind or config, or a malformed document (an
            unknown dtype, a reference to a missing array). The file is left untouched.
    """
    path = Path(path)
    with _open(path) as handle:
        header, _ = _read_header(handle, path)
        payload = handle.read()
    expected = header.get("payload_bytes")
    if len(payload) != expected:
        raise CheckpointError(
            f"{path}: truncated checkpoint ({len(payload)} of {expected} payload bytes)"
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
    split = header.get("document_bytes")
    if type(split) is not int or not 0 <= split <= len(payload):
        raise CheckpointError(f"{path}: corrupt checkpoint header (document_bytes)")
    view = memoryview(payload)
    try:
        return _decode(payload[:split], view[split:])
    except CheckpointError as error:
        raise CheckpointError(f"{path}: malformed checkpoint: {error}") from None


def restore_array(target: np.ndarray, value: object, name: str) -> None:
    """Copy a saved array into ``target`` in place (other objects hold views of it).

    Raises:
        ValueError: ``value`` is not an array of ``target``'s shape and dtype.
    """
    if not isinstance(value, np.ndarray):
        raise ValueError(f"{name}: expected an array, got {type(value).__name__}")
    if value.shape != target.shape or value.dtype != target.dtype:
        raise ValueError(
            f"{name}: saved {value.dtype}{list(value.shape)} does not fit "
            f"{target.dtype}{list(target.shape)}"
        )
    np.copyto(target, value)


__all__ = [
    "ARRAY_DTYPES",
    "FORMAT_VERSION",
    "MAGIC",
    "CheckpointError",
    "config_fingerprint",
    "load_checkpoint",
    "read_header",
    "restore_array",
    "save_checkpoint",
]
