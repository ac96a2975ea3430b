"""How a label is spelled: a class name alone is the whole body, "upper:<class>" the trunk and arms, "lower:<class>"
the legs and where the follower stands. A label vector is (C,) for a whole-body label, (2C,) (upper, then lower) for
a label per part; `ReactionModel.label_vector` (families/base.py) parses the keys, this module spells them back."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

PARTS = ("upper", "lower")  # a part label's prefixes, in the order of a (2C,) label vector's halves


def label_keys(vector: np.ndarray, class_names: Sequence[str]) -> dict[str, float]:
    """A label vector, (C,) or (2C,), -> its nonzero values as one spells them: a class name where both parts agree,
    then "upper:<class>" and "lower:<class>" where they differ (the inverse of `ReactionModel.label_vector`)."""
    vec = np.asarray(vector, np.float64).reshape(-1)
    c = len(class_names)
    if len(vec) == c:
        return {n: float(v) for n, v in zip(class_names, vec, strict=True) if v != 0}
    upper, lower = vec[:c], vec[c:]
    out = {n: float(u) for n, u, lo in zip(class_names, upper, lower, strict=True) if u == lo and u}
    for part, values in zip(PARTS, (upper, lower), strict=True):  # the whole body's keys, then each part's
        out |= {f"{part}:{n}": float(v) for n, v, u, lo in zip(class_names, values, upper, lower, strict=True) if u != lo and v}
    return out


def label_text(vector: np.ndarray, class_names: Sequence[str]) -> str:
    """A label vector -> "upper:shaking_hands=1,lower:pushing=-1" (`label_keys`, as `imm generate --label` takes it);
    "" when all zero."""
    return ",".join(f"{k}={v:g}" for k, v in label_keys(vector, class_names).items())


def whole_body(labels: np.ndarray, num_classes: int) -> np.ndarray:
    """(N, C) or (N, 2C) label vectors -> (N, C): a part label as the mean of its two parts."""
    labels = np.asarray(labels)
    return labels if labels.shape[-1] == num_classes else 0.5 * (labels[..., :num_classes] + labels[..., num_classes:])
