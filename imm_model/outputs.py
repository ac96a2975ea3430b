"""Output files: never replace an existing file unless asked to (--force), never an input of the same command,
and never write numbers that are not finite."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from imm_model.errors import IMMError


def check_output(path: Path, force: bool, inputs: Iterable[Path | None] = (), option: str = "--out") -> None:
    """Refuse (one-line IMMError) an output that is an input, or that exists without `force`."""
    target = Path(path).resolve()
    for source in inputs:
        if source is not None and Path(source).exists() and Path(source).resolve() == target:
            raise IMMError(f"{option} {path}: that is an input of this command; choose another file")
    if target.is_dir():
        raise IMMError(f"{option} {path}: is a directory; give a file name")
    if target.exists() and not force:
        raise IMMError(f"{option} {path}: the file exists; pass --force to replace it")


def check_finite(values: np.ndarray, what: str) -> np.ndarray:
    """Pass finite arrays through; anything else is a one-line IMMError naming `what`."""
    arr = np.asarray(values)
    if not np.isfinite(arr).all():
        raise IMMError(f"{what} is not finite (NaN or infinity): refusing to write or report it")
    return arr
