"""One window of a long take, shifted by 4 frames: how far its first new frame lands from the last frame given to it.

For each of the first 16 held-out leaders of at least 24 frames (true class, seed 0, raw network output): the
window of frames 0-15 is sampled alone; then the window of frames 4-19 is sampled with frames 4-15 of that follower
given, in its own canonical frame ("own", standardized on frames 4-13) and in the first window's ("kept"); and the first
window again with its own first 12 frames given ("same"). Printed: the mean joint distance between the first new
frame and the last given one, averaged over leaders (for "same", beyond the step the first window itself made there).

    python docs/experiments/scripts/window_seam.py [--checkpoint CK] [--continue-level 1.0 0.6]
"""

from __future__ import annotations

import argparse

import numpy as np

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.data.canonical import CanonicalFrame
from imm_model.data.splits import loso_fold
from imm_model.families.diffusion import windows
from imm_model.families.diffusion.sampler import initial_noise, leader_noise
from imm_model.inference import ReactionModel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(paths.SAMPLE_DEFAULT))
    ap.add_argument("--continue-level", type=float, nargs="+", default=[1.0, 0.6])
    args = ap.parse_args()
    data = load_any(paths.SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    model.raw = True
    width, d = 16, model.config.pose_dim
    for level in args.continue_level:
        windows.CONTINUE_LEVEL = level
        out = {"own": [], "kept": [], "same": []}
        for i in loso_fold(data.subject_pairs, model.held_out_subject).test[:16]:
            leader = model.prepare_leader(data.world(i)[0]).canonical.astype(np.float64)
            if len(leader) < 24:
                continue
            label = model._label_input(model.label_vector({data.class_names[data.actions[i]]: 1.0})[None])[0]
            noise, z = initial_noise(0, len(leader), d), leader_noise(0, len(leader), d)
            first_frame = CanonicalFrame.from_leader(leader[:width], model.skeleton, model.canonical_mode)
            first = windows.window_follower(model, leader[:width], np.zeros((width, 15, 3)), 0, label, 0, noise[:width],
                                            z[:width], first_frame)
            again = windows.window_follower(model, leader[:width], first, 12, label, 0, noise[:width], z[:width], first_frame)
            out["same"].append(np.linalg.norm(again[12] - again[11], axis=-1).mean()
                               - np.linalg.norm(first[12] - first[11], axis=-1).mean())
            given = np.zeros((width, 15, 3))
            given[:12] = first[4:16]
            shifted = slice(4, 4 + width)
            for name, frame in (("own", CanonicalFrame.from_leader(leader[shifted], model.skeleton, model.canonical_mode)),
                                ("kept", CanonicalFrame(np.full(width, first_frame.yaw[0]),
                                                        np.repeat(first_frame.origin[:1], width, 0), first_frame.mode))):
                made = windows.window_follower(model, leader[shifted], given, 12, label, 0, noise[shifted], z[shifted], frame)
                out[name].append(np.linalg.norm(made[12] - first[15], axis=-1).mean())
        print(f"{args.checkpoint}: continue level {level:g}: "
              + ", ".join(f"{k} {np.mean(v):.3f} m" for k, v in out.items()) + f" ({len(out['own'])} leaders)", flush=True)


if __name__ == "__main__":
    main()
