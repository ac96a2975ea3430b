"""A frozen follower-only reaction classifier as an auxiliary critic: the label the generator was given must
be readable in the follower it produced.

Training only ever pairs a leader with its own class, so without help the generator learns to react to the
leader and treats the label as a weak hint (docs/experiments/label-critic.md). The critic is the follower GRU of
model/classifier.py, trained on the fold's real training followers only and never updated here. Each batch,
the generated follower for the true label and a second one for a label drawn at random (another class, or a
two-class mix) are scored against what was asked for; only this term and the motion energy apply to the drawn
labels, which have no ground truth. The evaluation judges adherence with a different classifier (conv, other seed).
"""

from __future__ import annotations

import copy

import torch
import torch.nn.functional as F

from imm_model.device import move_module
from imm_model.model.classifier import MotionClassifier


class LabelCritic:
    """A frozen follower classifier whose cross-entropy for the asked-for label the generator minimizes."""

    def __init__(self, classifier: MotionClassifier):
        device = next(classifier.parameters()).device
        self.classifier = move_module(copy.deepcopy(classifier).eval().requires_grad_(False), device)
        if isinstance(self.classifier.body, torch.nn.RNNBase):
            # cuDNN backpropagates through a recurrent network in training mode only. With its between-layer dropout
            # at 0 the GRU computes in training mode exactly what it computes in eval mode, so the frozen critic (no
            # dropout anywhere) keeps cuDNN's kernels on a GPU.
            self.classifier.body.dropout = 0.0
            self.classifier.body.train()

    @classmethod
    def for_fold(cls, data, subject: str | None, device) -> LabelCritic:
        """The follower GRU (model/classifier_config.FOLLOWER) trained on fold `subject`'s real training followers,
        cached."""
        from imm_model import cache
        from imm_model.model.classifier_config import FOLLOWER

        return cls(cache.fold_classifier(FOLLOWER, data, subject).to(device))

    def loss(self, follower: torch.Tensor, lengths: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """follower (B, T, 3J) canonical metres, target (B, C) class probabilities -> soft cross-entropy (mean)."""
        return F.cross_entropy(self.classifier(follower, lengths), target, reduction="none").mean()


def drawn_labels(actions: torch.Tensor, num_classes: int, mix_prob: float, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """For each row, a label other than its class -> (label vectors (B, C), target probabilities (B, C)).

    One-hot of a random other class; with probability `mix_prob` a second class is added at +1 too, any class
    but the first, the row's own class included (a mix whose target puts half the probability on each member).
    """
    B, C = len(actions), num_classes
    k1 = torch.randint(1, C, (B,), generator=gen)  # offsets from the own class: never 0
    labels = F.one_hot((actions + k1) % C, C).float()
    if C >= 3:
        k2 = (k1 + torch.randint(1, C, (B,), generator=gen)) % C  # any offset but k1; 0 is the own class
        mix = torch.rand(B, generator=gen) < mix_prob
        labels = labels + F.one_hot((actions + k2) % C, C).float() * mix[:, None]
    return labels, labels / labels.sum(-1, keepdim=True)
