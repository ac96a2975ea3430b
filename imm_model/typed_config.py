"""Typed config dataclasses: each field declares what it accepts, as data beside its default (`param`), and one generic
check (`validate`, called from each config's __post_init__; `checked_kwargs` for JSON dicts) enforces it, so a bad
value fails with one line naming the field, at load time rather than mid-run.

    lr: float = param(1e-3, Interval(float, 0, None, closed="neither"))  # the optimizer's learning rate

A constraint is an object with `accepts(value) -> bool` and a `str()` that completes "<field> must be ...".
Rules that relate several fields are a config's `RULES`: (field, predicate of the config, what is expected).
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, field, fields
from typing import Any

_CHECK = "check"  # the key of a field's constraint in its dataclasses.field metadata


def param(default: Any = MISSING, check: Any = None, *, factory: Callable[[], Any] | None = None) -> Any:
    """A dataclass field with its constraint: `param(0.5, Interval(float, 0, 1))`, or `factory=dict` for a
    mutable default."""
    if factory is not None:
        return field(default_factory=factory, metadata={_CHECK: check})
    return field(default=default, metadata={_CHECK: check})


def constraint_of(f) -> Any:
    """The constraint a dataclass field declares (None: none declared)."""
    return f.metadata.get(_CHECK)


def _is_number(value: Any, kind: type) -> bool:
    if isinstance(value, bool):
        return False
    if kind is int:
        return isinstance(value, int)
    return isinstance(value, (int, float)) and math.isfinite(value)


@dataclass(frozen=True)
class Interval:
    """An int or a finite float between `low` and `high` (None: unbounded); `closed` is "both", "left", "right" or
    "neither"."""

    kind: type
    low: float | None = None
    high: float | None = None
    closed: str = "both"

    def accepts(self, value: Any) -> bool:
        if not _is_number(value, self.kind):
            return False
        low_ok = self.low is None or (value >= self.low if self.closed in ("both", "left") else value > self.low)
        high_ok = self.high is None or (value <= self.high if self.closed in ("both", "right") else value < self.high)
        return low_ok and high_ok

    def __str__(self) -> str:
        what = "an integer" if self.kind is int else "a finite number"
        if self.low is not None and self.high is not None:
            if self.kind is int and self.closed == "both":
                return f"{what} in {self.low}..{self.high}"
            left, right = "[" if self.closed in ("both", "left") else "(", "]" if self.closed in ("both", "right") else ")"
            return f"{what} in {left}{self.low}, {self.high}{right}"
        if self.low is not None:
            return f"{what} {'>=' if self.closed in ('both', 'left') else '>'} {self.low}"
        if self.high is not None:
            return f"{what} {'<=' if self.closed in ('both', 'right') else '<'} {self.high}"
        return what


@dataclass(frozen=True)
class OneOf:
    """One of a few strings."""

    options: tuple[str, ...]

    def accepts(self, value: Any) -> bool:
        return isinstance(value, str) and value in self.options

    def __str__(self) -> str:
        return "one of " + ", ".join(repr(o) for o in self.options)


@dataclass(frozen=True)
class Flag:
    """true or false."""

    def accepts(self, value: Any) -> bool:
        return isinstance(value, bool)

    def __str__(self) -> str:
        return "true or false"


@dataclass(frozen=True)
class Name:
    """A non-empty one-line string of at most `max_length` characters without path separators (names end up in file
    names)."""

    max_length: int = 100

    def accepts(self, value: Any) -> bool:
        return (isinstance(value, str) and 0 < len(value) <= self.max_length
                and not any(c in value for c in "/\\\n\r\0"))

    def __str__(self) -> str:
        return f"a name (1..{self.max_length} characters, no '/', '\\' or line break)"


@dataclass(frozen=True)
class PathText:
    """A one-line string of at most `max_length` characters, empty allowed: a file path."""

    max_length: int = 1000

    def accepts(self, value: Any) -> bool:
        return isinstance(value, str) and len(value) <= self.max_length and not any(c in value for c in "\n\r\0")

    def __str__(self) -> str:
        return f"a path (at most {self.max_length} characters, no line break)"


@dataclass(frozen=True)
class ListOf:
    """A list (or tuple) of `min_length`..`max_length` items, each accepted by `item`, with no item twice when
    `unique`."""

    item: Any
    min_length: int = 0
    max_length: int = 1000
    unique: bool = False

    def accepts(self, value: Any) -> bool:
        if not isinstance(value, (list, tuple)) or not self.min_length <= len(value) <= self.max_length:
            return False
        if not all(self.item.accepts(v) for v in value):
            return False
        return not self.unique or len({repr(v) for v in value}) == len(value)

    def __str__(self) -> str:
        size = f"at least {self.min_length} " if self.min_length else ""
        return f"a list of {size}{'distinct ' if self.unique else ''}items, each {self.item}"


@dataclass(frozen=True)
class FieldsOf:
    """A JSON object of some of another config's fields (`config.from_dict` accepts it with `defaults` added); the
    inner config's own error, naming its field, is what the user sees."""

    config: type
    defaults: Mapping[str, Any] = field(default_factory=dict)

    def accepts(self, value: Any) -> bool:
        return isinstance(value, Mapping)

    def inner_error(self, value: Mapping) -> str | None:
        try:
            self.config.from_dict(dict(self.defaults) | dict(value))
        except ValueError as err:
            return str(err)
        return None

    def __str__(self) -> str:
        return f"a JSON object of {self.config.__name__} fields"


def _problem(what: str, name: str, value: Any, check: Any) -> str | None:
    """The one-line error for field `name` holding `value`, or None when `check` accepts it."""
    if not check.accepts(value):
        return f"{what}: {name} must be {check}, not {value!r}"[:300]
    inner = check.inner_error(value) if isinstance(check, FieldsOf) else None
    return None if inner is None else f"{what}: {name}: {inner}"[:300]


def validate(config: Any, what: str) -> None:
    """Check each field of dataclass instance `config` against its declared constraint, then the class's RULES
    (ValueError naming the first field that fails)."""
    for f in fields(config):
        check = constraint_of(f)
        if check is not None and (message := _problem(what, f.name, getattr(config, f.name), check)):
            raise ValueError(message)
    for name, ok, expected in getattr(type(config), "RULES", ()):
        if not ok(config):
            raise ValueError(f"{what}: {name} must be {expected}, not {getattr(config, name)!r}"[:300])


def _type_error(value: Any, hint: Any) -> str | None:
    """None when `value` (from JSON) fits the annotation `hint`, else what was expected (fields without a declared
    constraint)."""
    origin = typing.get_origin(hint) or hint
    if hint is bool:
        return None if isinstance(value, bool) else "true or false"
    if hint is int:
        return None if _is_number(value, int) else "an integer"
    if hint is float:
        return None if _is_number(value, float) else "a finite number"
    if hint is str:
        return None if isinstance(value, str) else "a string"
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            return "a list"
        inner = typing.get_args(hint)[0] if typing.get_args(hint) else Any
        bad = next((e for e in (_type_error(v, inner) for v in value) if e), None)
        return None if bad is None else f"a list of items each {bad}"
    if origin is dict:
        return None if isinstance(value, dict) else "a JSON object"
    return None  # Any and other annotations: the dataclass checks them


def checked_kwargs(cls: type, d: Any, what: str) -> dict[str, Any]:
    """A copy of `d` after checking it is a dict whose keys are fields of dataclass `cls` and whose values meet the
    fields' constraints (or, for a field that declares none, its type) (ValueError naming the first problem)."""
    if not isinstance(d, dict):
        raise ValueError(f"{what} must be a JSON object, not {type(d).__name__}")
    by_name = {f.name: f for f in fields(cls)}
    unknown = set(d) - set(by_name)
    if unknown:
        raise ValueError(f"unknown {what} keys {sorted(unknown)}; known: {sorted(by_name)}")
    hints = typing.get_type_hints(cls)
    for key, value in d.items():
        check = constraint_of(by_name[key])
        if check is not None:
            if not check.accepts(value):  # types and ranges; a nested config is checked when the dataclass is built
                raise ValueError(f"{what}: {key} must be {check}, not {value!r}"[:300])
        elif expected := _type_error(value, hints[key]):
            raise ValueError(f"{what}: {key} must be {expected}, not {value!r}"[:300])
    return dict(d)
