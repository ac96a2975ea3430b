"""Reading typed config dataclasses back from JSON dicts: unknown keys and values of the wrong type are rejected
by name, in one place, before any dataclass sees them (ranges are each dataclass's own __post_init__)."""

from __future__ import annotations

import math
import typing
from dataclasses import fields
from typing import Any, TypeVar

T = TypeVar("T")


def _type_error(value: Any, hint: Any) -> str | None:
    """None when `value` (from JSON) fits the annotation `hint`, else what was expected."""
    origin = typing.get_origin(hint) or hint
    if hint is bool:
        return None if isinstance(value, bool) else "true or false"
    if hint is int:
        return None if isinstance(value, int) and not isinstance(value, bool) else "an integer"
    if hint is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        return None if ok else "a finite number"
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
    """A copy of `d` after checking it is a dict whose keys are fields of dataclass `cls` and whose values have
    the fields' types (ValueError naming the first problem)."""
    if not isinstance(d, dict):
        raise ValueError(f"{what} must be a JSON object, not {type(d).__name__}")
    known = {f.name for f in fields(cls)}
    unknown = set(d) - known
    if unknown:
        raise ValueError(f"unknown {what} keys {sorted(unknown)}; known: {sorted(known)}")
    hints = typing.get_type_hints(cls)
    for key, value in d.items():
        expected = _type_error(value, hints[key])
        if expected:
            raise ValueError(f"{what}: {key} must be {expected}, not {value!r}"[:300])
    return dict(d)
