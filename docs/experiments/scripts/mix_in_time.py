"""Whole-body two-class mixes A+B composed in time (the first class's term fading into the second's over the middle
third of the reaction) against the sum rule as shipped, read as both by the fold's whole-body judge (each member at
MIX_SHARE or more); beside them, the same judge's reading of real mixed motion: part composites of held-out followers
(`loso.held_out_mix_readings`). One JSON line per fold (docs/experiments/part-folds.md).

    IMM_CACHE_DIR=... OMP_NUM_THREADS=1 python docs/experiments/scripts/mix_in_time.py --fold s04 \\
        --checkpoint sample_data/imm_diffusion.safetensors --out docs/experiments/data/mix-in-time.jsonl
"""

from __future__ import annotations

import argparse
from itertools import combinations
from pathlib import Path

import numpy as np
from diffusion_fold import record


def fading(mask: np.ndarray) -> np.ndarray:
    """(B, T) -> the first class's weight per frame: 1 over the first third, 0 over the last, smoothstep between."""
    t = np.arange(mask.shape[1])[None] / np.maximum(mask.sum(1, keepdims=True) - 1, 1)
    u = np.clip(3 * t - 1, 0, 1)
    return 1 - u * u * (3 - 2 * u)


def in_time(denoise, leaders, mask, labels, noise, guidance, steps, seeds=None, **_):
    """`sample`'s signature for whole-body labels of two performed classes: the class terms weighed per frame."""
    from imm_model.families.diffusion.sampler import ddim, label_terms

    b, c = labels.shape
    conditions, weights = label_terms(labels)
    k = len(conditions)
    first = fading(mask)
    per_frame = np.repeat(weights[:, :, None], mask.shape[1], 2)  # (K, B, T): the lower-indexed class fades out
    per_frame[0] *= first
    per_frame[1] *= 1 - first
    label_input = np.concatenate([np.zeros((1, b, c), np.float32), np.repeat(conditions[:, None], b, 1)]).reshape(-1, c)
    label_on = np.repeat(np.arange(1 + k) > 0, b)
    leader_on = np.ones((1 + k) * b, bool)
    m = mask[..., None].astype(np.float32)

    def predict(x, step):
        _, t, d = x.shape
        terms = denoise(np.tile(x, (1 + k, 1, 1)), step, leader_on, label_input, label_on).reshape(1 + k, b, t, d)
        strength = guidance.label_scale if step <= guidance.guided_below * (steps - 1) else 1.0
        x0 = terms[0] + (per_frame[..., None] * strength * (terms[1:] - terms[0])).sum(0)
        return np.clip(x0, -guidance.clip, guidance.clip) * m

    return ddim(predict, noise, mask, guidance, steps, seeds)


def main() -> None:
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, held_out_mix_readings, prepare_model
    from imm_model.families.diffusion.sampler import sample
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA
    from imm_model.reads_as import MIX_SHARE

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    model = ReactionModel.load(args.checkpoint)
    prepare_model(model, data, args.fold, opts)
    n, c = len(judges.leaders), len(data.class_names)
    real = held_out_mix_readings(data, judges)
    row = {"fold": args.fold, "checkpoint": str(args.checkpoint), "seed": args.seed,
           "real_composites": float(np.nanmean([np.nanmean([real[i, j], real[j, i]]) for i, j in combinations(range(c), 2)]))}
    for name, sampler in (("sum", sample), ("in_time", in_time)):
        model.sampler = sampler
        reads = []
        for i, j in combinations(range(c), 2):
            labels = np.zeros((n, c), np.float32)
            labels[:, [i, j]] = 1.0
            p = judges.follower_view(judges.judge, model.synthesize_batch_canonical(judges.leaders, labels, [args.seed] * n))
            reads.append(float(np.mean((p[:, i] >= MIX_SHARE) & (p[:, j] >= MIX_SHARE))))
        row[name] = float(np.mean(reads))
    record(row, args.out)


if __name__ == "__main__":
    main()
