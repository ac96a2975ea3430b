"""Contact: closest distances between the bone segments of two skeletons (each bone is its axis, a segment), and
the thresholds that say when bodies overlap and when a foot is on the floor. The plausibility measures
(evaluation/plausibility.py) and the clean-up (cleanup.py) read the same definitions."""

from __future__ import annotations

import numpy as np

from imm_model.skeleton import Skeleton

# Limbs are at least ~8-10 cm thick, so two bone axes within 5 cm overlap by half a limb or more. Kinect's joints
# sit on the body's axis only roughly: real followers come that close in 25 % of handshake frames (hands clasped)
# and 48 % of hug frames, so in those classes the measure counts contact as well (docs/evaluation-protocol.md, interpenetration).
PENETRATION_M = 0.05
CONTACT_M = 0.05  # a foot this close to the sequence's lowest foot height is on the floor


def segment_distances(p0, p1, q0, q1) -> np.ndarray:
    """Closest distance between segments p0-p1 and q0-q1 (broadcast arrays (..., 3))."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e = (d1 * d1).sum(-1), (d2 * d2).sum(-1)
    b, c, f = (d1 * d2).sum(-1), (d1 * r).sum(-1), (d2 * r).sum(-1)
    denom = np.maximum(a * e - b * b, 1e-12)
    s = np.clip((b * f - c * e) / denom, 0.0, 1.0)
    t = np.clip((b * s + f) / np.maximum(e, 1e-12), 0.0, 1.0)
    s = np.clip((b * t - c) / np.maximum(a, 1e-12), 0.0, 1.0)  # re-project s onto the clamped t
    return np.linalg.norm(p0 + d1 * s[..., None] - q0 - d2 * t[..., None], axis=-1)


def bone_pair_distances(leader: np.ndarray, follower: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T, K, K) closest distance between bone segment i of A and bone segment j of B per frame (metres)."""
    bones = np.array(skeleton.bones)
    a0, a1 = leader[:, bones[:, 0]][:, :, None], leader[:, bones[:, 1]][:, :, None]  # (T, K, 1, 3)
    b0, b1 = follower[:, bones[:, 0]][:, None], follower[:, bones[:, 1]][:, None]  # (T, 1, K, 3)
    return segment_distances(a0, a1, b0, b1)


def closest_distances(leader: np.ndarray, follower: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(T,) closest distance between any bone segment of A and any of B per frame (metres)."""
    return bone_pair_distances(leader, follower, skeleton).min(axis=(1, 2))
