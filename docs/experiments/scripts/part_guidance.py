"""The part-pair reading of a part model at other sampler guidance: for each ordered pair (A upper, B lower) the share
of the fold's held-out leaders whose upper-body judge reads A and lower-body judge reads B (each >= 0.4), as
`imm evaluate`'s part table (evaluation/control.py `part_pair_table`), for a grid of label strengths and guidance
intervals; the real part composites' share beside it. Only the part table: the other figures need the whole fold
evaluation (`diffusion_fold.py --label-scale ... --guided-below ...`).

    python docs/experiments/scripts/part_guidance.py --checkpoint runs/parts/seed0/fold-s04/final.safetensors \
        --fold s04 --label-scale 3 5 --guided-below 0.3 1
"""

from __future__ import annotations

import argparse
import itertools
import json
from dataclasses import replace

import numpy as np
import torch


def main() -> None:
    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, real_part_readings
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--label-scale", type=float, nargs="+", default=[3.0])
    ap.add_argument("--guided-below", type=float, nargs="+", default=[0.3])
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    judges = FoldJudges(data, args.fold, EvalOptions(progress=False))
    real = real_part_readings(data, judges)
    model = ReactionModel.load(args.checkpoint)
    n = len(judges.leaders)
    for scale, below in itertools.product(args.label_scale, args.guided_below):
        model.guidance = replace(model.guidance, label_scale=scale, guided_below=below)

        def followers(labels: np.ndarray, cache: dict[bytes, list] = {}) -> list:  # noqa: B006 - one cache per setting
            key = labels.tobytes()
            if key not in cache:
                cache[key] = model.synthesize_batch_canonical(judges.leaders, labels)
            return cache[key]

        rows = control.part_pair_table(lambda lab: judges.part_view("upper", followers(lab)),
                                       lambda lab: judges.part_view("lower", followers(lab)),
                                       lambda a, b: real[a, b], n, data.class_names)
        read, ref = np.mean([r["read"] for r in rows]), np.mean([r["real"] for r in rows])
        print(json.dumps({"checkpoint": args.checkpoint, "fold": args.fold, "label_scale": scale, "guided_below": below,
                          "part_read": round(float(read), 4), "part_real": round(float(ref), 4),
                          "worst_ratio": round(min(r["read"] / r["real"] for r in rows if r["real"] > 0), 4),
                          "pairs_under_0.4x": int(sum(r["read"] < 0.4 * r["real"] for r in rows))}), flush=True)


if __name__ == "__main__":
    main()
