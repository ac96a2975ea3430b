"""Held-out accuracy of candidate reaction classifiers on real SBU motion, LOSO over the 7 subjects.

    .venv/bin/python benchmarks/classifier_accuracy.py [--inputs interaction,follower] [--seeds 0] [--threads 1]

How the evaluation's classifiers were chosen (docs/evaluation-protocol.md): each candidate ClassifierConfig is
trained on every fold's training subjects (real motion only) and scored on the fold's held-out subject;
prints per-fold accuracies and the mean, one line per candidate and seed. Not a speed benchmark: it lives
here because, like the speed scripts, it prints figures that the docs quote.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_folds
from imm_model.model.classifier import classify, motion_inputs, train_classifier
from imm_model.model.classifier_config import ClassifierConfig
from imm_model.paths import SAMPLE_DATA

CANDIDATES = {
    "gru": ClassifierConfig(arch="gru"),
    "gru-noaug": ClassifierConfig(arch="gru", rotate_deg=0.0, scale_jitter=0.0, noise_m=0.0),
    "gru-120ep": ClassifierConfig(arch="gru", epochs=120),
    "conv": ClassifierConfig(arch="conv"),
    "conv-120ep": ClassifierConfig(arch="conv", epochs=120),
}


def loso_accuracy(cfg: ClassifierConfig, data: InteractionDataset) -> list[float]:
    accs = []
    for fold in loso_folds(data.subject_pairs):
        seqs = lambda idx: motion_inputs(*zip(*(data.canonical(int(i)) for i in idx), strict=True), cfg.inputs)  # noqa: E731
        model = train_classifier(cfg, seqs(fold.train), data.actions[fold.train], len(data.class_names))
        probs, _ = classify(model, seqs(fold.test))
        accs.append(float((probs.argmax(-1) == data.actions[fold.test]).mean()))
    return accs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", default="interaction,follower")
    ap.add_argument("--candidates", default=",".join(CANDIDATES), help=f"comma-separated subset of: {', '.join(CANDIDATES)}")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    data = InteractionDataset.load(SAMPLE_DATA)
    print("folds: " + " ".join(f.name.removeprefix("loso-") for f in loso_folds(data.subject_pairs)))
    for inputs in args.inputs.split(","):
        for name in args.candidates.split(","):
            for seed in (int(s) for s in args.seeds.split(",")):
                t0 = time.perf_counter()
                accs = loso_accuracy(replace(CANDIDATES[name], inputs=inputs, seed=seed), data)
                print(f"{inputs:11s} {name:22s} seed {seed}: mean {np.mean(accs):.3f}  per fold "
                      f"{' '.join(f'{a:.2f}' for a in accs)}  ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
