"""Training speed: seconds per epoch on one LOSO fold's full training set (G and D steps, validation).

    .venv/bin/python benchmarks/train_speed.py [--config imm|paper|FILE] [--fold s04] [--threads 2] [--epochs 4]

Prints the thread count and the per-epoch times; the first epoch (allocator/oneDNN warm-up) is
reported separately and excluded from the mean. Adversarial weight is forced on from epoch 0 so
that every epoch pays for the full G + D step.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.paths import SAMPLE_DATA
from imm_model.training.config import load_config
from imm_model.training.trainer import Trainer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="imm")
    ap.add_argument("--fold", default="s04")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--epochs", type=int, default=4)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    data = InteractionDataset.load(SAMPLE_DATA)
    cfg = load_config(args.config)
    cfg = replace(cfg, adv_warmup_epochs=0, adv_ramp_epochs=0, lambda_adv=max(cfg.lambda_adv, 0.1))
    trainer = Trainer(cfg, data, args.fold, "/tmp/imm-train-speed")
    times = []
    for epoch in range(args.epochs + 1):
        t0 = time.perf_counter()
        trainer.train_epoch(epoch)
        trainer.validate()
        times.append(time.perf_counter() - t0)
    n_batches = -(-len(trainer.train_idx) // cfg.batch_size)
    print(f"config {cfg.name}: fold {args.fold}, {len(trainer.train_idx)} training sequences ({n_batches} batches of {cfg.batch_size}), "
          f"{len(trainer.val_idx)} validation; torch threads {torch.get_num_threads()}")
    print(f"first epoch (warm-up) {times[0]:.3f} s; then per epoch: " + ", ".join(f"{t:.3f}" for t in times[1:]))
    print(f"mean {statistics.mean(times[1:]):.3f} s/epoch, median {statistics.median(times[1:]):.3f} s/epoch")


if __name__ == "__main__":
    main()
