"""Posture profiles: how a class's follower holds its body, as a target for drawn labels.

The label critic rewards whatever makes a follower read as its class, and a classifier reads a posture held further
than real followers hold it as more typical still: `imm-steer`'s punched followers lean back 14.6 degrees on average
where the real ones lean 4.5 (docs/evaluation.md, "Torso lean"). For a drawn label nothing held that back. This term
gives it a target: per sequence, each joint's mean position relative to the body centre (the centre of the root's
neighbours), along the follower's own mean facing and along the vertical, with each left and right joint averaged with
its mirror twin. The augmentation's yaw turns and mirroring leave it unchanged, and so does where the follower stands.
For a drawn label the target is the label's mix of per-class mean postures (`energy.mixed_profile`); with a tolerance,
a posture within that many of the classes' standard deviations of it costs nothing, so that only a caricature is
pulled back, not every pose that is a little more typical than the mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from imm_model.skeleton import Skeleton
from imm_model.training.energy import mixed_profile


def postures(pose: torch.Tensor, lengths: torch.Tensor, skeleton: Skeleton) -> torch.Tensor:
    """pose (B, T, 3J) metres (any frame with the skeleton's vertical axis up), lengths (B,) -> (B, 2J): per joint, the
    mean over the valid frames of its offset from the body centre along the follower's facing and along the vertical
    (metres), left and right joints averaged."""
    B, T, _ = pose.shape
    p = pose.unflatten(-1, (-1, 3))  # (B, T, J, 3)
    valid = (torch.arange(T, device=pose.device)[None] < lengths[:, None]).to(pose.dtype)[..., None]  # (B, T, 1)
    up = torch.zeros(3, dtype=pose.dtype, device=pose.device)
    up[skeleton.vertical_axis] = 1.0
    # data.canonical.facing_direction's rule (across x up, horizontal by construction), over the whole sequence and
    # in torch so that the gradient reaches the facing too
    lhip, rhip, lsh, rsh = skeleton.facing_joints
    across = ((p[:, :, lhip] - p[:, :, rhip] + p[:, :, lsh] - p[:, :, rsh]) * valid).sum(1)  # (B, 3)
    forward = torch.linalg.cross(across, up.expand_as(across))
    forward = forward / forward.norm(dim=-1, keepdim=True).clamp(min=1e-9)
    offset = p - p[:, :, skeleton.root_neighbours].mean(2, keepdim=True)  # (B, T, J, 3)
    mean = (offset * valid[..., None]).sum(1) / valid.sum(1)[..., None].clamp(min=1)  # (B, J, 3)
    both = torch.stack([mean @ forward[:, :, None], mean @ up[:, None]], -1).squeeze(-2)  # (B, J, 2)
    twins = torch.as_tensor(skeleton.mirror_permutation, device=pose.device)
    return ((both + both[:, twins]) / 2).flatten(1)


def posture_loss(fake: torch.Tensor, target: torch.Tensor, lengths: torch.Tensor, skeleton: Skeleton,
                 rows: torch.Tensor | None = None, margin: torch.Tensor | float = 0.0) -> torch.Tensor:
    """Mean over sequences (those where `rows` (B,) is true, when given), joints and both directions of how far
    posture(fake) lies beyond `margin` (B, 2J) of the target (B, 2J), metres; 0 when no row is chosen."""
    error = ((postures(fake, lengths, skeleton) - target).abs() - margin).clamp(min=0).mean(-1)  # (B,)
    weight = torch.ones_like(error) if rows is None else rows.to(error.dtype)
    return (error * weight).sum() / weight.sum().clamp(min=1)


def class_postures(followers: list[np.ndarray], classes: np.ndarray, num_classes: int,
                   skeleton: Skeleton) -> tuple[torch.Tensor, torch.Tensor]:
    """-> the mean posture (C, 2J) per class over real followers (each (T, J, 3) metres), and its standard deviation."""
    means, spreads = torch.zeros(2, num_classes, 2 * skeleton.num_joints)
    for c in range(num_classes):
        rows = [postures(torch.as_tensor(f, dtype=torch.float32).flatten(1)[None], torch.tensor([len(f)]), skeleton)
                for f, k in zip(followers, classes, strict=True) if k == c]
        if rows:
            x = torch.cat(rows)
            means[c], spreads[c] = x.mean(0), x.std(0, unbiased=False)
    return means, spreads


@dataclass
class PostureTarget:
    """What a drawn label's follower is held to: the label's mix of the classes' mean postures, give or take
    `tolerance` of their standard deviations; with `on_mixes` off, one-class labels only (a two-class mix is free)."""

    means: torch.Tensor  # (C, 2J)
    spreads: torch.Tensor  # (C, 2J)
    skeleton: Skeleton
    tolerance: float = 0.0
    on_mixes: bool = True

    def loss(self, fake: torch.Tensor, labels: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """fake (B, T, 3J) followers generated for labels (B, C) -> the posture term (metres)."""
        rows = None if self.on_mixes else labels.sum(-1) == 1
        margin = self.tolerance * mixed_profile(labels, self.spreads)
        return posture_loss(fake, mixed_profile(labels, self.means), lengths, self.skeleton, rows, margin)
