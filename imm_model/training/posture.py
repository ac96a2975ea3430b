"""Posture profiles: how a class's follower holds its body, as a target for drawn labels.

The label critic rewards whatever makes a follower read as its class, and a classifier reads a posture held further
than real followers hold it as more typical still: `imm-steer`'s punched followers lean back 14.6 degrees on average
where the real ones lean 4.5 (docs/evaluation.md, "Torso lean"). For a drawn label nothing held that back. This
term gives it a target: per sequence, each joint's mean position relative to the body centre (the centre of the
root's neighbours), along the follower's own mean facing and along the vertical, with each left and right joint
averaged with its mirror twin. The augmentation's yaw turns and mirroring leave it unchanged, and so
does where the follower stands. For a drawn label the target is the label's mix of per-class mean postures
(`energy.mixed_profile`).
"""

from __future__ import annotations

import numpy as np
import torch

from imm_model.skeleton import Skeleton
from imm_model.training.data import mirror_permutation


def postures(pose: torch.Tensor, lengths: torch.Tensor, skeleton: Skeleton) -> torch.Tensor:
    """pose (B, T, 3J) metres (any frame with the skeleton's vertical axis up), lengths (B,) -> (B, 2J): per joint, the
    mean over the valid frames of its offset from the body centre along the follower's facing and along the vertical
    (metres), left and right joints averaged."""
    B, T, _ = pose.shape
    p = pose.unflatten(-1, (-1, 3))  # (B, T, J, 3)
    valid = (torch.arange(T, device=pose.device)[None] < lengths[:, None]).to(pose.dtype)[..., None]  # (B, T, 1)
    up = torch.zeros(3, dtype=pose.dtype, device=pose.device)
    up[skeleton.vertical_axis] = 1.0
    lhip, rhip, lsh, rsh = skeleton.facing_joints
    across = ((p[:, :, lhip] - p[:, :, rhip] + p[:, :, lsh] - p[:, :, rsh]) * valid).sum(1)  # (B, 3)
    forward = torch.linalg.cross(across, up.expand_as(across))
    forward = forward - (forward @ up)[:, None] * up  # horizontal
    forward = forward / forward.norm(dim=-1, keepdim=True).clamp(min=1e-9)
    offset = p - p[:, :, skeleton.root_neighbours].mean(2, keepdim=True)  # (B, T, J, 3)
    mean = (offset * valid[..., None]).sum(1) / valid.sum(1)[..., None].clamp(min=1)  # (B, J, 3)
    both = torch.stack([mean @ forward[:, :, None], mean @ up[:, None]], -1).squeeze(-2)  # (B, J, 2)
    twins = torch.as_tensor(mirror_permutation(skeleton), device=pose.device)
    return ((both + both[:, twins]) / 2).flatten(1)


def posture_loss(fake: torch.Tensor, target: torch.Tensor, lengths: torch.Tensor, skeleton: Skeleton,
                 rows: torch.Tensor | None = None) -> torch.Tensor:
    """Mean |posture(fake) - target (B, 2J)| over sequences (those where `rows` (B,) is true, when given), joints and
    both directions (metres); 0 when no row is chosen."""
    error = (postures(fake, lengths, skeleton) - target).abs().mean(-1)  # (B,)
    weight = torch.ones_like(error) if rows is None else rows.to(error.dtype)
    return (error * weight).sum() / weight.sum().clamp(min=1)


def class_postures(followers: list[np.ndarray], classes: np.ndarray, num_classes: int, skeleton: Skeleton) -> torch.Tensor:
    """(C, 2J) mean posture per class over real followers (each (T, J, 3) metres)."""
    out = torch.zeros(num_classes, 2 * skeleton.num_joints)
    for c in range(num_classes):
        rows = [postures(torch.as_tensor(f, dtype=torch.float32).flatten(1)[None], torch.tensor([len(f)]), skeleton)
                for f, k in zip(followers, classes, strict=True) if k == c]
        if rows:
            out[c] = torch.cat(rows).mean(0)
    return out
