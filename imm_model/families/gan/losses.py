"""Losses (paper eq. 4-7), all masked so padded frames never contribute.

Poses are (B, T, 3J) canonical metres; mask (B, T) bool.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F


def masked_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean absolute error over valid frames and coordinates."""
    m = mask[..., None].float()
    return ((pred - target).abs() * m).sum() / (m.sum() * pred.shape[-1])


def bone_lengths(pose: torch.Tensor, bones: torch.Tensor) -> torch.Tensor:
    """(B, T, 3J), bones (K, 2) parent/child -> (B, T, K)."""
    p = pose.unflatten(-1, (-1, 3))
    return (p[:, :, bones[:, 1]] - p[:, :, bones[:, 0]]).norm(dim=-1)


def bone_loss(pred: torch.Tensor, target: torch.Tensor, bones: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean |bone length(pred) - bone length(target)| over valid frames and bones."""
    m = mask[..., None].float()
    diff = (bone_lengths(pred, bones) - bone_lengths(target, bones)).abs()
    return (diff * m).sum() / (m.sum() * bones.shape[0])


def continuity_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean |velocity(pred) - velocity(target)| over pairs of consecutive valid frames."""
    m = (mask[:, 1:] & mask[:, :-1])[..., None].float()
    diff = ((pred[:, 1:] - pred[:, :-1]) - (target[:, 1:] - target[:, :-1])).abs()
    return (diff * m).sum() / (m.sum().clamp(min=1) * pred.shape[-1])



def discriminator_loss(real_logits: torch.Tensor, fake_logits: torch.Tensor, actions: torch.Tensor,
                       label_smoothing: float = 0.0, kind: str = "multiclass") -> torch.Tensor:
    """D side. "multiclass" (paper eq. 4): real follower -> its class, generated follower -> class N ("fake").
    "binary+class" (Men et al. 2022): logit N is a separate real/fake score and logits 0..N-1 a class head
    trained on real followers only (two discriminators sharing one Bi-LSTM trunk)."""
    if kind == "binary+class":
        real_score, fake_score = real_logits[:, -1], fake_logits[:, -1]  # > 0 means "fake"
        binary = (F.binary_cross_entropy_with_logits(real_score, torch.zeros_like(real_score))
                  + F.binary_cross_entropy_with_logits(fake_score, torch.ones_like(fake_score)))
        return binary + F.cross_entropy(real_logits[:, :-1], actions, label_smoothing=label_smoothing)
    fake_class = torch.full_like(actions, real_logits.shape[-1] - 1)
    return F.cross_entropy(real_logits, actions, label_smoothing=label_smoothing) + F.cross_entropy(fake_logits, fake_class)


def generator_adv_loss(fake_logits: torch.Tensor, actions: torch.Tensor, kind: str = "multiclass") -> torch.Tensor:
    """G side: the generated follower should be classified as the conditioned class (and, for
    "binary+class", scored real by the binary head)."""
    if kind == "binary+class":
        fake_score = fake_logits[:, -1]
        return (F.binary_cross_entropy_with_logits(fake_score, torch.zeros_like(fake_score))
                + F.cross_entropy(fake_logits[:, :-1], actions))
    return F.cross_entropy(fake_logits, actions)


def afd_metres(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(B,) per-sequence AFD in metres (mean over valid frames of the pose-vector distance)."""
    m = mask.float()
    return ((pred - target).norm(dim=-1) * m).sum(1) / m.sum(1)
