"""Atomic file output: a reader never sees a half-written file, a crash never leaves one.

Every file the package writes for a user (checkpoints, run tables, JSON records, figures,
images, videos, trained values, bundles) goes through :func:`atomic_output`: the content is
written to a temporary file in the target's directory, flushed and fsync'ed, given the
permissions of any new file under the user's umask (``mkstemp`` makes it owner-only), and
renamed over the target (``os.replace``, atomic within one directory on POSIX and Windows);
the directory entry is then fsync'ed too. A process killed mid-write leaves the previous file
intact and at most a stray temporary, which :func:`remove_stale_temporaries` deletes.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: Suffix of the temporaries (after the target's own suffix, which writers such as imageio and
#: matplotlib read to pick a format).
TEMP_MARK = ".partial"


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path`` atomically.

    The temporary keeps ``path``'s suffix (``.png``, ``.mp4``, ``.npz``) so that writers that
    choose a format by extension work unchanged. On any exception the temporary is deleted and
    ``path`` is left as it was.

    Args:
        path: the target; its directory must exist.
    """
    target = Path(path)
    fd, name = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=f"{TEMP_MARK}{target.suffix}", dir=target.parent
    )
    os.close(fd)
    temp = Path(name)
    try:
        yield temp
        with open(temp, "rb+") as handle:
            os.fsync(handle.fileno())
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(temp, 0o666 & ~mask)
        os.replace(temp, target)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise
    _fsync_directory(target.parent)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_output(path) as temp:
        temp.write_bytes(data)
    return Path(path)


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def write_json(path: str | os.PathLike[str], record: Any) -> Path:
    """Write ``record`` as indented JSON (sorted keys, trailing newline) atomically."""
    return write_text(path, json.dumps(record, indent=2, sort_keys=True) + "\n")


def remove_stale_temporaries(directory: str | os.PathLike[str]) -> list[Path]:
    """Delete temporaries left in ``directory`` by writers killed mid-write; return them."""
    removed = []
    for candidate in Path(directory).glob(f".*{TEMP_MARK}*"):
        with contextlib.suppress(OSError):
            candidate.unlink()
            removed.append(candidate)
    return removed


def _fsync_directory(directory: Path) -> None:
    """Make a rename durable (POSIX); a no-op where directories cannot be opened."""
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


__all__ = [
    "TEMP_MARK",
    "atomic_output",
    "remove_stale_temporaries",
    "write_bytes",
    "write_json",
    "write_text",
]
