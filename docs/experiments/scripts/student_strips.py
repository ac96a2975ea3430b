"""A picture of what the student's label critic changes: one held-out leader, a few labels, and for each model the
follower (and the leader, grey) at evenly spaced frames, seen from the side, seed 0 as `imm generate` gives it.

    python docs/experiments/scripts/student_strips.py --fold s04 --sequence-index 0 --labels pushing kicking hugging \\
        --model "teacher, 7 steps=sample_data/imm_diffusion.safetensors" \\
        --model "student, before=runs/student/fold-s04/final.safetensors" \\
        --model "student + label critic=sample_data/imm_diffusion_student.safetensors" \\
        --out docs/experiments/data/student-strips.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", default="s04")
    ap.add_argument("--sequence-index", type=int, default=0, help="which of the fold's held-out sequences")
    ap.add_argument("--labels", nargs="+", default=["pushing", "kicking", "hugging"],
                    help="each a class, or keys at 1 joined by commas (a mix, or a label per body part: upper:A,lower:B)")
    ap.add_argument("--model", action="append", required=True, help="NAME=CHECKPOINT")
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    i = int(loso_fold(data.subject_pairs, args.fold).test[args.sequence_index])
    leader, real = data.world(i)
    models = [(name, ReactionModel.load(path)) for name, path in (m.split("=", 1) for m in args.model)]
    sk = data.skeleton
    up, side = sk.vertical_axis, [a for a in range(3) if a != sk.vertical_axis][0]
    frames = np.linspace(0, len(leader) - 1, args.frames).round().astype(int)
    rows = [(f"recorded ({data.class_names[data.actions[i]]})", real)]
    rows += [(f"{name}: {label}", model.synthesize(leader, dict.fromkeys(label.split(","), 1.0), seed=0))
             for label in args.labels for name, model in models]
    fig, axes = plt.subplots(len(rows), 1, figsize=(2.0 * args.frames, 1.9 * len(rows)), squeeze=False)
    span = np.ptp(np.concatenate([leader, real])[..., side]) + 1.0
    for ax, (title, follower) in zip(axes[:, 0], rows, strict=True):
        for k, t in enumerate(frames):
            for who, color in ((leader, "0.6"), (follower, "tab:blue")):
                pose = who[t]
                for a, b in sk.bones:
                    ax.plot([pose[a, side] + k * span, pose[b, side] + k * span], [pose[a, up], pose[b, up]], color=color, lw=1.4)
        ax.set_title(title, fontsize=9, loc="left")
        ax.set_aspect("equal")
        ax.axis("off")
    fig.suptitle(f"held-out {data.sequence_ids[i]} ({args.fold}), frames {', '.join(map(str, frames))}; leader grey", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
