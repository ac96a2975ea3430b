"""The review across sequences: one row per sequence of a split, with how far the synthesized follower is from the real
one, what it reads as, and whether its contact or its feet look wrong (docs/evaluation-protocol.md, "Per-sequence
review"). The studio shows the rows as a sortable table with a "next worst" step.

    rows = review_table(model, data, judge=ReadsAs.load(SAMPLE_JUDGE), features=fold_interaction_features(data, "s04"))
    worst = sort_rows(rows, "afd")[0]
    after = next_worst(rows, worst.index, "afd")

Every row's follower comes from one batched synthesis call (a diffusion model sampling in numpy: a few, see
CPU_SAMPLER_CHUNK); the judge and the feature space read each follower once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, Protocol

import numpy as np

from imm_model.contact import PENETRATION_M, closest_distances
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.errors import LabelError
from imm_model.evaluation.metrics import afd
from imm_model.evaluation.plausibility import foot_skate_mps, frame_rate

# A synthesized pair interpenetrates when its bone axes are within PENETRATION_M on this share of the frames more than
# the real pair's are (real handshakes and hugs come that close: the real pair's share is the allowance).
PENETRATION_EXCESS = 0.2
# Where the real pair touched (bone axes within PENETRATION_M on some frame), a synthesized pair whose closest bones
# stay farther apart than this on every frame never comes within reach.
REACH_M = 0.15
# The foot flag: foot skate above this quantile of the real followers' own foot skate (Kinect feet slide too).
FOOT_QUANTILE = 0.95
# Rows per sampler call for a diffusion model sampling in numpy: its batches of many rows run slower per row than small
# ones on a CPU (benchmarks/review_table.py --chunk)
CPU_SAMPLER_CHUNK = 2

# Sort keys: the larger the worse, except the judge's probability of the asked class (`asked_p`), where smaller is worse.
SORT_KEYS = ("afd", "feature_distance", "asked_p", "interpenetration", "foot_skate_mps", "flags")
LOWER_IS_WORSE = frozenset({"asked_p"})


class Judge(Protocol):
    """What the review needs from imm_model.reads_as.ReadsAs."""

    class_names: Sequence[str]

    def probabilities(self, follower: np.ndarray) -> np.ndarray: ...


class FeatureSpace(Protocol):
    """The interaction classifier's penultimate features of (leader, follower) pairs: FID's feature space."""

    def features(self, leaders: list[np.ndarray], followers: list[np.ndarray]) -> np.ndarray: ...


class InteractionFeatures:
    """A trained interaction MotionClassifier (model/classifier.py) as a FeatureSpace (canonical metres in, (N, F) out)."""

    def __init__(self, classifier):
        self.classifier = classifier

    def features(self, leaders: list[np.ndarray], followers: list[np.ndarray]) -> np.ndarray:
        from imm_model.model import classifier as classifiers

        return classifiers.classify(self.classifier, classifiers.motion_inputs(leaders, followers, "interaction"))[1]


def fold_interaction_features(data: InteractionDataset, subject: str | None, progress: bool = False) -> InteractionFeatures:
    """The feature space `imm evaluate`'s FID uses on fold `subject` (the cached interaction classifier; trained on first
    use, which takes a minute or more)."""
    from imm_model import cache
    from imm_model.model.classifier_config import INTERACTION

    return InteractionFeatures(cache.fold_classifier(INTERACTION, data, subject, progress))


@dataclass(frozen=True)
class ReviewRow:
    index: int  # the sequence's index in the dataset
    sequence_id: str
    class_name: str
    subject_pair: str
    frames: int
    afd: float  # the paper's AFD of this sequence (normalized units, evaluation/metrics.py)
    feature_distance: float  # |f(A, B') - f(A, B)| / the median distance between real interactions of one class; nan without features
    reads_as: str  # the judge's most probable class for the synthesized follower
    reads_as_p: float  # its probability
    asked_p: float  # the judge's probability summed over the label's asked (> 0) classes; nan when none is asked
    interpenetration: float  # share of frames with bone axes of A and B' within PENETRATION_M
    real_interpenetration: float  # the same for the real pair
    closest_m: float  # the synthesized pair's closest bone distance over the sequence, metres
    real_closest_m: float
    contact_flag: bool
    contact_reason: str  # "interpenetrates", "never reaches" or ""
    foot_skate_mps: float
    foot_flag: bool

    @property
    def flags(self) -> int:
        return int(self.contact_flag) + int(self.foot_flag)

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)} | {"flags": self.flags}


@dataclass(frozen=True)
class ReviewThresholds:
    foot_skate_mps: float  # the foot flag's threshold
    penetration_excess: float = PENETRATION_EXCESS
    reach_m: float = REACH_M


def real_foot_threshold(data: InteractionDataset, quantile: float = FOOT_QUANTILE) -> float:
    """The `quantile` of the real followers' foot skate over every sequence of `data` (m/s)."""
    fps = frame_rate(data.dataset)
    skate = [foot_skate_mps(np.asarray(data.canonical(i)[1], np.float64), data.skeleton, fps) for i in range(len(data))]
    return float(np.nanquantile(skate, quantile))


def default_split(model, data: InteractionDataset) -> np.ndarray:
    """The sequences the model never saw: its fold's test sequences (the data's `held_out` ones without a fold)."""
    subject = getattr(model, "held_out_subject", None)
    if subject:
        return np.asarray(loso_fold(data.subject_pairs, subject).test, int)
    return np.flatnonzero(data.held_out)


def label_matrix(label, data: InteractionDataset, indices: np.ndarray) -> np.ndarray:
    """None -> each sequence's own class one-hot; a (C,) multi-hot vector -> the same for every row. (N, C) float32."""
    c = len(data.class_names)
    if label is None:
        return np.eye(c, dtype=np.float32)[data.actions[indices]]
    try:
        vec = np.asarray(label, np.float64)
    except (TypeError, ValueError):
        raise LabelError("the review's label must be a sequence of numbers, one per class") from None
    if vec.ndim != 1 or len(vec) != c:
        raise LabelError(f"the review's label has shape {vec.shape}; expected {c} values ({', '.join(data.class_names)})")
    if not np.isfinite(vec).all():
        raise LabelError("the review's label values must be finite")
    return np.repeat(vec.astype(np.float32)[None], len(indices), 0)


def review_table(model, data: InteractionDataset, indices: Sequence[int] | np.ndarray | None = None, judge: Judge | None = None,
                 label=None, features: FeatureSpace | None = None, seed: int = 0,
                 thresholds: ReviewThresholds | None = None) -> list[ReviewRow]:
    """One ReviewRow per sequence of `indices` (default `default_split`), the followers synthesized by `model` (a
    any family's ReactionModel, as it is set: clean-up, placement) in one batch with `label` (None: each
    sequence's own class) and sampler `seed` (every row the same seed). Without `judge` the reads-as columns are ''/nan;
    without `features` feature_distance is nan."""
    if judge is not None and tuple(judge.class_names) != tuple(data.class_names):
        raise LabelError(f"the judge's classes {', '.join(judge.class_names)} differ from the data's")
    idx = default_split(model, data) if indices is None else np.asarray(indices, int).reshape(-1)
    if len(idx) == 0:
        return []
    if idx.min() < 0 or idx.max() >= len(data):
        raise IndexError(f"sequence index outside 0..{len(data) - 1}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**31:
        raise LabelError(f"seed must be an integer in 0..{2**31 - 1}, not {seed!r}")
    labels = label_matrix(label, data, idx)
    leaders, reals = pairs_of(data, idx)
    synth = synthesize_followers(model, leaders, labels, int(seed))
    distance = feature_distances(features, leaders, reals, synth, data.actions[idx]) if features else None
    return score_rows(data, idx, labels, synth, judge=judge, thresholds=thresholds, distance=distance)


def pairs_of(data: InteractionDataset, indices) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The leaders and real followers of `indices`, canonical metres, float64."""
    pairs = [data.canonical(int(i)) for i in indices]
    return [np.asarray(a, np.float64) for a, _ in pairs], [np.asarray(b, np.float64) for _, b in pairs]


def score_rows(data: InteractionDataset, indices, labels: np.ndarray, synth: list[np.ndarray], judge: Judge | None = None,
               thresholds: ReviewThresholds | None = None, distance: np.ndarray | None = None) -> list[ReviewRow]:
    """One ReviewRow per sequence of `indices`, whose followers `synth` were drawn with the label vectors `labels`
    (N, C); `distance`: their feature distances (None: nan)."""
    idx = np.asarray(indices, int).reshape(-1)
    leaders, reals = pairs_of(data, idx)
    thresholds = thresholds or ReviewThresholds(real_foot_threshold(data))
    distance = np.full(len(idx), np.nan) if distance is None else distance
    fps = frame_rate(data.dataset)
    rows = []
    for k, i in enumerate(idx):
        i = int(i)
        close, real_close = (closest_distances(leaders[k], f, data.skeleton) for f in (synth[k], reals[k]))
        share, real_share = float((close < PENETRATION_M).mean()), float((real_close < PENETRATION_M).mean())
        reason = ("interpenetrates" if share > real_share + thresholds.penetration_excess
                  else "never reaches" if real_close.min() < PENETRATION_M and close.min() > thresholds.reach_m else "")
        skate = foot_skate_mps(synth[k], data.skeleton, fps)
        if judge is not None:
            p = np.asarray(judge.probabilities(synth[k].astype(np.float32)), np.float64)
            top, asked = int(np.argmax(p)), labels[k] > 0
            reads, reads_p, asked_p = data.class_names[top], float(p[top]), float(p[asked].sum()) if asked.any() else float("nan")
        else:
            reads, reads_p, asked_p = "", float("nan"), float("nan")
        rows.append(ReviewRow(
            index=i, sequence_id=str(data.sequence_ids[i]), class_name=data.action_name(i), subject_pair=str(data.subject_pairs[i]),
            frames=int(data.lengths[i]), afd=afd(synth[k], reals[k], data.frame_of(i), data.skeleton), feature_distance=float(distance[k]),
            reads_as=reads, reads_as_p=reads_p, asked_p=asked_p, interpenetration=share, real_interpenetration=real_share,
            closest_m=float(close.min()), real_closest_m=float(real_close.min()), contact_flag=bool(reason), contact_reason=reason,
            foot_skate_mps=float(skate), foot_flag=bool(skate > thresholds.foot_skate_mps)))
    return rows


def synthesize_followers(model, leaders: list[np.ndarray], labels: np.ndarray, seed: int) -> list[np.ndarray]:
    """Every row's follower, in order of length (less padding). One batch call, except for a diffusion model sampling in
    numpy on a CPU: there chunks of CPU_SAMPLER_CHUNK rows of similar length are faster than one batch
    (benchmarks/review_table.py)."""
    order = np.argsort([len(a) for a in leaders], kind="stable")
    chunk = CPU_SAMPLER_CHUNK if model.settings.seed and getattr(model, "fast", None) is not None else len(order)
    out: list[np.ndarray | None] = [None] * len(leaders)
    for start in range(0, len(order), chunk):
        rows = order[start:start + chunk]
        followers = model.synthesize_batch_canonical([leaders[k].astype(np.float32) for k in rows], labels[rows], [seed] * len(rows))
        for k, f in zip(rows, followers, strict=True):
            out[k] = np.asarray(f, np.float64)
    return out  # type: ignore[return-value]


def feature_distances(features: FeatureSpace, leaders: list[np.ndarray], reals: list[np.ndarray], synth: list[np.ndarray],
                      actions: np.ndarray) -> np.ndarray:
    """(N,) |f(A, B') - f(A, B)| over the median |f(A_i, B_i) - f(A_j, B_j)| of distinct real sequences of one class
    (all distinct pairs when no class has two): 1.0 is as far as another real reaction of the same class."""
    real = np.asarray(features.features(leaders, reals), np.float64)
    fake = np.asarray(features.features(leaders, synth), np.float64)
    between = np.linalg.norm(real[:, None] - real[None], axis=-1)
    distinct = ~np.eye(len(real), dtype=bool)
    same = distinct & (actions[:, None] == actions[None])
    pool = between[same] if same.any() else between[distinct]
    scale = float(np.median(pool)) if len(pool) else float("nan")
    return np.linalg.norm(fake - real, axis=-1) / scale if scale > 0 else np.full(len(real), np.nan)


def _check_key(key: str) -> None:
    if key not in SORT_KEYS:
        raise ValueError(f"unknown sort key {key!r}; one of {', '.join(SORT_KEYS)}")


def sort_rows(rows: Sequence[ReviewRow], key: str = "afd") -> list[ReviewRow]:
    """Worst first by `key` (SORT_KEYS; ties and nan last, then by dataset index)."""
    _check_key(key)
    sign = 1.0 if key in LOWER_IS_WORSE else -1.0

    def order(row: ReviewRow) -> tuple:
        v = float(getattr(row, key))
        return (np.isnan(v), sign * v if not np.isnan(v) else 0.0, row.index)

    return sorted(rows, key=order)


def next_worst(rows: Sequence[ReviewRow], current: int | None, key: str = "afd") -> ReviewRow | None:
    """The row after dataset index `current` in `sort_rows(rows, key)`; the worst row when `current` is None or not in
    the table; None after the last row."""
    ordered = sort_rows(rows, key)
    positions = {r.index: k for k, r in enumerate(ordered)}
    if current is None or current not in positions:
        return ordered[0] if ordered else None
    k = positions[current] + 1
    return ordered[k] if k < len(ordered) else None
