"""Jitter of sampled followers: the mean frame-to-frame speed and the mean second difference (per-frame acceleration)
of the joints relative to the body centre, raw and Savitzky-Golay smoothed, for the first 20 held-out sequences of
fold s04 with their true labels, beside the real followers.

    python docs/experiments/scripts/diffusion_jitter.py CHECKPOINT [CHECKPOINT ...] [--sample-steps 10]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.evaluation.plausibility import smooth
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DATA


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoints", nargs="+")
    ap.add_argument("--sample-steps", type=int, default=None)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    test = np.flatnonzero(data.held_out)[:20]
    leaders = [data.canonical(int(i))[0] for i in test]
    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[test]]
    body = data.skeleton.root_neighbours

    def stats(followers) -> str:
        rel = [np.asarray(f, np.float64) - np.asarray(f, np.float64)[:, body].mean(1, keepdims=True) for f in followers]
        speed = np.mean([np.linalg.norm(np.diff(r, axis=0), axis=-1).mean() for r in rel])
        accel = np.mean([np.linalg.norm(np.diff(r, 2, axis=0), axis=-1).mean() for r in rel])
        return f"speed {speed:.4f} m/frame, second difference {accel:.4f} m/frame"

    reals = [data.canonical(int(i))[1] for i in test]
    print(f"real: raw {stats(reals)}; smoothed {stats([smooth(r.astype(np.float64)) for r in reals])}")
    for path in args.checkpoints:
        model = ReactionModel.load(path)
        model.raw = True
        if args.sample_steps and model.settings.seed:
            model.guidance = replace(model.guidance, sample_steps=args.sample_steps)
        followers = model.synthesize_batch_canonical(leaders, labels)
        print(f"{path}: raw {stats(followers)}; smoothed {stats([smooth(f.astype(np.float64)) for f in followers])}")


if __name__ == "__main__":
    main()
