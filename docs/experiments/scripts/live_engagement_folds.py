"""How engaged the shipped live reactor stays against the clip sampled whole, on any LOSO fold: per held-out leader
and seed, the closest hands and the torso distance of the live reaction (`online_fold.online_followers`, the fold's
clip model at the live reactor's settings) minus the clip model's offline reaction with the same seed; means with 95 %
t intervals over the takes (the live bar: hands <= + 0.05 m, torso <= + 0.08 m).

    OMP_NUM_THREADS=1 python docs/experiments/scripts/live_engagement_folds.py --fold s02 \\
        --checkpoint runs/teachers/fold-s02/final.safetensors --out docs/experiments/data/live-engagement-folds.jsonl
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def minus_offline(leaders, labels, clip_model, makers: dict, skeleton, bases) -> dict:
    """For each maker ({name: seeds -> followers of `leaders`}) and the clip model's offline reaction, over the seed
    bases (leader k gets seed 1000 * base + k): the mean closest hands and torso distance, and each maker's minus the
    offline reaction's with the same seed, [mean, low, high] with a 95 % t interval over the takes."""
    from long_takes import copy_figures
    from long_takes_seeds import interval

    makers = makers | {"offline": lambda seeds: clip_model.synthesize_batch_canonical(leaders, labels, seeds)}
    figures: dict[str, list[dict]] = {who: [] for who in makers}
    for base in bases:
        seeds = [base * 1000 + k for k in range(len(leaders))]
        for who, make in makers.items():
            figures[who] += [copy_figures(a, f, skeleton, 1)[0] for a, f in zip(leaders, make(seeds), strict=True)]
    out = {}
    for who in figures:
        for key in ("hands", "torso"):
            values = np.array([f[key] for f in figures[who]])
            out[f"{who}_{key}"] = float(values.mean())
            if who != "offline":
                diff = values - np.array([f[key] for f in figures["offline"]])
                out[f"{who}_{key}_minus_offline"] = [float(v) for v in interval(diff)]
    return out


def main() -> None:
    from diffusion_fold import record
    from online_fold import online_followers

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation.loso import EvalOptions, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--checkpoint", type=Path, required=True, help="the fold's clip diffusion checkpoint")
    ap.add_argument("--bases", type=int, nargs="+", default=[0, 1, 2], help="seed bases: leader k gets seed 1000 * base + k")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    test = loso_fold(data.subject_pairs, args.fold).test
    leaders = [data.canonical(int(i))[0] for i in test]
    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[test]]
    model = ReactionModel.load(args.checkpoint)
    prepare_model(model, data, args.fold, EvalOptions(baselines=(), progress=False))
    figures = minus_offline(leaders, labels, model, {"live": lambda seeds: online_followers(model, leaders, labels, seeds)},
                            data.skeleton, args.bases)
    row = {"fold": args.fold, "checkpoint": str(args.checkpoint), "takes": len(leaders) * len(args.bases)}
    row |= {k: figures[k] for k in ("live_hands_minus_offline", "live_torso_minus_offline")}  # mean, low, high
    record(row, args.out)


if __name__ == "__main__":
    main()
