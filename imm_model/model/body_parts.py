"""What a body-part judge reads of a follower, and a follower composed of two by parts (numpy only: the studio's part
judges and the diffusion sampler run without torch)."""

from __future__ import annotations

import numpy as np


def part_indices(skeleton) -> tuple[list[int], list[int], list[int]]:
    """-> (the trunk's and arms' joints, the legs' joints, the body-centre joints: the root's neighbours)."""
    legs = skeleton.leg_joints
    return [j for j in range(skeleton.num_joints) if j not in legs], legs, list(skeleton.root_neighbours)


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


def compose_parts(upper_from, lower_from, upper: list[int], centre: list[int]):
    """(B, T, J, 3) each, numpy arrays or torch tensors alike -> the same kind: `lower_from`'s legs and placement with
    `upper_from`'s trunk and arms moved to a centre delta at which the result's own body centre is delta itself (the
    hips among the centre joints are legs), so that each part reads as its source does around the body centre. Training
    composes real followers with it (training/part_mix.py), the diffusion sampler joins its parts' predictions with it
    (families/diffusion/model.py `join_parts`), in processes that never import torch (the studio)."""
    relative = upper_from - upper_from[:, :, centre].mean(2)[:, :, None]
    in_legs = [j for j in centre if j not in upper]
    in_upper = [j for j in centre if j in upper]
    if in_legs:
        delta = (relative[:, :, in_upper].sum(2) + lower_from[:, :, in_legs].sum(2)) / len(in_legs)
    else:
        delta = lower_from[:, :, centre].mean(2)
    out = lower_from.copy() if isinstance(lower_from, np.ndarray) else lower_from.clone()
    out[:, :, upper] = relative[:, :, upper] + delta[:, :, None]
    return out
