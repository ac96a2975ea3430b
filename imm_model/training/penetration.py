"""Interpenetration as a training loss: the follower's bone axes kept PENETRATION_M from the leader's.

The same closest-distance geometry as the measure (contact.py), in torch, so that the network learns where to keep
its limbs; stepping the whole follower back after synthesis cost AFD (docs/evaluation.md, "Clean-up").
"""

from __future__ import annotations

import torch

from imm_model.contact import PENETRATION_M


def segment_distances(p0: torch.Tensor, p1: torch.Tensor, q0: torch.Tensor, q1: torch.Tensor) -> torch.Tensor:
    """Closest distance between segments p0-p1 and q0-q1 (broadcast tensors (..., 3)); contact.segment_distances."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e = (d1 * d1).sum(-1), (d2 * d2).sum(-1)
    b, c, f = (d1 * d2).sum(-1), (d1 * r).sum(-1), (d2 * r).sum(-1)
    s = ((b * f - c * e) / (a * e - b * b).clamp_min(1e-12)).clamp(0.0, 1.0)
    t = ((b * s + f) / e.clamp_min(1e-12)).clamp(0.0, 1.0)
    s = ((b * t - c) / a.clamp_min(1e-12)).clamp(0.0, 1.0)
    gap = p0 + d1 * s[..., None] - q0 - d2 * t[..., None]
    return (gap.square().sum(-1) + 1e-12).sqrt()


def penetration_loss(leader: torch.Tensor, follower: torch.Tensor, mask: torch.Tensor, bones: torch.Tensor) -> torch.Tensor:
    """leader, follower (B, T, 3J) metres, mask (B, T), bones (K, 2) -> mean over valid frames of the summed depth
    (metres) by which each pair of bone axes, one of each body, comes within PENETRATION_M of the other."""
    a, b = leader.unflatten(-1, (-1, 3)), follower.unflatten(-1, (-1, 3))
    a0, a1 = a[:, :, bones[:, 0], None], a[:, :, bones[:, 1], None]  # (B, T, K, 1, 3)
    b0, b1 = b[:, :, None, bones[:, 0]], b[:, :, None, bones[:, 1]]  # (B, T, 1, K, 3)
    depth = (PENETRATION_M - segment_distances(a0, a1, b0, b1)).clamp_min(0.0).sum((-1, -2))  # (B, T)
    return (depth * mask).sum() / mask.sum().clamp_min(1)
