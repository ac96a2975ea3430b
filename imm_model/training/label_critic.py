"""A frozen follower-only reaction classifier as an auxiliary critic: the label a model was given must be readable in
the follower it produced. The critic is the follower GRU of model/classifier.py, trained on the fold's real training
followers only and never updated here; the evaluation judges adherence with a different classifier (conv, other
seed). Used by the GAN's training (families/gan/trainer.py, docs/experiments/label-critic.md) and by the diffusion
student's (families/diffusion/distill.py).
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

    def loss(self, follower: torch.Tensor, lengths: torch.Tensor, target: torch.Tensor,
             weight: torch.Tensor | None = None) -> torch.Tensor:
        """follower (B, T, 3J) canonical metres, target (B, C) class probabilities -> soft cross-entropy (mean, or the
        mean weighed by `weight` (B,))."""
        ce = F.cross_entropy(self.classifier(follower, lengths), target, reduction="none")
        return ce.mean() if weight is None else (ce * weight).sum() / weight.sum()
