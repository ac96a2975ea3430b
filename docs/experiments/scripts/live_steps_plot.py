"""A picture of how a live follower moves: for a few held-out leaders of the model's fold, each played twice in a row
(pingpong: the second copy backwards), the fastest joint's step from one frame to the next (m), frame by frame, for
the live follower as it ships, live with the returning window's sample alone (`ENSEMBLE_GROWTH` 1e12) in windows of 16
frames (as before), the take made offline in windows, and the recorded follower (its clip, then backwards).

    python docs/experiments/scripts/live_steps_plot.py --leaders 3 --out docs/experiments/data/live-steps.png

Raw network output (no clean-up), seed 0, the leader's true class.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def fastest_step(motion: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> (T-1,) the largest joint displacement from each frame to the next (m)."""
    return np.linalg.norm(np.diff(motion, axis=0), axis=-1).max(1)


def live(model, leader: np.ndarray, label: dict) -> np.ndarray:
    reactor = model.online(label, seed=0)
    frames = [f for f in (reactor.push(x) for x in leader) if f is not None]
    return np.concatenate([np.stack(frames), reactor.flush()])


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.families.diffusion import windows
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(SAMPLE_DEFAULT))
    ap.add_argument("--leaders", type=int, default=3)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    model.raw = True
    held_out = loso_fold(data.subject_pairs, model.held_out_subject).test
    picked = [int(i) for i in held_out if len(data.world(int(i))[0]) >= 30][: args.leaders]
    fig, axes = plt.subplots(len(picked), 1, figsize=(9, 2.4 * len(picked)), sharex=True, squeeze=False)
    shipped = (windows.ONLINE_WINDOW, windows.ENSEMBLE_GROWTH)
    for ax, i in zip(axes[:, 0], picked, strict=True):
        clip, real = data.world(i)
        leader, recorded = np.concatenate([clip, clip[::-1]]), np.concatenate([real, real[::-1]])
        name = data.class_names[data.actions[i]]
        label = {name: 1.0}
        windows.ONLINE_WINDOW, windows.ENSEMBLE_GROWTH = 16, 1e12
        before = live(model, leader, label)
        windows.ONLINE_WINDOW, windows.ENSEMBLE_GROWTH = shipped
        for motion, what, style in ((recorded, "recorded follower", dict(color="0.5", lw=2)),
                                    (model.synthesize(leader, label, seed=0), "offline, in windows", dict(color="tab:green")),
                                    (before, "live before (16 frames, one window a frame)", dict(color="tab:red", ls="--")),
                                    (live(model, leader, label), "live (30 frames, the windows' mean)", dict(color="tab:blue"))):
            ax.plot(fastest_step(motion), label=what, **style)
        ax.set_title(f"{data.sequence_ids[i]} ({name}), played forwards then backwards", fontsize=9)
        ax.set_ylabel("fastest joint's step (m)", fontsize=8)
    axes[-1, 0].set_xlabel("frame (15 fps)")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
