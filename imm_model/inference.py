"""The inference API: load any family's checkpoint and synthesize reactions with it.

    model = ReactionModel.load("sample_data/imm_sbu.safetensors")   # the checkpoint's family (families/__init__.py)
    follower = model.synthesize(leader_world, {"kicking": 1.0, "hugging": 0.5})  # (T, J, 3) metres

The model API is families/base.py's `ReactionModel`, the same for every family; this module re-exports it and adds
the one-call helpers. A label is data/labels.py's `Label`; a user's leader file is read by data/leader_file.py's
`read_leader_file`.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from imm_model.data.labels import Label
from imm_model.families import load_model
from imm_model.families.base import MAX_SAMPLES, ReactionModel, check_compatible, check_seeds

__all__ = ["MAX_SAMPLES", "Label", "ReactionModel", "check_compatible", "check_seeds", "latent", "load_model", "synthesize"]



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
