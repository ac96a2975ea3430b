"""The inference API: load any family's checkpoint and synthesize reactions with it.

    model = ReactionModel.load("sample_data/imm_sbu.safetensors")   # the checkpoint's family (families/__init__.py)
    follower = model.synthesize(leader_world, {"kicking": 1.0, "hugging": 0.5})  # (T, J, 3) metres

The model API is families/base.py's `ReactionModel`, the same for every family; this module re-exports it and adds
the one-call helpers and what reads a user's leader file and label text.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from imm_model.data.sequence import check_world_positions
from imm_model.errors import DataFormatError, LabelError
from imm_model.families import load_model
from imm_model.families.base import MAX_SAMPLES, ReactionModel, as_float, check_compatible, check_seeds

__all__ = ["MAX_SAMPLES", "ReactionModel", "check_compatible", "check_seeds", "latent", "load_model", "parse_label",
           "read_leader_file", "synthesize"]

MAX_LEADER_BYTES = 16_000_000  # an .npz leader's arrays, uncompressed (about 44,000 frames of 15 joints in float64)


@functools.lru_cache(maxsize=4)
def _cached_model(path: str) -> ReactionModel:
    return ReactionModel.load(path)


def _model(checkpoint: ReactionModel | Path | str | None) -> ReactionModel:
    from imm_model.paths import SAMPLE_DEFAULT

    if isinstance(checkpoint, ReactionModel):
        return checkpoint
    return _cached_model(str(Path(checkpoint) if checkpoint is not None else SAMPLE_DEFAULT))


def synthesize(leader_motion: np.ndarray, label, scale: float = 1.0, checkpoint=None) -> np.ndarray:
    """Follower (T, J, 3) world metres for a world-space leader, with the bundled model by default."""
    return _model(checkpoint).synthesize(leader_motion, label, scale)


def latent(leader_motion: np.ndarray, label, scale: float = 1.0, checkpoint=None) -> np.ndarray:
    """Per-sequence embedding (D,) of a world-space leader + label, with the bundled model by default."""
    return _model(checkpoint).latent(leader_motion, label, scale)


# ---- `imm generate` ----------------------------------------------------------------------------
def parse_label(text: str, class_names: Sequence[str]) -> dict[str, float] | list[float]:
    """'kicking=1,hugging=0.5' -> mapping; '1,0,0,0,0.5,0' -> list (one value per class)."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise LabelError("empty --label")
    if all("=" in p for p in parts):
        out: dict[str, float] = {}
        for p in parts:
            k, v = (s.strip() for s in p.split("=", 1))
            if k in out:
                raise LabelError(f"--label gives {k} twice ({k}={out[k]:g} and {k}={v}); give each class once")
            out[k] = as_float(v, k)
        return out
    if any("=" in p for p in parts):
        raise LabelError("--label mixes name=value and plain values")
    if len(parts) == 1 and parts[0] in class_names:
        return {parts[0]: 1.0}
    return [as_float(p, f"class {i}") for i, p in enumerate(parts)]


def read_leader_file(path: Path, bvh_map: Path | None = None) -> np.ndarray:
    """A .bvh (any recognisable human skeleton, data/bvh.py), an .npz with a `leader` array ((T, J, 3), or (T, 3J)
    as `check_leader` reads it), or an SBU skeleton_pos.txt (its more active person) -> (T, J, 3) world metres.
    Suffixes in either case; anything else, or beyond the readers' bounds, is a one-line DataFormatError."""
    from imm_model.inputs import check_input

    check_input(path, "leader file")  # a FIFO or a device named as such, never opened
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        from imm_model.data.bvh import read_bvh

        return read_bvh(path, bvh_map)
    if suffix == ".npz":
        from imm_model.data.npz import read_npz

        leader = read_npz(path, ["leader"], MAX_LEADER_BYTES, "leader")["leader"].astype(np.float64)
        if leader.ndim == 2 and leader.shape[1] % 3 == 0 and leader.shape[1] > 0:
            leader = leader.reshape(len(leader), -1, 3)
        if leader.ndim != 3 or leader.shape[2] != 3:
            raise DataFormatError(f"{path}: 'leader' has shape {leader.shape}; expected (frames, joints, 3)")
        return check_world_positions(leader, f"{path}: 'leader'")
    if suffix == ".txt":
        from imm_model.data.leader import actor_by_motion_energy
        from imm_model.data.sbu import normalized_to_metres, parse_skeleton_file

        _, positions = parse_skeleton_file(path)
        metres = normalized_to_metres(positions)
        return metres[actor_by_motion_energy(metres[0], metres[1])]
    raise DataFormatError(f"{path}: unsupported leader file type {path.suffix!r}; give a .bvh, .npz or SBU skeleton_pos.txt")
