"""Loading many files where one bad file does not abort the rest (unless strict)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from imm_model.data.sequence import Interaction
from imm_model.errors import DataFormatError


@dataclass
class LoadResult:
    interactions: list[Interaction]
    class_names: tuple[str, ...]
    skipped: list[tuple[str, str]] = field(default_factory=list)  # (path, one-line reason)

    def __len__(self) -> int:
        return len(self.interactions)

    def report(self) -> str:
        """Human-readable summary of what was skipped ('' when nothing was)."""
        if not self.skipped:
            return ""
        lines = [f"skipped {len(self.skipped)} file(s):"] + [f"  {reason}" for _, reason in self.skipped]
        return "\n".join(lines)


def load_many(
    paths: Sequence[Path],
    read: Callable[[Path], Interaction],
    strict: bool,
    class_names: tuple[str, ...],
) -> LoadResult:
    result = LoadResult(interactions=[], class_names=class_names)
    for path in paths:
        try:
            result.interactions.append(read(path))
        except DataFormatError as err:
            if strict:
                raise
            result.skipped.append((str(path), str(err)))
    return result
