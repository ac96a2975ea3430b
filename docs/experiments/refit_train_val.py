"""Experiment (not part of the product): refit on training + validation sequences.

For each fold of a finished LOSO run, train a fresh model with the same recipe and seed on the fold's
training *and* validation sequences for the run's selected number of epochs (best epoch + 1), replaying
the run's learning-rate decays epoch by epoch, and save the final EMA generator as best.safetensors.
Measured on three seeds in docs/training.md ("refit" row).

    .venv/bin/python docs/experiments/refit_train_val.py runs/loso runs/refit 0 s01 s02 s03 s04 s05 s06 s07
    .venv/bin/imm evaluate --run runs/refit
"""

import json
import sys

import numpy as np
import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.paths import SAMPLE_DATA
from imm_model.training.config import load_config
from imm_model.training.trainer import Trainer


def main() -> None:
    src, out, seed, subjects = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    cfg = load_config("imm", seed=seed)
    for subject in subjects:
        history = json.load(open(f"{src}/fold-{subject}/last.json"))["history"]
        best = json.load(open(f"{src}/fold-{subject}/best.json"))["training"]["best_epoch"]
        trainer = Trainer(cfg, data, subject, f"{out}/fold-{subject}")
        trainer.train_idx = np.concatenate([trainer.train_idx, trainer.val_idx])  # normalization stays the run's
        for epoch in range(best + 1):
            trainer.state.history = history[:epoch]  # lr_scale() then replays the original run's decays
            trainer.train_epoch(epoch)
        trainer.state.epoch = best + 1
        trainer.out.mkdir(parents=True, exist_ok=True)
        trainer.save_best()
        print(f"{subject}: refit for {best + 1} epochs on {len(trainer.train_idx)} sequences", flush=True)


if __name__ == "__main__":
    main()
