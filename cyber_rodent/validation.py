"""One way to validate a configuration field, for every config dataclass of the package.

Every config is a frozen dataclass whose ``__post_init__`` calls :func:`validate_fields`. A
field declares its rule where it is defined, with :func:`integer`, :func:`number`,
:func:`boolean` or :func:`choice` in place of a plain default; cross-field constraints (a
maximum not below a minimum, say) follow in ``__post_init__`` with :func:`check_integer` and
:func:`check_number` and computed bounds. One rule holds everywhere:

* a bool is never a number, and a number is never a bool;
* numbers are finite; integers may be numpy integers, numbers numpy floats;
* a violation raises ``ValueError`` with one line naming the field, the allowed range and the
  value, e.g. ``max_energy must be a number in (0, 1e+09], got -1``.

The rules are data (``dataclasses.fields(cfg)[i].metadata[RULE]``), so a command that prints a
config can also print each field's allowed range (:func:`describe`). A field may also declare its
``unit`` and its ``source`` (the paper's table, or the ``docs/design.md`` section that argues the
choice), kept in the metadata beside the rule (:data:`UNIT`, :data:`SOURCE`) for the same reason.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar, cast

import numpy as np

#: Key of a field's rule in its dataclass metadata.
RULE = "cyber_rodent.rule"
#: Key of a field's unit ("m", "control steps", ...) in its dataclass metadata.
UNIT = "cyber_rodent.unit"
#: Key of a field's source (paper table or design section) in its dataclass metadata.
SOURCE = "cyber_rodent.source"

T = TypeVar("T")


def _range_text(low: float, high: float, low_open: bool, high_open: bool) -> str:
    left = "(" if low_open or low == -math.inf else "["
    right = ")" if high_open or high == math.inf else "]"
    lo = "-∞" if low == -math.inf else f"{low:g}" if isinstance(low, float) else str(low)
    hi = "∞" if high == math.inf else f"{high:g}" if isinstance(high, float) else str(high)
    return f"{left}{lo}, {hi}{right}"


def check_integer(name: str, value: object, low: float = -math.inf, high: float = math.inf) -> int:
    """``value`` as an int if it is an integer (not a bool) in [low, high]; else ValueError."""
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
    if not ok or not low <= cast(int, value) <= high:
        raise ValueError(
            f"{name} must be an integer in {_range_text(low, high, False, False)}, got {value!r}"
        )
    return int(cast(int, value))


def check_number(
    name: str,
    value: object,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a float if it is a finite number (not a bool) in the range; else ValueError."""
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )
    if ok:
        v = float(cast(float, value))
        ok = math.isfinite(v)
        ok = ok and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        text = _range_text(low, high, low_open, high_open)
        raise ValueError(f"{name} must be a number in {text}, got {value!r}")
    return float(cast(float, value))


def check_boolean(name: str, value: object) -> bool:
    """``value`` if it is True or False (not 0, 1 or a string); else ValueError."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be true or false, got {value!r}")
    return bool(value)


def check_choice(name: str, value: object, choices: Sequence[object]) -> Any:
    """``value`` if it is one of ``choices``; else ValueError listing them."""
    if isinstance(value, bool) or value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(str, choices))}, got {value!r}")
    return value


@dataclass(frozen=True)
class IntegerRule:
    """An integer in [low, high]."""

    low: float = -math.inf
    high: float = math.inf

    def check(self, name: str, value: object) -> None:
        check_integer(name, value, self.low, self.high)

    def describe(self) -> str:
        return f"integer in {_range_text(self.low, self.high, False, False)}"


@dataclass(frozen=True)
class NumberRule:
    """A finite number in the range (either end may be open)."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def check(self, name: str, value: object) -> None:
        check_number(
            name, value, self.low, self.high, low_open=self.low_open, high_open=self.high_open
        )

    def describe(self) -> str:
        return f"number in {_range_text(self.low, self.high, self.low_open, self.high_open)}"


@dataclass(frozen=True)
class BooleanRule:
    """True or False."""

    def check(self, name: str, value: object) -> None:
        check_boolean(name, value)

    def describe(self) -> str:
        return "true or false"


@dataclass(frozen=True)
class ChoiceRule:
    """One of a fixed set of values, or of a registry's names at the time of the check.

    Attributes:
        choices: the values (for a registry: its names when the field was declared).
        registry: None, or a function returning the values allowed now (a registry that
            grows as entries are registered); then it, not ``choices``, decides.
    """

    choices: tuple[object, ...]
    registry: Callable[[], Sequence[object]] | None = None

    def allowed(self) -> Sequence[object]:
        """The values allowed now."""
        return self.choices if self.registry is None else self.registry()

    def check(self, name: str, value: object) -> None:
        check_choice(name, value, self.allowed())

    def describe(self) -> str:
        return "one of " + ", ".join(map(str, self.allowed()))


@dataclass(frozen=True)
class NamesRule:
    """Comma-separated names, each one of a registry's names at the time of the check.

    Attributes:
        registry: a function returning the names allowed now.
    """

    registry: Callable[[], Sequence[str]]

    def check(self, name: str, value: object) -> None:
        allowed = self.registry()
        parts = [part.strip() for part in value.split(",")] if isinstance(value, str) else []
        bad = next((part for part in parts if part not in allowed), None) if parts else value
        if bad is not None:
            raise ValueError(
                f"{name} must be comma-separated names from {', '.join(allowed)}, got {bad!r}"
            )

    def describe(self) -> str:
        return "comma-separated names from " + ", ".join(self.registry())


Rule = IntegerRule | NumberRule | BooleanRule | ChoiceRule | NamesRule


def _metadata(rule: Rule, unit: str, source: str) -> dict[str, object]:
    return {RULE: rule, UNIT: unit, SOURCE: source}


def integer(
    default: int,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    unit: str = "",
    source: str = "",
) -> int:
    """A dataclass field holding an integer in [low, high] (see :func:`validate_fields`)."""
    rule = IntegerRule(low, high)
    return dataclasses.field(default=default, metadata=_metadata(rule, unit, source))


def number(
    default: float,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
    source: str = "",
) -> float:
    """A dataclass field holding a finite number in the range (see :func:`validate_fields`)."""
    rule = NumberRule(low, high, low_open, high_open)
    return dataclasses.field(default=default, metadata=_metadata(rule, unit, source))


def boolean(default: bool, *, source: str = "") -> bool:
    """A dataclass field holding True or False (see :func:`validate_fields`)."""
    return dataclasses.field(default=default, metadata=_metadata(BooleanRule(), "", source))


def choice(
    default: T, choices: Sequence[T] | Callable[[], Sequence[T]], *, source: str = ""
) -> T:
    """A dataclass field holding one of ``choices`` (see :func:`validate_fields`).

    ``choices`` is a sequence of values, or a function returning the values allowed at the
    time of each check: the names of a registry that may grow after the field is declared.
    """
    if callable(choices):
        rule = ChoiceRule(tuple(choices()), registry=choices)
    else:
        rule = ChoiceRule(tuple(choices))
    return dataclasses.field(default=default, metadata=_metadata(rule, "", source))


def names(default: str, registry: Callable[[], Sequence[str]], *, source: str = "") -> str:
    """A dataclass field holding comma-separated names from a registry (see
    :func:`validate_fields`)."""
    rule = NamesRule(registry)
    return dataclasses.field(default=default, metadata=_metadata(rule, "", source))


def validate_fields(config: object, prefix: str = "") -> None:
    """Check every field of the dataclass ``config`` that declares a rule.

    Args:
        config: a dataclass instance (call this from its ``__post_init__``).
        prefix: prepended to field names in messages (e.g. ``"survival."``).

    Raises:
        ValueError: one line naming the first field that breaks its rule.
    """
    for f in dataclasses.fields(cast(Any, config)):
        rule = f.metadata.get(RULE)
        if rule is not None:
            rule.check(prefix + f.name, getattr(config, f.name))


def describe(config_type: type, name: str) -> str:
    """The allowed values of field ``name`` of a config dataclass, in words ("" if no rule)."""
    for f in dataclasses.fields(config_type):
        if f.name == name:
            rule = f.metadata.get(RULE)
            return rule.describe() if rule is not None else ""
    raise KeyError(name)


__all__ = [
    "RULE",
    "SOURCE",
    "UNIT",
    "BooleanRule",
    "ChoiceRule",
    "IntegerRule",
    "NamesRule",
    "NumberRule",
    "Rule",
    "boolean",
    "check_boolean",
    "check_choice",
    "check_integer",
    "check_number",
    "choice",
    "describe",
    "integer",
    "names",
    "number",
    "validate_fields",
]
