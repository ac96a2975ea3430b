"""What the studio reads off the synthesized follower: its distance to the ground truth, the paper's AFD, contact with
the leader, and what the judges read it as."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from imm_model.evaluation.metrics import afd


class ReaderLike(Protocol):
    """What the studio needs from `imm_model.reads_as.ReadsAs`."""

    class_names: Sequence[str]

    def probabilities(self, follower: np.ndarray) -> np.ndarray: ...


def mean_joint_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T, J, 3) twice -> (T,) the mean over joints of the distance between corresponding joints."""
    return np.linalg.norm(np.asarray(a, np.float64) - np.asarray(b, np.float64), axis=-1).mean(-1)


class Readings:
    def __init__(self, session, reader: ReaderLike | None, part_readers: dict[str, ReaderLike]) -> None:
        """A room of `session` (session.py). `reader` reads the whole follower, `part_readers` ({"upper": ...,
        "lower": ...}, the body-part judges) each part of a mix by body part."""
        self.session, self.reader, self.part_readers = session, reader, part_readers

    def contact(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Leader vs synthesized follower -> closest limb distance per frame (T,) in metres, and the leader's and the
        follower's bones (T, K) closer than the evaluation's interpenetration threshold to the other body."""
        from imm_model.evaluation.plausibility import penetrating_bones

        ses = self.session
        return penetrating_bones(ses.leader, ses.synth, ses.data.skeleton)

    def reads_as(self) -> np.ndarray | None:
        """(C,) the follower-only classifier's class probabilities for the synthesized follower (None without one)."""
        return None if self.reader is None else np.asarray(self.reader.probabilities(self.session.synth), np.float64)

    def reads_as_parts(self) -> dict[str, np.ndarray]:
        """{"upper": (C,), "lower": (C,)}: each body-part judge's reading of the synthesized follower while the mix's
        parts differ ({} when they do not, or without part judges)."""
        if not self.session.label.parts_differ:
            return {}
        return {part: np.asarray(r.probabilities(self.session.synth), np.float64) for part, r in self.part_readers.items()}

    def distances_m(self) -> np.ndarray:
        """(T,) per frame, how far the synthesized follower's joints are from the ground truth's on average, metres
        (a distance one sees in the view, where the 45-d pose-vector norm of the metrics is ~sqrt(15) times larger)."""
        ses = self.session
        return np.zeros(0) if ses.ground_truth is None else mean_joint_distances(ses.synth, ses.ground_truth)

    def afd(self) -> float | None:
        """The paper's AFD (SBU normalized units) of the synthesized follower against ground truth."""
        ses = self.session
        if ses.ground_truth is None:
            return None
        return afd(ses.synth, ses.ground_truth, ses.frame, ses.data.skeleton, units="normalized")
