"""Training speed: seconds per epoch on one LOSO fold's full training set (G and D steps, validation).

    .venv/bin/python benchmarks/train_speed.py [--config imm] [--config paper|FILE ...] [--fold s04] [--threads 2] [--epochs 6]
        [--device auto|cpu|cuda]

Prints the thread count and per-epoch times. With several --config, their epochs are interleaved
(A, B, A, B, ...) in one process, so a change in the machine's speed hits all of them alike, and
each is reported as a ratio to the first. The first epoch of each (allocator/oneDNN warm-up) is
excluded. With --device cuda the batches are still drawn and augmented on the CPU (as in `imm train`).
The adversarial weight is forced on from epoch 0 so every epoch pays for the full G + D step.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from dataclasses import replace

import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.device import add_device_argument, resolve_device
from imm_model.families import load_recipe
from imm_model.families.gan.trainer import Trainer
from imm_model.paths import SAMPLE_DATA


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", action="append", help="named config or JSON file; repeat to compare (default: imm)")
    ap.add_argument("--fold", default="s04")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--epochs", type=int, default=6)
    add_device_argument(ap)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    device = resolve_device(args.device)
    data = InteractionDataset.load(SAMPLE_DATA)
    trainers = {}
    for name in args.config or ["imm"]:
        cfg = load_recipe(name)[1]
        cfg = replace(cfg, adv_warmup_epochs=0, adv_ramp_epochs=0, lambda_adv=max(cfg.lambda_adv, 0.1))
        trainers[name] = Trainer(cfg, data, args.fold, "/tmp/imm-train-speed", device)
    times: dict[str, list[float]] = {name: [] for name in trainers}
    for epoch in range(args.epochs + 1):
        for name, trainer in trainers.items():
            t0 = time.perf_counter()
            trainer.train_epoch(epoch)
            trainer.validate()
            times[name].append(time.perf_counter() - t0)
    gpu = f"; GPU {torch.cuda.get_device_name(device)}" if device.type == "cuda" else ""
    print(f"machine: {os.cpu_count()} CPUs; torch threads {torch.get_num_threads()}; device {device}{gpu}; fold {args.fold}")
    first = None
    for name, trainer in trainers.items():
        cfg, t = trainer.cfg, times[name]
        n_batches = -(-len(trainer.train_idx) // cfg.batch_size)
        median = statistics.median(t[1:])
        first = first or median
        print(f"config {name}: {len(trainer.train_idx)} training sequences ({n_batches} batches of {cfg.batch_size}), "
              f"{len(trainer.val_idx)} validation")
        print(f"  warm-up epoch {t[0]:.3f} s; then per epoch: " + ", ".join(f"{x:.3f}" for x in t[1:]))
        ratio = "" if median == first else f"; {median / first:.2f}x the first"
        print(f"  median {median:.3f} s/epoch (mean {statistics.mean(t[1:]):.3f}){ratio}")


if __name__ == "__main__":
    main()
