"""Sweeps over settings: the cells of a grid and where their runs live.

``cyber-rodent sweep --grid survival.reflex_max_steps=4,8,16 --grid
survival.mate_consecutive_steps=1,3`` runs every cell of the product (here 3 × 2) for every
method and seed. A cell is one combination of grid values; its runs live in
``<sweep>/<cell name>/<method>-seed<NNN>/`` and the sweep's ``grid.json`` lists the cells with
their settings (and the sweep's plugins, if it has any), so what a directory holds never has to
be parsed from its name. How cells
compare is :mod:`evolution.lab.cells`.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cyber_rodent.atomic import write_text
from cyber_rodent.plugins import PluginSource, plugin_records

GRID_FILE = "grid.json"

Grid = tuple[tuple[str, tuple[Any, ...]], ...]


@dataclass(frozen=True)
class Cell:
    """One combination of grid values, or one cell of a sweep's explicit cell list.

    Attributes:
        name: the directory name, e.g. ``reflex_max_steps=4,mate_consecutive_steps=1``.
        settings: the grid's values in this cell, by dotted key.
        methods: the methods this cell runs (a subset of the sweep's); empty: every method of
            the sweep. A grid's cells run every method; an explicit cell list
            (``SweepSpec.cell_list``) may leave some out.
    """

    name: str
    settings: Mapping[str, Any]
    methods: tuple[str, ...] = ()


def format_value(value: Any) -> str:
    """A setting's value as written in a cell name and on the command line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def cells(grid: Grid) -> tuple[Cell, ...]:
    """Every cell of ``grid`` (the product of its axes, in the order given).

    A cell is named by each axis's field name (the full dotted key where two axes share a
    field name) and value.
    """
    if not grid:
        return ()
    keys = [key for key, _ in grid]
    fields = [key.rpartition(".")[2] for key in keys]
    labels = [f if fields.count(f) == 1 else k for f, k in zip(fields, keys, strict=True)]
    found = []
    for combination in itertools.product(*(values for _, values in grid)):
        name = ",".join(
            f"{label}={format_value(v)}" for label, v in zip(labels, combination, strict=True)
        )
        found.append(Cell(name, dict(zip(keys, combination, strict=True))))
    return tuple(found)


def grid_record(grid: Grid, plugins: Sequence[PluginSource] = ()) -> dict[str, Any]:
    """The content of ``grid.json``; ``plugins``: the sweep's, recorded as ``plugins`` (name,
    kind, content hash) when there are any."""
    record: dict[str, Any] = {
        "grid": [[key, list(values)] for key, values in grid],
        "cells": [{"name": c.name, "settings": dict(c.settings)} for c in cells(grid)],
    }
    if plugins:
        record["plugins"] = plugin_records(plugins)
    return record


def read_grid(path: str | os.PathLike[str]) -> Grid | None:
    """The grid of the sweep at ``path`` (None if it is not a grid sweep).

    Raises:
        ValueError: ``grid.json`` is unreadable or not a grid record (the message names it).
    """
    file = Path(path) / GRID_FILE
    if not file.exists():
        return None
    try:
        record = json.loads(file.read_text())
        return tuple((str(key), tuple(values)) for key, values in record["grid"])
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{file}: not a grid record ({err})") from None


def check_grid(path: str | os.PathLike[str], grid: Grid) -> None:
    """Refuse to continue a sweep directory with a different grid than it was started with.

    Raises:
        ValueError: the directory's ``grid.json`` names another grid (or none where one is
            given, or one where none is given).
    """
    root = Path(path)
    if not root.is_dir():
        return
    existing = read_grid(root)
    holds_runs = any(p.is_dir() for p in root.iterdir())
    if existing is None and (not grid or not holds_runs):
        return
    if existing != grid:
        raise ValueError(
            f"{root} holds a sweep over another grid ({GRID_FILE}); use a new --out or the "
            "same --grid values"
        )


def write_grid(
    path: str | os.PathLike[str], grid: Grid, plugins: Sequence[PluginSource] = ()
) -> None:
    """Write ``grid.json`` (atomically) into the sweep directory."""
    record = grid_record(grid, plugins)
    write_text(Path(path) / GRID_FILE, json.dumps(record, indent=2, default=repr) + "\n")
