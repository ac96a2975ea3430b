"""A label per body part composed by part at every sampler step (Guidance.part_join) against the part network's own
part terms, on one fold's held-out leaders: the 30 ordered pairs upper:A=1, lower:B=1 read by the fold's body-part
judges, the two-class whole-body mixes, and what a whole-body label costs (nothing: bit-identical). One JSON line per
checkpoint x sampler x seed (docs/experiments/part-join.md).

    IMM_CACHE_DIR=... python docs/experiments/scripts/part_join.py --fold s04 --seeds 0 1 2 \\
        --checkpoints sample_data/imm_diffusion_parts.safetensors sample_data/imm_diffusion.safetensors \\
        --out docs/experiments/data/part-join.jsonl

A whole-label checkpoint is measured with the join only (without it, it takes no label per body part).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def main() -> None:
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--checkpoints", type=Path, nargs="+", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per row here")
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    judges = FoldJudges(data, args.fold, EvalOptions(baselines=(), progress=False))
    n, names = len(judges.leaders), data.class_names
    for path in args.checkpoints:
        model = ReactionModel.load(path)
        prepare_model(model, data, args.fold, EvalOptions(baselines=(), progress=False))
        shipped = model.guidance
        samplers = ([("part terms", shipped)] if model.config.part_labels else []) + [("join", replace(shipped, part_join=True))]
        for seed in args.seeds:
            whole_label = np.eye(len(names), dtype=np.float32)[data.actions[judges.test]]
            reference = model.synthesize_batch_canonical(judges.leaders, whole_label, [seed] * n)
            for name, guidance in samplers:
                start = time.time()
                model.guidance = guidance
                drawn: dict[bytes, list[np.ndarray]] = {}

                def followers(labels: np.ndarray, seed=seed, drawn=drawn, model=model) -> list[np.ndarray]:
                    key = np.ascontiguousarray(labels, np.float32).tobytes()
                    if key not in drawn:
                        drawn[key] = model.synthesize_batch_canonical(judges.leaders, labels, [seed] * n)
                    return drawn[key]

                upper = lambda labels: judges.part_view("upper", followers(labels))  # noqa: E731
                lower = lambda labels: judges.part_view("lower", followers(labels))  # noqa: E731
                whole = lambda labels: judges.follower_view(judges.judge, followers(labels))  # noqa: E731
                pairs = control.part_pair_table(upper, lower, lambda a, b: np.zeros(n, bool), n, names)
                mixes = control.part_mix_table(whole, upper, lower, n, names)
                same = all(np.array_equal(a, b) for a, b in zip(reference, followers(whole_label), strict=True))
                row = {"checkpoint": str(path), "fold": args.fold, "seed": seed, "sampler": name,
                       "part_read": float(np.mean([r["read"] for r in pairs])),
                       "pairs_under_0.1": int(sum(r["read"] < 0.1 for r in pairs)),
                       "per_pair": {f"{r['upper']}/{r['lower']}": round(r["read"], 4) for r in pairs},
                       "mix_whole": float(np.mean([r["whole"] for r in mixes])),
                       "mix_mixed": float(np.mean([r["mixed"] for r in mixes])),
                       "whole_label_bit_identical": same, "seconds": round(time.time() - start, 1)}
                print(json.dumps(row), flush=True)
                if args.out:
                    with open(args.out, "a") as fh:
                        fh.write(json.dumps(row) + "\n")
            model.guidance = shipped


if __name__ == "__main__":
    main()
