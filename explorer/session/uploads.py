"""A leader file from the page."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from imm_model.errors import DataFormatError, IMMError
from imm_model.families.base import Leader

MAX_UPLOAD_BYTES = 20_000_000
UPLOAD_SUFFIXES = (".bvh", ".npz", ".txt")


@dataclass(frozen=True)
class Upload:
    """A leader file from the page: shown with the synthesized follower only (there is no ground truth)."""

    name: str
    leader: Leader


def read_upload(name: str, content: bytes, model) -> Leader:
    """An uploaded .bvh / .npz / SBU .txt -> the leader, checked and standardized by the model (`prepare_leader`).
    Every problem is a one-line IMMError naming it (size, type, content, length)."""
    import tempfile

    from imm_model.data.leader_file import read_leader_file

    suffix = Path(name).suffix.lower()
    if suffix not in UPLOAD_SUFFIXES:
        raise DataFormatError(f"{name}: unsupported file type; upload a {', '.join(UPLOAD_SUFFIXES)} leader")
    if len(content) > MAX_UPLOAD_BYTES:
        raise DataFormatError(f"{name}: {len(content) / 1e6:.0f} MB; uploads up to {MAX_UPLOAD_BYTES / 1e6:.0f} MB are accepted")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"upload{suffix}"
        path.write_bytes(content)
        try:
            return model.prepare_leader(read_leader_file(path))
        except IMMError as err:
            raise DataFormatError(f"{name}: {str(err).replace(str(path), '').lstrip(': ')}") from None
