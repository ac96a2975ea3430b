"""A picture of the diffusion model's variations: for one held-out leader per class, the follower's root and right
hand seen from above for five sampler seeds, one column per sampler setting, beside the real follower and the leader.

    python docs/experiments/scripts/variations_plot.py --checkpoint sample_data/imm_diffusion.safetensors --fold s04 \\
        --classes kicking pushing hugging --setting "leader every step=" --setting "leader from the second step=leader_below=0.95" \\
        --out docs/experiments/data/variations.png

A setting is NAME=FIELD=VALUE[,FIELD=VALUE...] of Guidance fields over the checkpoint's own (empty: as shipped).
Followers are cleaned up as `imm generate` gives them; the true label at +1.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np


def parse_setting(text: str) -> tuple[str, dict[str, float]]:
    name, _, fields = text.partition("=")
    changes = dict(f.split("=", 1) for f in fields.split(",") if f)
    return name, {k: float(v) for k, v in changes.items()}


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--classes", nargs="+", default=["kicking", "pushing", "hugging"])
    ap.add_argument("--setting", action="append", required=True, help="NAME=FIELD=VALUE[,...]")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    held_out = loso_fold(data.subject_pairs, args.fold).test
    sk = data.skeleton
    root, hand = sk.joint_names.index("torso"), sk.joint_names.index("right_hand")
    ground = [a for a in range(3) if a != sk.vertical_axis]
    settings = [parse_setting(s) for s in args.setting]
    models = []  # one model per setting, its guidance replaced
    for _, changes in settings:
        model = ReactionModel.load(args.checkpoint)
        model.guidance = replace(model.guidance, **changes)
        models.append(model)
    fig, axes = plt.subplots(len(args.classes), len(settings), figsize=(4.2 * len(settings), 3.6 * len(args.classes)),
                             squeeze=False)
    colors = plt.cm.viridis(np.linspace(0, 0.9, args.seeds))
    for row, cls in enumerate(args.classes):
        c = data.class_names.index(cls)
        i = int(next(j for j in held_out if data.actions[j] == c))  # the fold's first sequence of the class
        leader, real = data.canonical(i)
        label = np.eye(len(data.class_names), dtype=np.float32)[c]
        for col, ((name, _), model) in enumerate(zip(settings, models, strict=True)):
            followers = model.synthesize_batch_canonical([leader] * args.seeds, np.tile(label, (args.seeds, 1)),
                                                         list(range(args.seeds)))
            ax = axes[row, col]
            ax.plot(*leader[:, root][:, ground].T, color="0.6", lw=2, label="leader (torso)")
            for k, f in enumerate(followers):
                ax.plot(*f[:, root][:, ground].T, color=colors[k], lw=1.5, label="samples (torso, hand)" if k == 0 else None)
                ax.plot(*f[:, hand][:, ground].T, color=colors[k], lw=0.8, ls="--")
            ax.plot(*real[:, root][:, ground].T, color="k", lw=2, label="real (torso, hand)")
            ax.plot(*real[:, hand][:, ground].T, color="k", lw=0.8, ls="--")
            spread = np.mean([np.linalg.norm(a - b, axis=-1).mean() for k, a in enumerate(followers)
                              for b in followers[k + 1:]])
            ax.set_title(f"{cls}: {name}\nsamples {spread:.2f} m apart per joint and frame", fontsize=9)
            ax.set_aspect("equal", adjustable="datalim")
            ax.tick_params(labelsize=7)
            if row == 0 and col == 0:
                ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"{Path(args.checkpoint).name}, fold {args.fold}: {args.seeds} seeds seen from above (metres)", fontsize=10)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
