"""The labels the GAN's label critic (training/label_critic.py) scores besides each row's own: the generator must
make the label it was given readable in the follower it produced.

Training only ever pairs a leader with its own class, so without help the generator learns to react to the
leader and treats the label as a weak hint (docs/experiments/label-critic.md). The critic is the follower GRU of
model/classifier.py, trained on the fold's real training followers only and never updated here. Each batch,
the generated follower for the true label and a second one for a label drawn at random (another class, or a
two-class mix) are scored against what was asked for; only this term and the motion energy apply to the drawn
labels, which have no ground truth. The evaluation judges adherence with a different classifier (conv, other seed).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F


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
