"""Score reaction models on LOSO folds with `imm evaluate`'s own fold evaluation, one JSON line per model x fold x
guidance, for the diffusion experiments (docs/experiments/).

    python docs/experiments/scripts/diffusion_fold.py --checkpoint runs/d/fold-s04/final.safetensors --fold s04 \\
        --label-scale 2 3 --eta 0.5 --out results.jsonl
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np


def record(row: dict, out: Path | None) -> None:
    """Print one result row as a JSON line, and append it to `out` when given (the experiments' data files)."""
    print(json.dumps(row), flush=True)
    if out:
        with open(out, "a") as fh:
            fh.write(json.dumps(row) + "\n")


def headline(result: dict) -> dict:
    """The numbers the diffusion model's bar reads, from one evaluate_fold result."""
    m, nn1 = result["model"], result["baselines"].get("nn1", {})
    matrix = np.array(result["adherence_matrix_judge"], dtype=float)
    mixes = result["mix_judge"]
    p = m["plausibility"]
    out = {
        "afd": float(np.mean([c["afd"] for c in m["classes"].values()])),
        "afd_nn1": float(np.mean([c["afd"] for c in nn1["classes"].values()])) if nn1 else None,
        "fid": m["fid"], "fid_nn1": nn1.get("fid"), "kid": m["kid"], "kid_nn1": nn1.get("kid"),
        "judge_real_accuracy": result["classifier"]["real_accuracy"]["follower_judge"],
        "off_label": result["adherence_off_diagonal_judge"], "true_label": float(np.nanmean(np.diag(matrix))),
        "mix_both_read": float(np.mean([r["both_read"] for r in mixes])),
        "mix_pairs_read": int(sum(r["first"] >= 0.25 and r["second"] >= 0.25 for r in mixes)),
        "avoid_change": result["avoid_judge"]["change"], "avoid_share_lowered": result["avoid_judge"]["share_lowered"],
        "mix_whole": float(np.mean([r["whole"] for r in result["mix_parts"]])),
        "mix_parts": float(np.mean([r["parts"] for r in result["mix_parts"]])),
        "mix_mixed": float(np.mean([r["mixed"] for r in result["mix_parts"]])),
        "mix_worst_pair": float(min(r["mixed"] for r in result["mix_parts"])),
        "mix_per_pair": {"+".join(r["pair"]): round(float(r["mixed"]), 4) for r in result["mix_parts"]},
        "upper_judge_accuracy": result["classifier"]["real_accuracy"]["upper_judge"],
        "lower_judge_accuracy": result["classifier"]["real_accuracy"]["lower_judge"],
        "interior_limb_speed_ratio": p["interior_limb_speed_ratio"], "lean_error_deg": p["lean_error_deg"],
        # root-relative limb speed, and the same with the generated motion smoothed like the real: jitter lowers the
        # second below the first
        "limb_speed_ratio": p["limb_speed_ratio"], "smooth_limb_speed_ratio": p["smooth_limb_speed_ratio"],
        "bone_error_cm": p["bone_error_cm"], "foot_skate_mps": p["foot_skate_mps"], "jitter_ratio": p["jitter_ratio"],
        "interpenetration": p["interpenetration"],
        "real_interpenetration": p["real_interpenetration"],
        "start_root_m": m["afd_parts"]["start_root_m"], "limb_m": m["afd_parts"]["limb_m"],
    }
    if "part_pairs" in result:  # a model with a label per body part: the ordered pairs and the part negations
        pairs = result["part_pairs"]
        ratios = [r["read"] / r["real"] for r in pairs if r["real"] > 0]
        out |= {"part_read": float(np.mean([r["read"] for r in pairs])), "part_real": float(np.nanmean([r["real"] for r in pairs])),
                "part_real_nearest_training": float(np.mean([r.get("real_nearest_training", np.nan) for r in pairs])),
                "part_worst_ratio": float(min(ratios)) if ratios else None,
                "part_per_pair": {f"{r['upper']}/{r['lower']}": [round(r["read"], 4), round(r["real"], 4)] for r in pairs},
                "part_avoid_lower_share": result["part_avoid"]["lower"]["share_lowered"],
                "part_avoid_upper_share": result["part_avoid"]["upper"]["share_lowered"]}
    if "part_realism" in result:  # each class on each part: [leaders of the class, all leaders, real held-out followers]
        out["part_realism"] = {f"{r['class']}/{r['part']}": [round(r["own"], 4), round(r["all"], 4), round(r["real"], 4)]
                               for r in result["part_realism"]}
    if "variations" in result:
        v = result["variations"]
        out |= {"multimodality": v["multimodality"], "real_class_diversity": v["real_class_diversity"],
                "real_same_leader_diversity": v["real_same_leader_diversity"],
                "multimodality_m": v["multimodality_m"], "afd_best_of_5": v["afd_best_of_n"]}
    return out


def main(argv: list[str] | None = None, adapt=None, extra: dict | None = None) -> None:
    """`argv` as on the command line; `adapt(model)`, if given, changes each loaded model before it is scored (an
    experiment's sampler); `extra` is added to every row it records."""
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation.loso import EvalOptions, evaluate_fold
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--label-scale", type=float, nargs="*", default=[], help="guidance strengths to score (diffusion)")
    ap.add_argument("--leader-scale", type=float, default=None)
    ap.add_argument("--eta", type=float, default=None, help="DDIM's eta: 0 deterministic steps, up to 1 (diffusion)")
    ap.add_argument("--sample-steps", type=int, default=None)
    ap.add_argument("--guided-below", type=float, default=None, help="noise level t/(T-1) under which the label is guided")
    ap.add_argument("--leader-below", type=float, default=None, help="noise level t/(T-1) under which the leader conditions")
    ap.add_argument("--leader-noise", type=float, nargs="*", default=[],
                    help="noise levels t/(T-1) on the leader to score (models trained with noised leaders)")
    ap.add_argument("--memory-level", type=float, nargs="*", default=[],
                    help="noise levels t/(T-1) to start the sampler at from the reaction memory (the fold's training pairs)")
    ap.add_argument("--join-each-step", action="store_true",
                    help="a label per body part joined at every sampler step rather than the parts' reactions after it")
    ap.add_argument("--smoothing", type=float, default=None,
                    help="each follower blended this far towards its smoothing in time (Guidance.smoothing)")
    ap.add_argument("--baselines", default="nn1")
    ap.add_argument("--raw", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per run here")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    opts = EvalOptions(baselines=tuple(b for b in args.baselines.split(",") if b), progress=False, raw=args.raw)
    grid = itertools.product(args.label_scale or [None], args.leader_noise or [None], args.memory_level or [None])
    for scale, leader_noise, memory_level in grid:
        model = ReactionModel.load(args.checkpoint)
        if adapt is not None:
            adapt(model)
        if model.settings.seed:
            changes = {k: v for k, v in (("label_scale", scale), ("leader_scale", args.leader_scale),
                                         ("sample_steps", args.sample_steps), ("eta", args.eta),
                                         ("guided_below", args.guided_below), ("leader_below", args.leader_below),
                                         ("leader_noise", leader_noise), ("memory_level", memory_level),
                                         ("join_outputs", False if args.join_each_step else None),
                                         ("smoothing", args.smoothing))
                       if v is not None}
            try:
                model.guidance = replace(model.guidance, **changes)
            except ValueError as err:
                print(err, file=sys.stderr)
                raise SystemExit(2) from None
            if model.guidance.uses_memory:
                model.attach_memory(data)  # the fold's training pairs: the checkpoint's held-out subject is never in it
        row = {"checkpoint": str(args.checkpoint), "fold": args.fold, "raw": args.raw,
               "guidance": model.guidance.to_dict() if model.settings.seed else None}
        row |= headline(evaluate_fold(model, data, args.fold, opts))
        record(row | (extra or {}), args.out)


if __name__ == "__main__":
    main()
