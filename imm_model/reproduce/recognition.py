"""The paper's recognition study (its Table 5): does adding synthesized interactions to the training set help
an interaction classifier?

The paper synthesizes 300 interactions (50 per class) with its model, splits them evenly and adds one half
to the training set and the other to the test set of SBU's half/half split. Adding synthesized data to the
*test* set measures the classifier on the generator's output as much as on real motion, so besides that
"paper" protocol we report a "clean" one (synthesized data in training only, real test data only) and the
same under leave-one-subject-out. The classifier is the evaluation's interaction GRU (model/classifier.py),
not the paper's discriminator-shaped one. Each condition is one classifier with the evaluation's own seed
(INTERACTION.seed) whatever the training seed, so the conditions are paired and the spread over training seeds is
the generator's. Under LOSO the real-only classifier is the fold's cached judge (imm_model/cache.py), trained once
per fold. (Three classifier seeds per condition had made these studies a quarter of a seed's wall time.)

The synthesized interactions: training leaders of each class, with their own class label at scales
SCALES (the label scale is IMM's "match" variation), 50 per class drawn without replacement.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

PER_CLASS = 50
SCALES = (0.8, 0.9, 1.0, 1.1, 1.2)


def synthesize_per_class(model, data, train_idx: np.ndarray, seed: int) -> tuple[list, list, np.ndarray]:
    """-> (leaders, followers, classes) for PER_CLASS synthesized interactions of each class."""
    rng = np.random.default_rng(seed)
    C = len(data.class_names)
    leaders, labels, classes = [], [], []
    for c in range(C):
        members = train_idx[data.actions[train_idx] == c]
        combos = [(int(i), s) for i in members for s in SCALES]
        for k in rng.permutation(len(combos))[:PER_CLASS]:
            i, scale = combos[k]
            leaders.append(data.canonical(i)[0])
            labels.append(np.eye(C, dtype=np.float32)[c] * scale)
            classes.append(c)
    followers = model.synthesize_batch_canonical(leaders, np.stack(labels)) if leaders else []
    return leaders, followers, np.array(classes, dtype=np.int64)


def _per_class_accuracy(pred: np.ndarray, y: np.ndarray, C: int) -> list[float]:
    return [float((pred[y == c] == c).mean()) if (y == c).any() else float("nan") for c in range(C)]


def _score(train: tuple[list, np.ndarray], test: tuple[list, np.ndarray], C: int, epochs: int | None, trained=None) -> dict:
    """Train the evaluation's interaction classifier on `train` (or take `trained(cfg)`, the same classifier already
    trained), test on `test` -> accuracies."""
    from imm_model.model.classifier import classify, train_classifier
    from imm_model.model.classifier_config import INTERACTION

    cfg = replace(INTERACTION, **({"epochs": epochs} if epochs else {}))
    clf = trained(cfg) if trained else train_classifier(cfg, train[0], train[1], C)
    pred = classify(clf, test[0])[0].argmax(-1)
    return {"per_class": _per_class_accuracy(pred, test[1], C), "accuracy": float((pred == test[1]).mean()),
            "train": len(train[1]), "test": len(test[1])}


def study(model, data, train_idx: np.ndarray, test_idx: np.ndarray, protocols: tuple[str, ...],
          classifier_epochs: int | None = None, seed: int = 0, real_only=None) -> dict:
    """Accuracy per class without and with synthesized data, under each protocol ("clean", "paper").
    `real_only(cfg)`, when given, is the classifier `cfg` already trained on the real `train_idx` (a cache)."""
    from imm_model.model.classifier import motion_inputs

    C = len(data.class_names)

    def real(idx: np.ndarray) -> tuple[list, np.ndarray]:
        pairs = [data.canonical(int(i)) for i in idx]
        return motion_inputs([p[0] for p in pairs], [p[1] for p in pairs], "interaction"), data.actions[idx]

    leaders, followers, classes = synthesize_per_class(model, data, train_idx, seed)
    synth = motion_inputs(leaders, followers, "interaction")
    (train_x, train_y), (test_x, test_y) = real(train_idx), real(test_idx)
    score = lambda train, test: _score(train, test, C, classifier_epochs)  # noqa: E731
    out = {"original": _score((train_x, train_y), (test_x, test_y), C, classifier_epochs, real_only)}
    if "clean" in protocols:
        out["augmented"] = score((train_x + synth, np.concatenate([train_y, classes])), (test_x, test_y))
    if "paper" in protocols:  # half of the synthesized set to training, half to the test set
        half = np.random.default_rng(seed).permutation(len(classes)) < len(classes) // 2
        pick = lambda xs, m: [x for x, k in zip(xs, m, strict=True) if k]  # noqa: E731
        out["augmented_paper"] = score((train_x + pick(synth, half), np.concatenate([train_y, classes[half]])),
                                       (test_x + pick(synth, ~half), np.concatenate([test_y, classes[~half]])))
    return out | {"class_names": list(data.class_names), "synthesized": len(classes)}
