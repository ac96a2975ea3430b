"""Reading typed config dataclasses back from JSON dicts, with unknown keys rejected by name."""

from __future__ import annotations

from dataclasses import fields
from typing import Any, TypeVar

T = TypeVar("T")


def checked_kwargs(cls: type, d: dict[str, Any], what: str) -> dict[str, Any]:
    """A copy of `d` after checking every key is a field of dataclass `cls` (ValueError naming the strays)."""
    known = {f.name for f in fields(cls)}
    unknown = set(d) - known
    if unknown:
        raise ValueError(f"unknown {what} keys {sorted(unknown)}; known: {sorted(known)}")
    return dict(d)
