"""K3HI in place of the paper's 2C MoCap set (its Table 3: FID per class, IMM vs Men et al.).

K3HI's own split (InterFormer's Train.txt / Test.txt) leaves 2-8 test sequences per shared class, too few for a
Fréchet distance, so besides it every recipe is also trained on CV_FOLDS class-stratified folds of the whole
shared-class set and each sequence is synthesized by the fold model that never saw it; FID is taken over the
pooled predictions. The FID features come from an interaction classifier trained on all real K3HI sequences of
the shared classes (a fixed feature extractor, as Inception is for images), never on synthesized ones.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

OFFICIAL = "k3hi"
CV_FOLDS = 4
CV_SPLITS = tuple(f"k3hi-cv{k}" for k in range(1, CV_FOLDS + 1))
SPLITS = (OFFICIAL, *CV_SPLITS)


@lru_cache(maxsize=1)
def shared_data():
    """(dataset, {split: (train indices, test indices)}) of K3HI's classes shared with SBU."""
    from imm_model.data.k3hi import k3hi_shared_dataset
    from imm_model.paths import k3hi_raw_root

    data, train, test = k3hi_shared_dataset(k3hi_raw_root())
    splits = {OFFICIAL: (train, test)}
    rng = np.random.default_rng(0)
    fold_of = np.zeros(len(data), dtype=np.int64)
    for c in range(len(data.class_names)):
        members = rng.permutation(np.flatnonzero(data.actions == c))
        fold_of[members] = np.arange(len(members)) % CV_FOLDS
    for k, name in enumerate(CV_SPLITS):
        splits[name] = (np.flatnonzero(fold_of != k), np.flatnonzero(fold_of == k))
    return data, splits


def scores(checkpoints: dict[str, dict[str, str]], classifier_epochs: int | None = None) -> dict:
    """{recipe: {split: checkpoint path}} -> {recipe: {"official"|"cv": {class: {"afd", "fid"}}}}."""
    from dataclasses import replace

    from imm_model.evaluation.baselines import evaluate_predictions
    from imm_model.evaluation.distribution import fid
    from imm_model.evaluation.loso import model_predictions
    from imm_model.inference import ReactionModel
    from imm_model.model.classifier import classify, motion_inputs, train_classifier
    from imm_model.model.classifier_config import INTERACTION

    data, splits = shared_data()
    pairs = [data.canonical(i) for i in range(len(data))]
    cfg = replace(INTERACTION, **({"epochs": classifier_epochs} if classifier_epochs else {}))
    clf = train_classifier(cfg, motion_inputs([p[0] for p in pairs], [p[1] for p in pairs], "interaction"), data.actions,
                           len(data.class_names))

    def table(test: np.ndarray, preds: dict[int, np.ndarray]) -> dict:
        leaders = [pairs[int(i)][0] for i in test]
        real = classify(clf, motion_inputs(leaders, [pairs[int(i)][1] for i in test], "interaction"))[1]
        fake = classify(clf, motion_inputs(leaders, [preds[int(i)] for i in test], "interaction"))[1]
        afd = evaluate_predictions(data, test, preds)
        y = data.actions[test]
        return {c: {"afd": afd.get(c, float("nan")), "fid": fid(real[y == k], fake[y == k]), "n": int((y == k).sum())}
                for k, c in enumerate(data.class_names)}

    out = {}
    for recipe, paths in checkpoints.items():
        preds = {s: model_predictions(ReactionModel.load(paths[s]), data, splits[s][1]) for s in SPLITS}
        pooled = {i: p for s in CV_SPLITS for i, p in preds[s].items()}
        out[recipe] = {"official": table(splits[OFFICIAL][1], preds[OFFICIAL]),
                       "cv": table(np.arange(len(data)), pooled)}
    return out | {"class_names": list(data.class_names)}
