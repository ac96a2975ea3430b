"""Two-class training examples composed by body parts: the data that a mix has none of in SBU.

SBU records one class per reaction, so the network never sees a reaction that is two classes at once, and a
two-class label composed at sampling time reads as one class for most leaders. Real reactions composed by body parts
(one class's trunk and arms around the body centre, another class's legs and placement) do read as mixed to the
body-part judges (docs/experiments/reaction-memory.md). With probability `mix_prob` a training row becomes such a
composite of its own follower and the follower of another row of the batch whose class differs (resampled in time to
the row's length), labelled with both classes (two-hot), beside its own leader. Which of the two classes gives the
trunk and arms is fixed per pair, not drawn: the class whose real followers move their trunk and arms more, for the
motion of their legs and placement (`upper_shares`). A drawn side would teach the network, which regresses the clean
reaction, the average of the two composites for a two-hot label: a blend again.

A network that reads a label per body part (DiffusionConfig.part_labels) is told which class gave which part, so
there the side is drawn (`part_rows`): a composite carries its upper body's class on the upper label and its lower
body's on the lower label, a one-class row its class on both; and with probability `part_drop` a row's label names
one part only (the other part's label zeros), which teaches the network each part's term alone, the terms the
sampler composes a part label from.
"""

from __future__ import annotations

import torch

from imm_model.model.body_parts import compose_parts, part_indices


def upper_shares(followers: list, classes, num_classes: int, skeleton) -> torch.Tensor:
    """Real followers (T_i, J, 3) and their classes -> (C,) per class, the mean share of the trunk's and arms' speed
    around the body centre in the whole body's (that and the legs' speed around the centre, and the centre's own)."""
    upper, legs, centre = part_indices(skeleton)
    totals, counts = torch.zeros(num_classes, dtype=torch.float64), torch.zeros(num_classes, dtype=torch.float64)
    for follower, c in zip(followers, classes, strict=True):
        b = torch.as_tensor(follower, dtype=torch.float64)
        middle = b[:, centre].mean(1, keepdim=True)
        speed = lambda x: (x[1:] - x[:-1]).norm(dim=-1).mean()  # noqa: E731
        arms, rest = speed(b[:, upper] - middle), speed(b[:, legs] - middle) + speed(middle)
        totals[int(c)] += float(arms / (arms + rest + 1e-9))
        counts[int(c)] += 1
    return (totals / counts.clamp(min=1)).float()


def resample_rows(motion: torch.Tensor, lengths: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """(B, T, D) padded motions of `lengths` -> each resampled (linearly) to its `target` length, padded to T."""
    b, t, _ = motion.shape
    out = torch.zeros_like(motion)
    for i in range(b):
        n, m = int(lengths[i]), int(target[i])
        pos = torch.linspace(0, n - 1, m) if n > 1 else torch.zeros(m)
        lo = pos.floor().long()
        hi = (lo + 1).clamp(max=n - 1)
        frac = (pos - lo)[:, None]
        out[i, :m] = motion[i, lo] * (1 - frac) + motion[i, hi] * frac
    return out


def with_composites(follower: torch.Tensor, lengths: torch.Tensor, donor: torch.Tensor, composed: torch.Tensor,
                    own_upper: torch.Tensor, skeleton) -> torch.Tensor:
    """Followers (B, T, 3J) -> the `composed` rows replaced by the composite of their own follower and row `donor`'s
    (resampled to their length): their own trunk and arms on the donor's legs and placement where `own_upper`, else the
    other way round; padding stays zero."""
    upper, _, centre = part_indices(skeleton)
    other = resample_rows(follower[donor], lengths[donor], lengths).unflatten(-1, (-1, 3))
    own = follower.unflatten(-1, (-1, 3))
    first = torch.where(own_upper[:, None, None, None], own, other)
    second = torch.where(own_upper[:, None, None, None], other, own)
    mixed = compose_parts(first, second, upper, centre).flatten(-2)
    mask = (torch.arange(follower.shape[1])[None] < lengths[:, None])[..., None]
    return torch.where(composed[:, None, None], mixed * mask, follower)


def mixed_rows(follower: torch.Tensor, lengths: torch.Tensor, actions: torch.Tensor, shares: torch.Tensor, mix_prob: float,
               skeleton, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Followers (B, T, 3J), classes (B,) and the classes' upper-body shares (C,) -> (followers with some rows
    composed, labels (B, C): one-hot, or two-hot for the composed rows)."""
    b, num_classes = len(follower), len(shares)
    donor = torch.randint(b, (b,), generator=gen)
    composed = (torch.rand(b, generator=gen) < mix_prob) & (actions[donor] != actions)
    own_upper = shares[actions] >= shares[actions[donor]]
    labels = torch.nn.functional.one_hot(actions, num_classes).float()
    if not composed.any():
        return follower, labels
    follower = with_composites(follower, lengths, donor, composed, own_upper, skeleton)
    labels = labels + composed[:, None].float() * torch.nn.functional.one_hot(actions[donor], num_classes).float()
    return follower, labels


def part_rows(follower: torch.Tensor, lengths: torch.Tensor, actions: torch.Tensor, num_classes: int, mix_prob: float,
              part_drop: float, skeleton, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Followers (B, T, 3J) and classes (B,) -> (followers with some rows composed by parts, labels (B, 2C): the upper
    body's one-hot, then the lower body's; one part's zeros on the rows whose label names one part only). A composed
    row takes its own follower's upper or lower body, drawn, and the other from a row of another class."""
    b = len(follower)
    donor = torch.randint(b, (b,), generator=gen)
    composed = (torch.rand(b, generator=gen) < mix_prob) & (actions[donor] != actions)
    own_upper = torch.rand(b, generator=gen) < 0.5
    upper_class = torch.where(composed & ~own_upper, actions[donor], actions)
    lower_class = torch.where(composed & own_upper, actions[donor], actions)
    if composed.any():
        follower = with_composites(follower, lengths, donor, composed, own_upper, skeleton)
    one_part = torch.rand(b, generator=gen) < part_drop
    keep_upper = torch.rand(b, generator=gen) < 0.5
    labels = torch.cat([torch.nn.functional.one_hot(upper_class, num_classes).float() * (~one_part | keep_upper)[:, None],
                        torch.nn.functional.one_hot(lower_class, num_classes).float() * (~one_part | ~keep_upper)[:, None]], 1)
    return follower, labels
