"""Where the MJCF models live. The only module that resolves asset paths.

In an installed wheel the models ship inside the package (``cyber_rodent/_assets/mjcf``); in a
source checkout or editable install they sit at the repository root (``assets/mjcf``), the
user's layout. ``CYBER_RODENT_ASSETS`` points at another directory of models (a modified robot,
say) and takes precedence over both.
"""

from __future__ import annotations

import os
from pathlib import Path

ASSETS_ENV_VAR = "CYBER_RODENT_ASSETS"

_PACKAGE_DIR = Path(__file__).resolve().parent


class AssetNotFoundError(FileNotFoundError):
    """A model file the simulation needs is missing; the message names where we looked."""


def asset_dirs() -> list[Path]:
    """The directories searched for MJCF files, in order of precedence."""
    override = os.environ.get(ASSETS_ENV_VAR)
    if override:
        return [Path(override)]
    return [_PACKAGE_DIR / "_assets" / "mjcf", _PACKAGE_DIR.parent / "assets" / "mjcf"]


def asset_path(name: str) -> Path:
    """Absolute path of the MJCF file ``name``.

    Raises:
        AssetNotFoundError: if no searched directory holds ``name``.
    """
    dirs = asset_dirs()
    for directory in dirs:
        candidate = directory / name
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(d) for d in dirs)
    raise AssetNotFoundError(
        f"missing asset {name!r}: not found in {searched}"
        + (f" (set by ${ASSETS_ENV_VAR})" if os.environ.get(ASSETS_ENV_VAR) else "")
    )
