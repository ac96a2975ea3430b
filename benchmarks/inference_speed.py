"""Inference speed: one 46-frame reaction at batch 1, and all 197 SBU sequences in one batch.

    .venv/bin/python benchmarks/inference_speed.py [--checkpoint CK] [--threads 2] [--repeats 200] [--device cpu|cuda]

Prints the thread count, the median/p90 latency of `ReactionModel.synthesize_canonical` for a
46-frame leader with and without the clean-up (rigid bones, planted feet) and with the averaged placement (a second
network pass on the leader's mirror image), and the time and peak
resident-memory increase of `synthesize_batch_canonical` (and of `latent_canonical_batch`) over the
whole bundled dataset.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import numpy as np
import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.device import add_device_argument, resolve_device
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DATA, SAMPLE_GAN


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(SAMPLE_GAN))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=200)
    add_device_argument(ap, default="cpu")  # the studio synthesizes on the CPU (NumPy runtime)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    device = resolve_device(args.device)
    data = InteractionDataset.load(SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint, device=str(device))
    print(f"checkpoint {args.checkpoint}; torch threads {torch.get_num_threads()}; device {device}")

    i = int(np.argmax(data.lengths))
    leader = data.canonical(i)[0]
    # its own class, unless that is one the training never mirrored: then the averaged placement would skip its second pass
    c = int(data.actions[i]) if not model.handed[data.actions[i]] else int(np.argmin(model.handed))
    label = np.eye(len(data.class_names), dtype=np.float32)[c]
    modes = {"with the clean-up": (False, False), "raw": (True, False), "clean-up + averaged placement": (False, True)}
    for name in [*modes, *modes]:  # interleaved, so drift on a shared machine hits every mode alike
        model.raw, model.average_placement = modes[name]
        for _ in range(10):
            model.synthesize_canonical(leader, label)
        lat = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            model.synthesize_canonical(leader, label)
            lat.append((time.perf_counter() - t0) * 1000)
        lat.sort()
        print(f"one {len(leader)}-frame reaction, batch 1, {name}: median "
              f"{statistics.median(lat):.2f} ms, p90 {lat[int(0.9 * len(lat))]:.2f} ms ({args.repeats} runs)")
    model.raw, model.average_placement = False, False

    leaders = [data.canonical(k)[0] for k in range(len(data))]
    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions]
    for name, fn in (("synthesize_batch_canonical", model.synthesize_batch_canonical),
                     ("latent_canonical_batch", model.latent_canonical_batch)):
        before = peak_rss_mb()
        t0 = time.perf_counter()
        fn(leaders, labels)
        dt = time.perf_counter() - t0
        print(f"{name}: all {len(leaders)} sequences at once: {dt * 1000:.0f} ms, "
              f"peak RSS {peak_rss_mb():.0f} MB (+{peak_rss_mb() - before:.0f} MB over the process peak before)")


if __name__ == "__main__":
    main()
