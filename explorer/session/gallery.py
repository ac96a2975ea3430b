"""The variations gallery's reactions: for a model that takes a seed, the current leader and mix drawn with GALLERY_SEEDS
seeds one after another, each with the frame where the two bodies come closest and what the judge reads it as."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from explorer.rendering.palette import display_name
from imm_model.inference import check_seeds

GALLERY_SEEDS = 8  # two rows of four at 1366x768


@dataclass(frozen=True)
class Variation:
    seed: int
    follower: np.ndarray  # (T, J, 3) canonical, as the view draws it
    frame: int  # where the leader and the follower come closest
    reads_as: str  # "reads as kicking 63%", "" without a judge

    @property
    def caption(self) -> str:
        return " · ".join(filter(None, (f"seed {self.seed}", self.reads_as)))


def gallery_seeds(first: int) -> list[int]:
    """The gallery's seeds from `first` on (LabelError, one line, past the last seed)."""
    return check_seeds(first, GALLERY_SEEDS)


def variation(session, seed: int) -> Variation:
    """The session's leader and mix drawn with `seed` by its model (~20 ms for the bundled diffusion model)."""
    follower = np.asarray(session.model.synthesize_canonical(session.leader, session.vector, seed=seed), np.float32)
    return Variation(seed, follower, closest_frame(session.leader, follower), reads_as(session, follower))


def closest_frame(leader: np.ndarray, follower: np.ndarray) -> int:
    """The frame where some joint of one body comes closest to some joint of the other: where an interaction shows."""
    n = min(len(leader), len(follower))
    gaps = np.linalg.norm(leader[:n, :, None] - follower[:n, None], axis=-1).min(axis=(1, 2))
    return int(gaps.argmin())


def reads_as(session, follower: np.ndarray) -> str:
    """What the session's judge reads `follower` as, its likeliest class ("" without a judge)."""
    reader = session.readings.reader
    if reader is None:
        return ""
    p = np.asarray(reader.probabilities(follower), np.float64)
    best = int(p.argmax())
    return f"reads as {display_name(str(reader.class_names[best]))} {p[best]:.0%}"
