"""Which person leads (character A, the actor) and which reacts (B).

Rule, in order: an explicit `left`/`right` choice; otherwise the dataset's actor labelling where it
covers the sequence (SBU: InterFormer's assignment csv; K3HI: the first file of each Train/Test
line); otherwise the motion-energy rule below. Note the provenance file's warning: on SBU the
motion-energy rule agrees with InterFormer's labels for only 50-80 % of the non-approach classes,
so it is a documented fallback, not ground truth.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

LeaderChoice = Literal["actor", "left", "right"]


def motion_energy(positions: np.ndarray) -> float:
    """Total joint path length: sum over frames and joints of |p_t+1 - p_t|. positions (T, J, 3)."""
    return float(np.linalg.norm(np.diff(positions, axis=0), axis=-1).sum())


def actor_by_motion_energy(first: np.ndarray, second: np.ndarray) -> int:
    """0 if `first` moves at least as much as `second`, else 1 (ties go to the first person)."""
    return 0 if motion_energy(first) >= motion_energy(second) else 1


def check_leader_choice(leader: str) -> None:
    if leader not in ("actor", "left", "right"):
        raise ValueError(f"leader must be 'actor', 'left' or 'right', not {leader!r}")
