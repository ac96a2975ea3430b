"""Cheap baselines that a learned reaction model must beat, each predicting a canonical follower per test
leader from the fold's training sequences of the same class (the true class is given to all of them, as it
is to the model):

- `nn1` (the paper's NN): the training leader closest after resampling to equal length (mean
  per-frame pose-vector distance); its follower, resampled to the test length.
- `knn_dtw`: the k = 3 training leaders closest under dynamic time warping; each one's follower is warped
  onto the test leader's timeline along the DTW path, expressed relative to its own leader's root and
  placed relative to the test leader's root; the k are averaged. Averaging is what AFD rewards, so this
  is the baseline a model has to beat to show it learned more than "the average nearby reaction".
- `template`: the class's mean follower (every training follower resampled to the test length and
  averaged). It never looks at the leader: anything the model does better comes from reading A.
The label-free Men et al. 2022-style model (`--config men`) is the fourth baseline; it is trained like the
model and cached (`fold_baseline_model`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.data.sequence import resample
from imm_model.data.splits import Fold
from imm_model.evaluation.metrics import afd, per_class_mean
from imm_model.families.retrieval.model import nearest_follower

HEURISTIC_BASELINES = ("nn1", "knn_dtw", "template")
KNN = 3


def _same_class_pool(data: InteractionDataset, train_idx: np.ndarray, i: int) -> list[int]:
    pool = [int(j) for j in train_idx if data.actions[j] == data.actions[i] and int(j) != i]
    if not pool:
        raise ValueError(f"no training sequence of class {data.action_name(i)} for the baselines")
    return pool


def nearest_neighbour_follower(data: InteractionDataset, train_idx: np.ndarray, i: int) -> np.ndarray:
    """Canonical follower (T_i, J, 3) predicted for sequence i by `nn1`: the retrieval family's answer with the true
    class (families/retrieval/model.py)."""
    return nearest_follower(data.canonical(i)[0], [data.canonical(j) for j in _same_class_pool(data, train_idx, i)])


def knn_dtw_follower(data: InteractionDataset, train_idx: np.ndarray, i: int, k: int = KNN) -> np.ndarray:
    """Canonical follower (T_i, J, 3) predicted for sequence i by `knn_dtw`."""
    from dtaidistance import dtw_ndim  # C implementation of DTW and its warping path

    root = data.skeleton.root
    leader = data.canonical(i)[0].astype(np.float64)
    query = leader.reshape(len(leader), -1)
    pool = _same_class_pool(data, train_idx, i)
    cands = [data.canonical(j)[0].astype(np.float64) for j in pool]
    dist = [dtw_ndim.distance(query, c.reshape(len(c), -1), use_c=True) for c in cands]
    preds = []
    for n in np.argsort(dist, kind="stable")[:k]:
        a, b = cands[n], data.canonical(pool[n])[1].astype(np.float64)
        relative = b - a[:, root:root + 1]  # B relative to its own leader's root
        warped, count = np.zeros_like(leader), np.zeros(len(leader))
        for t, s in dtw_ndim.warping_path(query, a.reshape(len(a), -1), use_c=True):
            warped[t] += relative[s]
            count[t] += 1
        preds.append(warped / count[:, None, None] + leader[:, root:root + 1])
    return np.mean(preds, axis=0).astype(np.float32)


def template_follower(data: InteractionDataset, train_idx: np.ndarray, i: int) -> np.ndarray:
    """Canonical follower (T_i, J, 3) predicted for sequence i by `template` (leader-blind)."""
    t = int(data.lengths[i])
    pool = _same_class_pool(data, train_idx, i)
    return np.mean([resample(data.canonical(j)[1].astype(np.float64), t) for j in pool], axis=0).astype(np.float32)


_PREDICTORS = {"nn1": nearest_neighbour_follower, "knn_dtw": knn_dtw_follower, "template": template_follower}


def baseline_predictions(name: str, data: InteractionDataset, fold: Fold) -> dict[int, np.ndarray]:
    """{test index: canonical follower} from baseline `name` fitted on fold.train."""
    if name not in _PREDICTORS:
        raise ValueError(f"unknown baseline {name!r}; known: {', '.join(_PREDICTORS)}")
    predict = _PREDICTORS[name]
    return {int(i): predict(data, fold.train, int(i)) for i in fold.test}


def sequence_afds(data: InteractionDataset, predictions: Mapping[int, np.ndarray], units: str = "normalized",
                  squared: bool = False) -> dict[int, float]:
    """{index: canonical follower prediction} -> {index: AFD} (or the squared variant, see metrics.afd)."""
    return {
        int(i): afd(pred, data.canonical(int(i))[1], data.frame_of(int(i)), data.skeleton, units, squared)
        for i, pred in predictions.items()
    }


def evaluate_predictions(data: InteractionDataset, test_idx: np.ndarray, predictions: Mapping[int, np.ndarray],
                         squared: bool = False) -> dict[str, float]:
    """Per-class mean AFD (normalized units) of `predictions` over `test_idx`."""
    missing = [int(i) for i in test_idx if int(i) not in predictions]
    if missing:
        raise ValueError(f"no prediction for {len(missing)} test sequences (e.g. {data.sequence_ids[missing[0]]})")
    afds = sequence_afds(data, {int(i): predictions[int(i)] for i in test_idx}, squared=squared)
    return per_class_mean(afds, data.actions, data.class_names)


def fold_baseline_model(config: str, data: InteractionDataset, subject: str, progress: bool = True) -> Path:
    """A training recipe (a name, e.g. the label-free `men`, or a JSON file of overrides on one) trained on fold
    `subject` by its family (the registry, families/__init__.py), cached (imm_model/cache.py) -> its final checkpoint."""
    import json
    import time

    from imm_model import cache
    from imm_model.checkpoint import final_checkpoint, load_checkpoint
    from imm_model.errors import CheckpointError
    from imm_model.families import load_recipe

    family, cfg = load_recipe(config)
    key = cache.entry_key("model", data, subject, cfg.to_dict())
    out = cache.cache_dir() / "models" / f"{cfg.name}-{subject}-{key}"
    done = out / "done.json"
    if done.exists():
        try:
            path = final_checkpoint(out)
            load_checkpoint(path)
            return path
        except CheckpointError as err:
            cache.note(f"cache: {err}; rebuilding")
    t0 = time.perf_counter()
    trained = family.train(cfg, data, subject, out, "cpu", resume=False, progress=progress)
    done.write_text(json.dumps({"key": key, "line": trained.line}) + "\n")
    cache.note(f"cache: trained the {cfg.name} baseline for fold {subject} in {time.perf_counter() - t0:.0f} s")
    return final_checkpoint(out)
