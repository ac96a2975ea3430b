"""Does a low-variance placement with sampled limbs lower the diffusion model's AFD? The diffusion model's follower is
placed, at every sampler step, where the deterministic GAN places it (horizontally; its body centre, the mean of the
root's neighbours), and its limbs are sampled as before: an imputation of the placement (as MDM's and GMD's trajectory
conditioning), with no retraining. One JSON line per mode (evaluation/report.py FoldFigures) for
docs/experiments/placement.md.

    python docs/experiments/scripts/placement_imputation.py --fold s04 --mode offset path --out results.jsonl

Modes: `offset` moves the whole sequence by one horizontal offset so that its mean body centre is the GAN's (the
diffusion model's own path kept); `path` moves every frame onto the GAN's body-centre path; `none` is the diffusion
model as shipped.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def imputing_sampler(model, gan, mode: str):
    """A sampler for `model.sampler` (the diffusion model's sampling loop) that takes the placement from `gan` at every
    step (see the module's docstring)."""
    from imm_model.families.diffusion.sampler import sample

    skeleton = model.skeleton
    body, up = list(skeleton.root_neighbours), skeleton.vertical_axis
    horizontal = np.array([a != up for a in range(3)], np.float32)
    mean, std = model.weights["follower_mean"], model.weights["follower_std"]
    joints = skeleton.num_joints

    def centres(pos: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(..., B, T, J, 3) -> body centre (..., B, T, 3), or its mean over the real frames for `offset`."""
        c = pos[..., body, :].mean(-2)
        if mode == "offset":
            w = mask[..., None].astype(np.float32)
            c = np.broadcast_to((c * w).sum(-2, keepdims=True) / w.sum(-2, keepdims=True), c.shape)
        return c

    def sampler(inner, x, mask, labels, noise, guidance, steps, seeds=None, **network):
        b, t = mask.shape
        lengths = mask.sum(1)
        # the canonical leaders back from the sampler's normalized ones, and the GAN's own followers for them
        leaders = [(x[k, :n] * model.weights["leader_std"] + model.weights["leader_mean"]).reshape(n, joints, 3)
                   for k, n in enumerate(lengths)]
        gan.raw = True
        target = np.zeros((b, t, joints, 3), np.float32)
        for k, f in enumerate(gan.synthesize_batch_canonical(leaders, labels, seeds)):
            target[k, : len(f)] = f
        goal = centres(target, mask)  # (B, T, 3) metres

        def denoise(x_t, step, *rest):
            x0 = inner(x_t, step, *rest)  # (reps * B, T, D) normalized, one block of B rows per term
            pos = (x0 * std + mean).reshape(-1, b, t, joints, 3)
            # each term moved onto the goal, so the composed x0 (goal + sum of weighted differences) is there too
            shift = (goal - centres(pos, mask)) * horizontal
            pos = pos + shift[..., None, :]
            return ((pos.reshape(-1, b, t, 3 * joints) - mean) / std * mask[..., None]).reshape(x0.shape).astype(np.float32)

        return sample(denoise, x, mask, labels, noise, guidance, steps, seeds=seeds, **network)

    return sampler


def main() -> None:
    import torch
    from diffusion_fold import record  # the script beside this one

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation.loso import EvalOptions, evaluate_fold
    from imm_model.evaluation.report import FoldFigures
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DIFFUSION, SAMPLE_GAN

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=SAMPLE_DIFFUSION)
    ap.add_argument("--gan", type=Path, default=SAMPLE_GAN, help="the placement's model (same held-out fold)")
    ap.add_argument("--fold", required=True)
    ap.add_argument("--mode", nargs="+", choices=("none", "offset", "path"), default=["offset"])
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per mode here")
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    gan = ReactionModel.load(args.gan)
    for mode in args.mode:
        model = ReactionModel.load(args.checkpoint)
        if mode != "none":
            if model.settings.spread:
                model.spread = 0.0  # the imputation reads the clean leader
            model.sampler = imputing_sampler(model, gan, mode)
        result = evaluate_fold(model, data, args.fold, EvalOptions(baselines=("nn1",), progress=False))
        row = {"checkpoint": str(args.checkpoint), "gan": str(args.gan), "fold": args.fold, "mode": mode,
               "guidance": model.guidance.to_dict(), "first_frame_root_m": result["model"]["afd_parts"]["start_root_m"],
               "limb_m": result["model"]["afd_parts"]["limb_m"]} | FoldFigures.of(result).flat()
        record(row, args.out)


if __name__ == "__main__":
    main()
