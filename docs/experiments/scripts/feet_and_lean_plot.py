"""A picture of planted feet and torso lean: for held-out leaders of one fold, each model's follower (raw, before the
clean-up, so that the network's own feet show) beside the real one, frame by frame.

    python docs/experiments/scripts/feet_and_lean_plot.py --fold s04 --classes kicking pushing \\
        --model before=sample_data/imm_diffusion.safetensors --model after=runs/geo/fold-s04/final.safetensors \\
        --out docs/experiments/data/feet-and-lean.png

Top row: the horizontal speed of the foot nearer the floor (m/s); bottom row: the torso's lean from the vertical
(degrees, + towards the follower's facing), as evaluation/plausibility.py measures them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def lowest_foot_speed(motion: np.ndarray, skeleton, fps: float) -> np.ndarray:
    """(T, J, 3) -> (T-1,) horizontal speed of whichever foot is lower at each step."""
    feet = [skeleton.joint_names.index(n) for n in ("left_foot", "right_foot")]
    up = skeleton.vertical_axis
    pos = motion[:, feet]
    step = np.linalg.norm(np.delete(np.diff(pos, axis=0), up, axis=-1), axis=-1) * fps  # (T-1, 2)
    lower = np.argmin(pos[1:, :, up], axis=1)
    return step[np.arange(len(step)), lower]


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation.plausibility import torso_lean_per_frame_deg
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--classes", nargs="+", default=["kicking", "pushing"])
    ap.add_argument("--model", action="append", required=True, help="NAME=CHECKPOINT")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    held_out = loso_fold(data.subject_pairs, args.fold).test
    models = {}
    for spec in args.model:
        name, path = spec.split("=", 1)
        models[name] = ReactionModel.load(path)
        models[name].raw = True
    fps = 15.0
    fig, axes = plt.subplots(2, len(args.classes), figsize=(5 * len(args.classes), 6), squeeze=False)
    for col, cls in enumerate(args.classes):
        k = data.class_names.index(cls)
        i = next(int(j) for j in held_out if data.actions[j] == k)
        leader, real = data.canonical(i)
        label = np.eye(len(data.class_names), dtype=np.float32)[k]
        curves = {"real": real} | {n: m.synthesize_canonical(leader, label, seed=args.seed) for n, m in models.items()}
        for name, follower in curves.items():
            style = dict(color="black", lw=2) if name == "real" else {}
            axes[0, col].plot(lowest_foot_speed(follower, data.skeleton, fps), label=name, **style)
            axes[1, col].plot(torso_lean_per_frame_deg(follower, data.skeleton), label=name, **style)
        axes[0, col].set_title(f"{cls}, held-out sequence {i} (fold {args.fold})")
        axes[0, col].set_ylabel("lower foot, horizontal m/s")
        axes[1, col].set_ylabel("torso lean, degrees")
        axes[1, col].set_xlabel("frame (15 fps)")
    axes[0, 0].legend()
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
