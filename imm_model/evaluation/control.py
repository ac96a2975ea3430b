"""Label control: does the reaction read as the label asked for? Judged by a follower-only classifier.

- adherence: every test leader x every one-hot target label; matrix[leader class, target class] = share of
  generated followers the judge assigns to the target. The diagonal is the true label; the off-diagonal
  mean is what "mix and match" needs: a reaction the data never paired with that leader.
- mix: every pair of classes at +1 each; mean probability on the pair and on each member, and the share of leaders
  whose reaction reads as both (the mean can pass while each leader's reaction reads as one member only).
- avoid: -1 on the leader's class vs an all-zero label: the change in that class's probability.
- part pairs (a model with a label per body part): every ordered pair, class A on the trunk and arms and class B on
  the legs and placement; the share of leaders whose upper-body judge reads A and lower-body judge reads B, beside the
  same share for real part composites (real followers' parts put together), the judges' own ceiling.
- part avoid: -1 on the leader's class on one part vs an all-zero label: that part judge's change.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import combinations, permutations

import numpy as np

from imm_model.reads_as import MIX_SHARE

# (N, C) label vectors for N leaders -> (N, C) judge probabilities of the generated followers
Judge = Callable[[np.ndarray], np.ndarray]


def adherence_matrix(judge: Judge, leader_classes: np.ndarray, num_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """-> (matrix (C, C) [leader class, target], per-target share over all leaders (C,))."""
    hits = np.zeros((len(leader_classes), num_classes))
    for target in range(num_classes):
        labels = np.zeros((len(leader_classes), num_classes), np.float32)
        labels[:, target] = 1.0
        hits[:, target] = judge(labels).argmax(-1) == target
    matrix = np.full((num_classes, num_classes), np.nan)
    for c in range(num_classes):
        if (leader_classes == c).any():
            matrix[c] = hits[leader_classes == c].mean(0)
    return matrix, hits.mean(0)


def off_diagonal_mean(matrix: np.ndarray) -> float:
    off = ~np.eye(len(matrix), dtype=bool)
    return float(np.nanmean(matrix[off]))


def mix_table(judge: Judge, num_leaders: int, class_names: tuple[str, ...]) -> list[dict]:
    """One row per pair of classes at +1 each: probability mass on the pair and on each member (means over leaders),
    and the share of leaders whose reaction reads as both members (each at MIX_SHARE or more)."""
    rows = []
    for i, j in combinations(range(len(class_names)), 2):
        labels = np.zeros((num_leaders, len(class_names)), np.float32)
        labels[:, [i, j]] = 1.0
        p = judge(labels)
        rows.append({"pair": [class_names[i], class_names[j]], "mass": float((p[:, i] + p[:, j]).mean()),
                     "first": float(p[:, i].mean()), "second": float(p[:, j].mean()),
                     "both_top2": float(np.mean([{i, j} == set(np.argsort(row)[-2:]) for row in p])),
                     "both_read": float(np.mean((p[:, i] >= MIX_SHARE) & (p[:, j] >= MIX_SHARE)))})
    return rows


PART_SHARE = 0.4  # a body-part judge's probability at which that part reads as a class


def part_mix_table(whole: Judge, upper: Judge, lower: Judge, num_leaders: int, class_names: tuple[str, ...],
                   held_out_real: np.ndarray | None = None) -> list[dict]:
    """One row per pair of classes at +1 each: the share of leaders whose reaction reads as mixed, by the whole-body
    judge (each member at MIX_SHARE or more), by the body-part judges (one member on the trunk and arms, the other on the
    legs and placement, each at PART_SHARE or more), and by either; with `held_out_real` (C, C), "real_whole": the
    share of part composites of held-out followers (each member on the trunk and arms in turn) that the whole-body
    judge reads so, the only real mixed motion there is."""
    rows = []
    for i, j in combinations(range(len(class_names)), 2):
        labels = np.zeros((num_leaders, len(class_names)), np.float32)
        labels[:, [i, j]] = 1.0
        p, pu, pl = whole(labels), upper(labels), lower(labels)
        by_whole = (p[:, i] >= MIX_SHARE) & (p[:, j] >= MIX_SHARE)
        by_parts = ((pu[:, i] >= PART_SHARE) & (pl[:, j] >= PART_SHARE)) | ((pu[:, j] >= PART_SHARE) & (pl[:, i] >= PART_SHARE))
        rows.append({"pair": [class_names[i], class_names[j]], "whole": float(by_whole.mean()), "parts": float(by_parts.mean()),
                     "mixed": float((by_whole | by_parts).mean())}
                    | ({} if held_out_real is None else {"real_whole": float(np.nanmean([held_out_real[i, j], held_out_real[j, i]]))}))
    return rows


def part_pair_table(upper: Judge, lower: Judge, real_reads: Callable[[int, int], np.ndarray], num_leaders: int,
                    class_names: tuple[str, ...], held_out_real: np.ndarray | None = None) -> list[dict]:
    """One row per ordered pair of classes (A upper, B lower, A != B): the share of leaders whose reaction to the part
    label upper:A=1, lower:B=1 reads as A on the trunk and arms and as B on the legs and placement (each part judge at
    PART_SHARE or more), beside real part composites: "real", the share of composites of held-out followers (A's
    trunk and arms on B's legs, every pair of them: motion the judges never saw) that read so, `held_out_real[a, b]`
    (C, C); and "real_nearest_training", the share of leaders whose composite of the nearest training followers (which
    the judges were trained on: it measures their memory too) reads so, `real_reads(a, b)` -> (N,) bool. Without
    `held_out_real`, "real" is the nearest-training share. The judges get (N, 2C) part label vectors (upper, then
    lower)."""
    c, rows = len(class_names), []
    for a, b in permutations(range(c), 2):
        labels = np.zeros((num_leaders, 2 * c), np.float32)
        labels[:, a], labels[:, c + b] = 1.0, 1.0
        read = (upper(labels)[:, a] >= PART_SHARE) & (lower(labels)[:, b] >= PART_SHARE)
        nearest = float(np.mean(real_reads(a, b)))
        rows.append({"upper": class_names[a], "lower": class_names[b], "read": float(read.mean()),
                     "real": nearest if held_out_real is None else float(held_out_real[a, b]),
                     "real_nearest_training": nearest})
    return rows


def part_realism(upper: Judge, lower: Judge, leader_classes: np.ndarray, real_upper: np.ndarray, real_lower: np.ndarray,
                 class_names: tuple[str, ...]) -> list[dict]:
    """Per class and body part, whether the model's reactions asked for the class read as it on that part (its judge
    at PART_SHARE or more): the share over the leaders of that class ("own") and over all leaders ("all"), beside the
    share of the real held-out followers of the class ("real"; `real_upper`, `real_lower`: (N, C) the part judges'
    probabilities for each leader's real follower). The judges get (N, C) whole-body labels."""
    c, n, rows = len(class_names), len(leader_classes), []
    for k in range(c):
        labels = np.zeros((n, c), np.float32)
        labels[:, k] = 1.0
        own = leader_classes == k
        for part, judge, real in (("upper", upper, real_upper), ("lower", lower, real_lower)):
            read = judge(labels)[:, k] >= PART_SHARE
            rows.append({"class": class_names[k], "part": part, "own": float(read[own].mean()) if own.any() else float("nan"),
                         "all": float(read.mean()),
                         "real": float((real[own, k] >= PART_SHARE).mean()) if own.any() else float("nan")})
    return rows


def part_avoid_effect(parts: dict[str, Judge], leader_classes: np.ndarray, num_classes: int) -> dict[str, dict[str, float]]:
    """Per part: -1 on the leader's class on that part alone (the other part 0) against an all-zero label; the mean
    change in that part judge's probability of the class, and the share of leaders for whom it is lowered."""
    n, c = len(leader_classes), num_classes
    own = np.arange(n), leader_classes
    out = {}
    for k, (part, judge) in enumerate(parts.items()):
        zero = judge(np.zeros((n, 2 * c), np.float32))[own]
        labels = np.zeros((n, 2 * c), np.float32)
        labels[np.arange(n), k * c + leader_classes] = -1.0
        avoid = judge(labels)[own]
        out[part] = {"change": float((avoid - zero).mean()), "share_lowered": float((avoid < zero).mean())}
    return out


def avoid_effect(judge: Judge, leader_classes: np.ndarray, num_classes: int) -> dict[str, float]:
    """Mean over leaders of P(own class | -1 on it) - P(own class | all zero), the two probabilities, and the share of
    leaders for whom -1 lowers it."""
    n = len(leader_classes)
    own = np.arange(n), leader_classes
    zero = judge(np.zeros((n, num_classes), np.float32))[own]
    avoid_labels = np.zeros((n, num_classes), np.float32)
    avoid_labels[own] = -1.0
    avoid = judge(avoid_labels)[own]
    return {"p_zero": float(zero.mean()), "p_avoid": float(avoid.mean()), "change": float((avoid - zero).mean()),
            "share_lowered": float((avoid < zero).mean())}
