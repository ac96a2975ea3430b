"""Why the trunk and arms of a hug and the legs of a punch read less as their class than real held-out followers do:
per class, the part judges' reading of the default diffusion model's whole-body reactions (on the leaders of that
class, "own", and on all held-out leaders, "all") beside the real held-out followers', under sampler variants
(guidance overrides), with what the hands do: the closest a hand comes to the leader's torso, how far apart the two
hands are at that frame, and the arms' share of the body's motion around its centre. One JSON line per variant
(docs/experiments/part-realism.md).

    IMM_CACHE_DIR=... OMP_NUM_THREADS=1 python docs/experiments/scripts/part_realism_sampler.py --fold s04 --seeds 0 1 2 \\
        --variant shipped --variant label_scale=5 --variant guided_below=1 --variant memory_level=0.6 \\
        --out docs/experiments/data/part-realism.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np


def hands(leaders: list[np.ndarray], followers: list[np.ndarray], skeleton) -> dict[str, float]:
    """Means over the pairs: the closest a follower hand comes to the leader's torso (m), the hands' distance apart at
    that frame (m), and the trunk and arms' share of the motion around the body centre."""
    names = skeleton.joint_names
    lh, rh, torso = names.index("left_hand"), names.index("right_hand"), names.index("torso")
    legs, centre = skeleton.leg_joints, list(skeleton.root_neighbours)
    upper = [j for j in range(skeleton.num_joints) if j not in legs]
    reach, apart, share = [], [], []
    for a, b in zip(leaders, followers, strict=True):
        d = np.minimum(np.linalg.norm(b[:, lh] - a[:, torso], axis=-1), np.linalg.norm(b[:, rh] - a[:, torso], axis=-1))
        t = int(d.argmin())
        reach.append(d[t])
        apart.append(np.linalg.norm(b[t, lh] - b[t, rh]))
        rel = b - b[:, centre].mean(1, keepdims=True)
        speed = np.linalg.norm(np.diff(rel, axis=0), axis=-1)
        share.append(speed[:, upper].sum() / (speed.sum() + 1e-9))
    return {"hand_to_torso_m": float(np.mean(reach)), "hands_apart_m": float(np.mean(apart)), "arm_share": float(np.mean(share))}


def main() -> None:
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", default="s04")
    ap.add_argument("--checkpoint", type=Path, default=SAMPLE_DEFAULT)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--variant", action="append", default=[],
                    help="'shipped' or comma-separated guidance overrides, e.g. label_scale=5,guided_below=1")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    names, c = data.class_names, len(data.class_names)
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    model = ReactionModel.load(args.checkpoint)
    if model.held_out_subject != args.fold:
        sys.exit(f"{args.checkpoint} holds out {model.held_out_subject}, not {args.fold}")
    prepare_model(model, data, args.fold, opts)
    y, n = data.actions[judges.test], len(judges.leaders)
    reals = [data.canonical(int(i))[1] for i in judges.test]
    real_upper, real_lower = judges.part_view("upper", reals), judges.part_view("lower", reals)
    real_rows = {"variant": "real held-out followers",
                 **{names[k]: hands([judges.leaders[i] for i in np.flatnonzero(y == k)], [reals[i] for i in np.flatnonzero(y == k)],
                                    data.skeleton) for k in range(c)}}
    print(json.dumps(real_rows), flush=True)
    shipped = model.guidance
    for variant in args.variant or ["shipped"]:
        overrides = {} if variant == "shipped" else {k: float(v) for k, v in (kv.split("=") for kv in variant.split(","))}
        model.guidance = replace(shipped, **overrides)
        if model.guidance.uses_memory:
            model.attach_memory(data)
        for seed in args.seeds:
            drawn: dict[bytes, list[np.ndarray]] = {}

            def followers(labels: np.ndarray, seed=seed, drawn=drawn) -> list[np.ndarray]:
                key = np.ascontiguousarray(labels, np.float32).tobytes()
                if key not in drawn:
                    drawn[key] = model.synthesize_batch_canonical(judges.leaders, labels, [seed] * n)
                return drawn[key]

            realism = control.part_realism(lambda labels: judges.part_view("upper", followers(labels)),
                                           lambda labels: judges.part_view("lower", followers(labels)),
                                           y, real_upper, real_lower, names)
            geometry = {}
            for k in range(c):
                own = np.flatnonzero(y == k)
                made = followers(np.eye(c, dtype=np.float32)[np.full(n, k)])
                geometry[names[k]] = hands([judges.leaders[i] for i in own], [made[i] for i in own], data.skeleton)
            row = {"fold": args.fold, "variant": variant, "seed": seed,
                   "realism": {f"{r['class']}/{r['part']}": [round(r["own"], 4), round(r["all"], 4), round(r["real"], 4)]
                               for r in realism},
                   **geometry}
            print(json.dumps(row), flush=True)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
    if args.out:
        with open(args.out, "a") as fh:
            fh.write(json.dumps(real_rows) + "\n")


if __name__ == "__main__":
    main()
