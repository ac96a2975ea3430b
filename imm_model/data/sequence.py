"""One two-person interaction as arrays, in world metres, with the leader (A) first."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from imm_model.errors import DataFormatError


def resample(motion: np.ndarray, length: int) -> np.ndarray:
    """(T, ...) -> (length, ...) by linear interpolation in time (endpoints kept; a one-frame motion is repeated), in
    the motion's own float type."""
    src = np.linspace(0.0, len(motion) - 1.0, length)
    lo = np.floor(src).astype(int)
    hi = np.minimum(lo + 1, len(motion) - 1)
    w = (src - lo).astype(motion.dtype).reshape(-1, *([1] * (motion.ndim - 1)))
    return (1 - w) * motion[lo] + w * motion[hi]


MAX_COORDINATE_M = 1000.0  # a joint further than this from the origin is not a person's motion (wrong units, garbage)


def check_world_positions(positions: np.ndarray, where: str) -> np.ndarray:
    """Finite positions within MAX_COORDINATE_M of the origin pass through; else a one-line DataFormatError."""
    if not np.isfinite(positions).all():
        raise DataFormatError(f"{where}: NaN or infinite positions")
    largest = float(np.abs(positions).max(initial=0.0))
    if largest > MAX_COORDINATE_M:
        raise DataFormatError(f"{where}: a joint {largest:.3g} m from the origin; positions within {MAX_COORDINATE_M:g} m "
                              "are accepted (wrong units?)")
    return positions


@dataclass(frozen=True)
class Interaction:
    """A two-person sequence. Positions are world coordinates in metres, shape (T, J, 3).

    `leader` is character A (the one whose motion is given), `follower` is B (the reaction).
    `leader_source` says which raw person A is ("PA"/"PB" for SBU, "A"/"B" for K3HI files) and
    `leader_rule` how that was decided ("interformer", "k3hi_list", "motion_energy", "left", "right").
    """

    sequence_id: str  # e.g. "s01s02/03/001"
    dataset: str  # "sbu" | "k3hi"
    action: str  # class name, e.g. "kicking"
    subject_pair: str  # e.g. "s01s02" ("" where the dataset has none)
    leader: np.ndarray  # (T, J, 3) metres
    follower: np.ndarray  # (T, J, 3) metres
    leader_source: str
    leader_rule: str
    frame_numbers: np.ndarray  # (T,) original frame numbers

    @property
    def num_frames(self) -> int:
        return int(self.leader.shape[0])

    @property
    def subjects(self) -> tuple[str, ...]:
        """('s01', 's02') for subject pair 's01s02'."""
        p = self.subject_pair
        return tuple(p[i : i + 3] for i in range(0, len(p), 3)) if p else ()

    def swapped(self) -> Interaction:
        """Role-swap augmentation: B becomes the leader and A the follower."""
        return replace(
            self,
            leader=self.follower,
            follower=self.leader,
            leader_source=f"not {self.leader_source}",
            leader_rule=f"swapped({self.leader_rule})",
        )
