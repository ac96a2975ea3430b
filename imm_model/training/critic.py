"""A frozen follower-only reaction classifier as an auxiliary critic: the label the generator was given must
be readable in the follower it produced.

Training only ever pairs a leader with its own class, so without help the generator learns to react to the
leader and treats the label as a weak hint (docs/evaluation.md, adherence). The critic is the follower GRU of
model/classifier.py, trained on the fold's real training followers only and never updated here. Each batch,
the generated follower for the true label and a second one for a label drawn at random (another class, or a
two-class mix) are scored against what was asked for; only this term applies to the drawn labels, which
have no ground truth. The evaluation judges adherence with a different classifier (conv, other seed).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from imm_model.model.classifier import MotionClassifier, augment


class LabelCritic:
    """One or several frozen classifiers (an ensemble of seeds: the generator cannot satisfy one network's quirks
    alone). With `augment`, each scores a randomly turned, scaled and jittered copy of the follower, as the
    classifiers saw their training data, so only what survives those changes counts."""

    def __init__(self, classifiers: list[MotionClassifier], augment: bool = False):
        self.classifiers = [c.eval().requires_grad_(False) for c in classifiers]
        self.augment = augment

    @classmethod
    def for_fold(cls, cfg, data, subject: str | None, device) -> LabelCritic:
        """The critic a training config asks for: one follower GRU per `critic_seeds` (mixup-trained with
        `critic_mixup`, reading motion from the first frame's spot with `critic_start_centred`), trained on fold
        `subject`'s real training followers and cached."""
        from dataclasses import replace

        from imm_model import cache
        from imm_model.model.classifier_config import FOLLOWER

        configs = [replace(FOLLOWER, seed=s, mixup=cfg.critic_mixup, start_centred=cfg.critic_start_centred)
                   for s in cfg.critic_seeds]
        return cls([cache.fold_classifier(c, data, subject).to(device) for c in configs], augment=cfg.critic_augment)

    def loss(self, follower: torch.Tensor, lengths: torch.Tensor, target: torch.Tensor, gen: torch.Generator,
             confidence: float = 1.0) -> torch.Tensor:
        """follower (B, T, 3J) canonical metres, target (B, C) class probabilities -> soft cross-entropy (mean).

        With `confidence` < 1 (one-hot targets), a follower the critic already reads as its class with at least that
        probability adds nothing: the term asks for a readable reaction, not for the most prototypical one."""
        floor = -math.log(confidence)
        total = follower.new_zeros(())
        # cuDNN refuses to backpropagate through an RNN in eval mode, and the frozen critic must stay in eval
        # mode (no dropout); PyTorch's own RNN kernels compute the same function on the GPU.
        with torch.backends.cudnn.flags(enabled=False):
            for clf in self.classifiers:
                x = augment(follower, clf.cfg, gen) if self.augment else follower
                per_row = F.cross_entropy(clf(x, lengths), target, reduction="none")
                total = total + (per_row - floor).clamp(min=0).mean()
        return total / len(self.classifiers)


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
