"""Relation curves: how the follower moves as a whole relative to the leader, as a target for drawn labels.

Issue 9's mixes: the independent judge reads a reaction mostly from the follower's whole-body motion (approach,
retreat, crouch), not from its limbs (docs/training.md, "Mixes without retraining"), and for a drawn label nothing
told the generator what that motion should be, only that a classifier should read the label. This term gives it a
target: per sequence, the change since the first frame of (1) the horizontal distance between the two roots and
(2) the follower's root height, averaged over RELATION_BINS equal parts of the sequence. For a drawn label the
target is the label's mix of the per-class mean curves of the fold's real training pairs; the generated curve is
measured against the leader it was given.
"""

from __future__ import annotations

import numpy as np
import torch

RELATION_BINS = 8


def relation_curves(leader: torch.Tensor, follower: torch.Tensor, lengths: torch.Tensor, root: int, up: int) -> torch.Tensor:
    """leader, follower (B, T, 3J) metres (any frame that keeps `up` vertical: world or canonical), lengths (B,)
    -> (B, RELATION_BINS, 2): per part of the sequence, the mean change since the first frame of the roots'
    horizontal distance and of the follower's root height (metres)."""
    B, T, _ = leader.shape
    a = leader.unflatten(-1, (-1, 3))[:, :, root]  # (B, T, 3)
    b = follower.unflatten(-1, (-1, 3))[:, :, root]
    floor = [k for k in range(3) if k != up]
    distance = (b[..., floor] - a[..., floor]).norm(dim=-1)  # (B, T)
    features = torch.stack([distance - distance[:, :1], b[..., up] - b[:, :1, up]], dim=-1)  # (B, T, 2)
    t = torch.arange(T, device=leader.device)[None]
    bins = (t * RELATION_BINS // lengths[:, None].clamp(min=1)).clamp(max=RELATION_BINS - 1)  # (B, T)
    member = torch.nn.functional.one_hot(bins, RELATION_BINS).to(leader.dtype) * (t < lengths[:, None]).to(leader.dtype)[..., None]
    return member.transpose(1, 2) @ features / member.sum(1)[..., None].clamp(min=1)


def relation_loss(leader: torch.Tensor, fake: torch.Tensor, target: torch.Tensor, lengths: torch.Tensor, root: int,
                  up: int) -> torch.Tensor:
    """Mean |relation curve(fake) - target (B, RELATION_BINS * 2)| over sequences, parts and features (metres)."""
    return (relation_curves(leader, fake, lengths, root, up).flatten(1) - target).abs().mean()


def class_relations(leaders: list[np.ndarray], followers: list[np.ndarray], classes: np.ndarray, num_classes: int,
                    root: int, up: int) -> torch.Tensor:
    """(C, RELATION_BINS * 2) mean relation curve per class over real pairs (each (T, J, 3) canonical metres)."""
    out = torch.zeros(num_classes, RELATION_BINS * 2)
    for c in range(num_classes):
        rows = [relation_curves(torch.as_tensor(a, dtype=torch.float32).flatten(1)[None],
                                torch.as_tensor(b, dtype=torch.float32).flatten(1)[None], torch.tensor([len(a)]), root, up)
                for a, b, k in zip(leaders, followers, classes, strict=True) if k == c]
        if rows:
            out[c] = torch.cat(rows).mean(0).flatten()
    return out
