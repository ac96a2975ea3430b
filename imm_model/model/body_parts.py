"""What a body-part judge reads of a follower (numpy only: the studio's part judges run without torch)."""

from __future__ import annotations

import numpy as np


def body_part_view(follower: np.ndarray, part: str, skeleton=None) -> np.ndarray:
    """(T, J, 3) follower -> (T, J, 3) what a body-part judge reads, the other joints zero:
    "upper": trunk and arms relative to the body centre (the root's neighbours: neck and hips), i.e. posture and
    gestures wherever the body stands; "lower": legs relative to the body centre, and the centre itself in the root's
    slot, i.e. steps and placement."""
    from imm_model.skeleton import KINECT15

    skeleton = skeleton or KINECT15
    b = np.asarray(follower, np.float32)
    centre = b[:, skeleton.root_neighbours].mean(1, keepdims=True)
    legs = skeleton.leg_joints
    out = np.zeros_like(b)
    if part == "upper":
        upper = [j for j in range(b.shape[1]) if j not in legs]
        out[:, upper] = b[:, upper] - centre
    else:
        out[:, legs] = b[:, legs] - centre
        out[:, skeleton.root] = centre[:, 0]
    return out
