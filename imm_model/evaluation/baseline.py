"""The nearest-neighbour baseline and per-class evaluation of a set of predictions.

Baseline (issue 3): for each test leader, the training leader of the same class that is closest
after resampling to equal length (mean per-frame pose-vector distance in the canonical frame); its
follower, resampled to the test length, is the prediction.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import Fold
from imm_model.evaluation.metrics import afd, per_class_mean


def resample(motion: np.ndarray, length: int) -> np.ndarray:
    """(T, ...) -> (length, ...) by linear interpolation in time (endpoints kept)."""
    src = np.linspace(0.0, len(motion) - 1.0, length)
    lo = np.floor(src).astype(int)
    hi = np.minimum(lo + 1, len(motion) - 1)
    w = (src - lo).reshape(-1, *([1] * (motion.ndim - 1)))
    return (1.0 - w) * motion[lo] + w * motion[hi]


def nearest_neighbour_follower(data: InteractionDataset, train_idx: np.ndarray, i: int) -> np.ndarray:
    """Canonical follower (T_i, J, 3) predicted for sequence i from the same-class training pool."""
    leader, _ = data.canonical(i)
    pool = [int(j) for j in train_idx if data.actions[j] == data.actions[i] and int(j) != i]
    if not pool:
        raise ValueError(f"no training sequence of class {data.action_name(i)} for the nearest-neighbour baseline")
    target = leader.reshape(len(leader), -1).astype(np.float64)
    best_j, best_d = pool[0], np.inf
    for j in pool:
        cand = resample(data.canonical(j)[0].reshape(int(data.lengths[j]), -1).astype(np.float64), len(leader))
        d = float(np.linalg.norm(cand - target, axis=-1).mean())
        if d < best_d:
            best_j, best_d = j, d
    return resample(data.canonical(best_j)[1].astype(np.float64), len(leader)).astype(np.float32)


def nn_predictions(data: InteractionDataset, fold: Fold) -> dict[int, np.ndarray]:
    """{test index: canonical follower} from the nearest-neighbour baseline trained on fold.train."""
    return {int(i): nearest_neighbour_follower(data, fold.train, int(i)) for i in fold.test}


def sequence_afds(data: InteractionDataset, predictions: Mapping[int, np.ndarray], units: str = "normalized") -> dict[int, float]:
    """{index: canonical follower prediction} -> {index: AFD}."""
    return {
        int(i): afd(pred, data.canonical(int(i))[1], data.frame_of(int(i)), data.skeleton, units)
        for i, pred in predictions.items()
    }


def evaluate_predictions(data: InteractionDataset, test_idx: np.ndarray, predictions: Mapping[int, np.ndarray]) -> dict[str, float]:
    """Per-class mean AFD (normalized units) of `predictions` over `test_idx`."""
    missing = [int(i) for i in test_idx if int(i) not in predictions]
    if missing:
        raise ValueError(f"no prediction for {len(missing)} test sequences (e.g. {data.sequence_ids[missing[0]]})")
    afds = sequence_afds(data, {int(i): predictions[int(i)] for i in test_idx})
    return per_class_mean(afds, data.actions, data.class_names)
