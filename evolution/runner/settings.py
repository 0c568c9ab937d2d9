"""Every setting of a run under one dotted key: the language of ``--set``, ``--config``,
``--grid`` and ``cyber-rodent config``.

A run is described by a :class:`~evolution.runner.RunConfig`, a tree of frozen config
dataclasses. Each scalar field of that tree is one key, named by its section and field:

- ``evolution.<field>``: :class:`~evolution.config.EvolutionConfig` (paper Table 1);
- ``genetic.<field>``: :class:`~evolution.config.GeneticConfig` (paper Table 2);
- ``learning.<field>``: :class:`~evolution.config.LearningConfig` (learning mode);
- ``reproduction.<field>``: :class:`~evolution.config.ReproductionConfig` (its variants);
- ``survival.<field>``: :class:`~cyber_rodent.survival.SurvivalConfig` (the world's rules);
- ``world.<field>``: :class:`~cyber_rodent.world.WorldConfig` (the field and its physics);
- ``camera.<field>``, ``camera.noise.<field>``, ``camera.led.<field>``, ...:
  :class:`~cyber_rodent.vision.CameraConfig` and its parts;
- ``vision``: the vision provider.

The keys are derived from the dataclasses themselves, so a new config field is a new key with
no further code: its type and allowed range come from its validation rule, its meaning from
the ``Attributes`` section of its class docstring, its unit and source from the rule's metadata
(:mod:`cyber_rodent.validation`).

The flat names of earlier versions (``population_size``, ``n_packs``, ``vision``, ...) still
work: each names one dotted key (:data:`FLAT_KEYS`). Four numbers live in two sections because
both the world and the evolution need them (``initial_energy``, ``max_energy``,
``max_recharge_steps`` and the robot count): either key sets both, so a run can never hold two
values of one number.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import math
import os
import re
import textwrap
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cyber_rodent.validation import (
    RULE,
    SOURCE,
    UNIT,
    BooleanRule,
    ChoiceRule,
    IntegerRule,
    NumberRule,
)
from evolution.runner.config import RunConfig

#: Section prefix → (attribute path from the RunConfig, default source of its fields).
SECTIONS: dict[str, tuple[tuple[str, ...], str]] = {
    "evolution": (("evolution",), "paper Table 1"),
    "genetic": (("evolution", "genetics"), "paper Table 2"),
    "learning": (("evolution", "learning"), "docs/design.md §11"),
    "reproduction": (("evolution", "reproduction"), "docs/design.md §9.27"),
    "ctrnn": (("evolution", "ctrnn"), "docs/design.md §9.31"),
    "medea": (("evolution", "medea"), "docs/design.md §9.34"),
    "survival": (("survival",), "docs/design.md §9"),
    "world": (("world",), "docs/design.md §9"),
    "camera": (("camera",), "docs/design.md §6"),
}
#: Keys that name another key's number: setting either sets both.
SHARED_KEYS = {
    "survival.initial_energy": "evolution.initial_energy",
    "survival.max_energy": "evolution.max_energy",
    "survival.max_recharge_steps": "evolution.max_recharge_steps",
    "world.n_robots": "evolution.n_robots",
}
#: Fields of a section that are not settings (nested configs are reached through their keys).
_NOT_SETTINGS: dict[tuple[str, ...], set[str]] = {
    ("evolution",): {"genetics", "learning", "reproduction", "ctrnn", "medea"}
}


@dataclass(frozen=True)
class Setting:
    """One settable field of a run's configuration.

    Attributes:
        key: the dotted key, e.g. ``survival.mate_distance``.
        path: attribute path from the :class:`RunConfig` to the field.
        kind: the value's Python type (``int``, ``float``, ``bool``, ``str`` or ``tuple``).
        default: the value in the default configuration.
        allowed: the allowed values in words ("number in (0, 3.39]"), "" if unchecked here.
        meaning: what the field means, from its class docstring.
        unit: the field's unit, "" if it has none.
        source: the paper's table or section, or the design section that argues the default.
    """

    key: str
    path: tuple[str, ...]
    kind: type
    default: Any
    allowed: str
    meaning: str
    unit: str
    source: str


def _attribute_docs(cls: type) -> dict[str, str]:
    """Field name → its description in the ``Attributes:`` section of ``cls``'s docstring."""
    doc = textwrap.dedent("\n".join((cls.__doc__ or "").splitlines()[1:]))
    docs: dict[str, str] = {}
    inside = False
    names: list[str] = []
    for line in doc.splitlines():
        if line.strip() == "Attributes:":
            inside = True
            continue
        if not inside:
            continue
        if line.strip() and not line.startswith(" "):
            break  # the next section
        match = re.match(r"^    ([a-z_][a-z0-9_, ]*):\s*(.*)$", line)
        if match:
            names = [n.strip() for n in match.group(1).split(",")]
            for name in names:
                docs[name] = match.group(2).strip()
        elif line.strip() and names:
            for name in names:
                docs[name] += " " + line.strip()
    return docs


def _kind(value: Any, rule: object) -> type:
    if isinstance(rule, IntegerRule):
        return int
    if isinstance(rule, NumberRule):
        return float
    if isinstance(rule, BooleanRule):
        return bool
    if isinstance(rule, ChoiceRule):
        return type(rule.choices[0])
    return type(value)


def _settings_of(config: Any, prefix: str, path: tuple[str, ...], source: str) -> Iterator[Setting]:
    docs = _attribute_docs(type(config))
    skip = _NOT_SETTINGS.get(path, set())
    for f in dataclasses.fields(config):
        if f.name in skip:
            continue
        value = getattr(config, f.name)
        key = f"{prefix}.{f.name}" if prefix else f.name
        if dataclasses.is_dataclass(value):
            yield from _settings_of(value, key, (*path, f.name), source)
            continue
        if value is None or not isinstance(value, int | float | str | tuple):
            continue
        rule = f.metadata.get(RULE)
        yield Setting(
            key=key,
            path=(*path, f.name),
            kind=_kind(value, rule),
            default=value,
            allowed=rule.describe() if rule is not None else "",
            meaning=docs.get(f.name, ""),
            unit=f.metadata.get(UNIT, ""),
            source=f.metadata.get(SOURCE, "") or source,
        )


def settings(config: RunConfig | None = None) -> dict[str, Setting]:
    """Every setting, by key, with defaults taken from ``config`` (default: the paper's)."""
    if config is None:
        return dict(_default_settings())
    return _collect(config)


@functools.cache
def _default_settings() -> dict[str, Setting]:
    return _collect(RunConfig())


def _collect(config: RunConfig) -> dict[str, Setting]:
    found: dict[str, Setting] = {}
    vision = next(f for f in dataclasses.fields(RunConfig) if f.name == "vision")
    found["vision"] = Setting(
        key="vision",
        path=("vision",),
        kind=str,
        default=config.vision,
        allowed=vision.metadata[RULE].describe(),
        meaning=_attribute_docs(RunConfig)["vision"],
        unit="",
        source=vision.metadata.get(SOURCE, ""),
    )
    for prefix, (path, source) in SECTIONS.items():
        section: Any = config
        for name in path:
            section = getattr(section, name)
        for setting in _settings_of(section, prefix, path, source):
            found[setting.key] = setting
    return found


def _flat_keys() -> dict[str, str]:
    """The flat names of earlier versions: each evolution and genetic field, n_packs, vision."""
    flat = {"vision": "vision", "n_packs": "world.n_packs"}
    for key in settings():
        section, _, name = key.partition(".")
        if section in ("evolution", "genetic"):
            flat[name] = key
    return flat


#: Flat name → dotted key (the keys ``--set`` accepted before sections existed).
FLAT_KEYS: dict[str, str] = _flat_keys()


def canonical_key(key: str) -> str:
    """The dotted key that ``key`` (dotted or flat) names.

    Raises:
        ValueError: an unknown key, naming the closest valid keys.
    """
    key = key.strip()
    known = settings()
    if key in known:
        return key
    if key in FLAT_KEYS:
        return FLAT_KEYS[key]
    raise ValueError(f"unknown config key {key!r}; {_closest(key, known)}")


def _closest(key: str, known: Mapping[str, Setting]) -> str:
    """A hint naming up to three valid keys near ``key``."""
    candidates = list(known) + list(FLAT_KEYS)
    near = [FLAT_KEYS.get(k, k) for k in difflib.get_close_matches(key, candidates, cutoff=0.6)]
    if not near:  # match the field name alone, in any section
        field = key.rpartition(".")[2]
        by_field: dict[str, list[str]] = {}
        for k in known:
            by_field.setdefault(k.rpartition(".")[2], []).append(k)
        for name in difflib.get_close_matches(field, list(by_field), n=3, cutoff=0.6):
            near.extend(by_field[name])
    if not near:
        section = key.partition(".")[0]
        near = [k for k in known if k.startswith(section + ".")][:3]
    tail = "see `cyber-rodent config` for every key"
    if not near:
        return tail
    return f"closest: {', '.join(dict.fromkeys(near[:3]))} ({tail})"


def _describe(setting: Setting) -> str:
    """The allowed values, worded to follow "must be"."""
    if setting.allowed.startswith("integer"):
        return "an " + setting.allowed
    if setting.allowed.startswith("number"):
        return "a " + setting.allowed
    if setting.allowed:
        return setting.allowed
    if setting.kind is tuple:
        return f"a list like {','.join(map(str, setting.default))}"
    return {int: "an integer", float: "a number", bool: "true or false"}.get(
        setting.kind, "a string"
    )


def parse_text(key: str, text: str) -> tuple[str, Any]:
    """``(dotted key, typed value)`` for ``KEY=TEXT`` as written on a command line.

    Raises:
        ValueError: an unknown key, or text that is not a value of the field's type (one line
            naming the key and its allowed values).
    """
    name = canonical_key(key)
    setting = settings()[name]
    text = text.strip()
    try:
        value: Any
        if setting.kind is bool:
            lowered = text.lower()
            if lowered not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            value = lowered in ("true", "1", "yes")
        elif setting.kind is int:
            value = int(text)
        elif setting.kind is float:
            value = float(text)
            if not math.isfinite(value):
                raise ValueError
        elif setting.kind is tuple:
            value = tuple(int(part) for part in text.split(","))
        else:
            value = text
    except ValueError:
        raise ValueError(f"{name} must be {_describe(setting)}, got {text!r}") from None
    return name, value


def parse_set(items: Sequence[str] | None) -> dict[str, Any]:
    """``["survival.mate_distance=0.4", ...]`` → ``{dotted key: typed value}``.

    Raises:
        ValueError: an item without ``=``, an unknown key or a value of the wrong type.
    """
    values: dict[str, Any] = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(
                f"--set {item!r}: use KEY=VALUE, e.g. --set survival.mate_distance=0.4"
            )
        name, value = parse_text(key, text)
        values[SHARED_KEYS.get(name, name)] = value  # a later --set wins
    return values


def parse_grid(items: Sequence[str] | None) -> tuple[tuple[str, tuple[Any, ...]], ...]:
    """``["survival.reflex_max_steps=4,8,16", ...]`` → ``((dotted key, values), ...)``.

    Raises:
        ValueError: an item without ``=`` or without values, an unknown key, a value of the
            wrong type, a repeated value, or a key given twice.
    """
    grid: list[tuple[str, tuple[Any, ...]]] = []
    for item in items or []:
        key, sep, text = item.partition("=")
        parts = [p.strip() for p in text.split(",")]
        if not sep or not key.strip() or not all(parts):
            raise ValueError(
                f"--grid {item!r}: use KEY=V1,V2,..., e.g. --grid survival.reflex_max_steps=4,8,16"
            )
        name = canonical_key(key)
        if settings()[name].kind is tuple:
            raise ValueError(f"--grid {item!r}: {name} holds a list and cannot be a grid axis")
        values = tuple(parse_text(name, part)[1] for part in parts)
        if len(set(values)) != len(values):
            raise ValueError(f"--grid {item!r}: a value appears twice")
        if any(name == other for other, _ in grid):
            raise ValueError(f"--grid {item!r}: {name} is already a grid axis")
        grid.append((name, values))
    return tuple(grid)


def _put(values: dict[str, Any], origins: dict[str, str], key: str, value: Any, where: str) -> None:
    """Store a file's ``value`` under the key of its number; two keys of one number must agree."""
    shared = SHARED_KEYS.get(key, key)
    if shared in values and values[shared] != value:
        raise ValueError(
            f"{where}: {key} = {value!r} contradicts {origins[shared]} = {values[shared]!r} "
            "(one number in two sections; change both or remove one)"
        )
    values[shared] = value
    origins[shared] = key


def _coerce(setting: Setting, value: Any, where: str) -> Any:
    """A value read from a TOML or JSON file, checked against the field's type."""
    kind = setting.kind
    ok = isinstance(value, kind) and not (kind in (int, float) and isinstance(value, bool))
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value, ok = float(value), True
    if kind is tuple and isinstance(value, list) and all(
        isinstance(v, int) and not isinstance(v, bool) for v in value
    ):
        value, ok = tuple(value), True
    if not ok:
        raise ValueError(f"{where}: {setting.key} must be {_describe(setting)}, got {value!r}")
    return value


def _flatten(table: Mapping[str, Any], prefix: str = "") -> Iterator[tuple[str, Any]]:
    for key, value in table.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            yield from _flatten(value, name)
        else:
            yield name, value


def load_config_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Settings from a TOML or JSON file: sections (``[survival]``) or dotted or flat keys.

    The output of ``cyber-rodent config`` is such a file.

    Raises:
        ValueError: an unreadable or malformed file, an unknown key, or a value of the wrong
            type (one line naming the file and the key).
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as err:
        raise ValueError(f"--config {p}: {err.strerror or err}") from None
    is_json = p.suffix.lower() == ".json"
    try:
        data = json.loads(raw) if is_json else tomllib.loads(raw.decode())
    except (ValueError, UnicodeDecodeError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        kind = "JSON" if is_json else "TOML"
        raise ValueError(f"--config {p}: not valid {kind} ({reason})") from None
    if not isinstance(data, dict):
        raise ValueError(f"--config {p}: expected a table of key = value pairs")
    known = settings()
    values: dict[str, Any] = {}
    origins: dict[str, str] = {}
    for key, value in _flatten(data):
        try:
            name = canonical_key(key)
        except ValueError as err:
            raise ValueError(f"--config {p}: {err}") from None
        value = _coerce(known[name], value, f"--config {p}")
        _put(values, origins, name, value, f"--config {p}")
    return values


def merge(*layers: Mapping[str, Any]) -> dict[str, Any]:
    """Layers of settings, later ones winning (a file, then ``--set``); keys made canonical."""
    merged: dict[str, Any] = {}
    for layer in layers:
        for key, value in layer.items():
            name = canonical_key(key)
            merged[SHARED_KEYS.get(name, name)] = value
    return merged


def apply(base: RunConfig, values: Mapping[str, Any]) -> RunConfig:
    """``base`` with the settings ``values`` (dotted or flat keys) changed.

    Every sub-config validates its own fields; an error names the dotted key.

    Raises:
        ValueError: an unknown key, or a value its field refuses (one line naming the key and
            the allowed range).
    """
    known = settings()
    groups: dict[tuple[str, ...], dict[str, Any]] = {}
    for key, value in merge(values).items():
        path = known[key].path
        groups.setdefault(path[:-1], {})[path[-1]] = value
    result = base
    # The evolution first: RunConfig.replace carries its shared numbers into survival and world.
    evolution_changes = groups.pop(("evolution",), {})
    genetic_changes = groups.pop(("evolution", "genetics"), {})
    if evolution_changes or genetic_changes:
        genetics = _replace(result.evolution.genetics, genetic_changes, "genetic")
        changes = {**evolution_changes, "genetics": genetics}
        evolution = _replace(result.evolution, changes, "evolution")
        # The world in the same step: its robot count follows the evolution's, so a field
        # enlarged by the same settings must already hold the new robots when it is checked.
        world_changes = {**groups.pop(("world",), {}), "n_robots": evolution.n_robots}
        world = _replace(result.world, world_changes, "world")
        result = result.replace(evolution=evolution, world=world)
    while groups:  # nested parts before their parents
        path = max(groups, key=len)
        changes = groups.pop(path)
        if not path:
            result = result.replace(**changes)
            continue
        parent: Any = result
        for name in path:
            parent = getattr(parent, name)
        section = _key_prefix(path)
        updated = _replace(parent, changes, section)
        if len(path) == 1:
            result = result.replace(**{path[0]: updated})
        else:
            groups.setdefault(path[:-1], {})[path[-1]] = updated
    return result


def _key_prefix(path: tuple[str, ...]) -> str:
    """The dotted key prefix of the config at ``path``: its most specific section's."""
    best: tuple[str, tuple[str, ...]] | None = None
    for prefix, (section_path, _) in SECTIONS.items():
        if path[: len(section_path)] == section_path:
            if best is None or len(section_path) > len(best[1]):
                best = (prefix, section_path)
    if best is None:
        return ".".join(path)
    prefix, section_path = best
    return ".".join((prefix, *path[len(section_path) :]))


def _replace(config: Any, changes: Mapping[str, Any], prefix: str) -> Any:
    """``dataclasses.replace`` whose errors name the dotted key."""
    try:
        return dataclasses.replace(config, **changes)
    except ValueError as err:
        message = str(err)
        if message.startswith("genetics."):
            message = "genetic." + message.removeprefix("genetics.")
        elif prefix and not message.startswith(prefix + "."):
            message = f"{prefix}.{message}"
        raise ValueError(message) from None


def changed(config: RunConfig) -> dict[str, Any]:
    """The settings of ``config`` that differ from the paper's defaults, by dotted key."""
    defaults = settings()
    now = settings(config)
    return {
        k: now[k].default
        for k in now
        if k not in SHARED_KEYS and now[k].default != defaults[k].default
    }


# --- the commented TOML of `cyber-rodent config` -----------------------------------------------
def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _comment(setting: Setting, width: int = 96) -> list[str]:
    """The comment above a setting: its meaning (docstring markup removed), then its facts."""
    meaning = re.sub(r":[a-z]+:`~?([^`]*)`", r"\1", setting.meaning).replace("``", "`")
    lines = textwrap.wrap(meaning, width - 2) if meaning else []
    facts = [setting.allowed or _describe(setting)]
    if setting.unit:
        facts.append(f"unit: {setting.unit}")
    if setting.source:
        facts.append(f"source: {setting.source}")
    shared = SHARED_KEYS.get(setting.key) or next(
        (k for k, v in SHARED_KEYS.items() if v == setting.key), None
    )
    if shared:
        facts.append(f"same number as {shared}")
    lines.append(" · ".join(facts))
    return ["# " + line for line in lines]


def to_toml(config: RunConfig | None = None, method: str | None = None) -> str:
    """``config`` as commented TOML, every setting with its meaning, range, unit and source.

    The text is a valid ``--config`` file that reproduces ``config``.
    """
    config = config if config is not None else RunConfig()
    found = settings(config)
    out = [
        "# cyber-rodent: every setting of a run, resolved. Use this file with --config FILE, or",
        "# change one setting with --set KEY=VALUE (e.g. --set survival.mate_distance=0.4).",
    ]
    if method is not None:
        out.append(f"# method: {method} (chosen with --method, not in this file)")
    tables: dict[str, list[Setting]] = {}
    for setting in found.values():
        table = setting.key.rpartition(".")[0]
        tables.setdefault(table, []).append(setting)
    for table, members in tables.items():
        out.append("")
        if table:
            out.append(f"[{table}]")
        for setting in members:
            out.extend(_comment(setting))
            name = setting.key.rpartition(".")[2]
            out.append(f"{name} = {_toml_value(setting.default)}")
    return "\n".join(out) + "\n"


__all__ = [
    "FLAT_KEYS",
    "SECTIONS",
    "SHARED_KEYS",
    "Setting",
    "apply",
    "canonical_key",
    "changed",
    "load_config_file",
    "merge",
    "parse_grid",
    "parse_set",
    "parse_text",
    "settings",
    "to_toml",
]
