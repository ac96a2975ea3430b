"""Motion-energy matching: the generated follower's limbs should move as much as a real follower's.

An L1-dominated generator answers an uncertain future with the average of its plausible futures, a near-frozen
pose (docs/experiments/imm-recipe.md: limbs at ~0.13 of real speed). This term compares, per sequence and joint, the mean
speed of the joint relative to the follower's root (or, with `energy_reference` "body", to the centre of the
root's neighbours, so that the root joint swaying inside the body earns nothing), of the generated and of the real
follower. It constrains how much a limb moves, not where, so it does not pull towards an average. Both motions are smoothed with the
evaluation's Savitzky-Golay filter (window 7, order 2) first: jitter earns nothing, and Kinect's jitter in the
real followers does not set the target.

For a drawn label (no ground truth) the target is the label's mix of per-class profiles: the mean limb speed
of each joint over the real training followers of each class.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.signal import savgol_coeffs

WINDOW = 7  # must match evaluation/plausibility.py SMOOTH_WINDOW, so that the target is what is measured
_KERNEL = torch.tensor(savgol_coeffs(WINDOW, 2), dtype=torch.float32).view(1, 1, WINDOW)


def frame_speeds(pose: torch.Tensor, lengths: torch.Tensor, reference: int | list[int]) -> tuple[torch.Tensor, torch.Tensor]:
    """pose (B, T, 3J) metres, lengths (B,) -> speed per frame and joint relative to joint `reference` (or the centre
    of several) of the smoothed motion (B, T - WINDOW, J) (metres/frame), and which of those frames are valid
    (B, T - WINDOW): those whose whole smoothing window lies in the sequence."""
    B, T, D = pose.shape
    if T <= WINDOW:
        return pose.new_zeros(B, 0, D // 3), pose.new_zeros(B, 0)
    p = pose.unflatten(-1, (-1, 3))
    rel = (p - p[:, :, torch.atleast_1d(torch.as_tensor(reference))].mean(2, keepdim=True)).flatten(2)  # (B, T, 3J)
    x = rel.transpose(1, 2).reshape(B * D, 1, T)
    smooth = torch.nn.functional.conv1d(x, _KERNEL.to(pose)).view(B, D, T - WINDOW + 1).transpose(1, 2)
    speed = (smooth[:, 1:] - smooth[:, :-1]).unflatten(-1, (-1, 3)).norm(dim=-1)  # (B, T - WINDOW, J)
    valid = (torch.arange(WINDOW, T, device=pose.device)[None] < lengths[:, None]).to(pose.dtype)  # last window frame is valid
    return speed, valid


def limb_speeds(pose: torch.Tensor, lengths: torch.Tensor, reference: int | list[int]) -> torch.Tensor:
    """-> (B, J): `frame_speeds` averaged over each sequence's valid frames."""
    speed, valid = frame_speeds(pose, lengths, reference)
    return (speed * valid[..., None]).sum(1) / valid.sum(1).clamp(min=1)[:, None]


def energy_loss(fake: torch.Tensor, target_speeds: torch.Tensor, lengths: torch.Tensor, reference: int | list[int]) -> torch.Tensor:
    """Mean |limb speed(fake) - target_speeds (B, J)| over sequences long enough to measure and joints (metres/frame)."""
    has = (lengths > WINDOW).to(fake.dtype)[:, None]
    diff = (limb_speeds(fake, lengths, reference) - target_speeds).abs() * has
    return diff.sum() / (has.sum() * diff.shape[1]).clamp(min=1)


def class_profiles(followers: list[np.ndarray], classes: np.ndarray, num_classes: int, reference: int | list[int]) -> torch.Tensor:
    """(C, J) mean limb speed per class and joint over real followers (each (T, J, 3) metres)."""
    profiles = torch.zeros(num_classes, followers[0].shape[1])
    for c in range(num_classes):
        rows = [torch.as_tensor(f, dtype=torch.float32).flatten(1)[None] for f, k in zip(followers, classes, strict=True) if k == c]
        if rows:
            profiles[c] = torch.cat([limb_speeds(r, torch.tensor([r.shape[1]]), reference) for r in rows]).mean(0)
    return profiles


def mixed_profile(labels: torch.Tensor, profiles: torch.Tensor) -> torch.Tensor:
    """labels (B, C) non-negative label vectors -> (B, J): the members' profiles weighted by their values."""
    weights = labels.clamp(min=0)
    return weights @ profiles / weights.sum(-1, keepdim=True).clamp(min=1e-6)
