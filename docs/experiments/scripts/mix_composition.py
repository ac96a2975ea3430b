"""Compare the diffusion sampler's label compositions ("sum", "parts" with a routing power) on one LOSO fold: the
+1/+1 mix table by the whole-body and body-part judges, single-label adherence and avoid by the whole-body judge, and
two realism figures of the mixed reactions, one JSON line per composition x sampler seed (docs/experiments/mix-composition.md).

    python docs/experiments/scripts/mix_composition.py --checkpoint sample_data/imm_diffusion.safetensors --fold s04 \\
        --variants sum parts:2 parts:8 relative:4 --seeds 0 --out docs/experiments/data/mix-composition.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from itertools import combinations
from pathlib import Path

import numpy as np


def variant(spec: str) -> dict:
    """"sum", "parts:P" or "relative:P" -> Guidance overrides. "relative" (this script only) routes by each class's
    own profile over the body: its per-part magnitudes divided by its largest before the classes compete."""
    name, _, power = spec.partition(":")
    if name == "sum" and not power:
        return {"composition": "sum"}
    if name in ("parts", "relative"):
        return {"composition": "parts", "routing_power": float(power or 2.0)}
    raise SystemExit(f"mix_composition: error: unknown variant {spec!r} (sum, parts:P, relative:P)")


def bone_error_cm(followers: list[np.ndarray], skeleton, lengths: np.ndarray) -> float:
    """Mean |bone length - the training followers' length| over bones and frames, centimetres."""
    return float(100 * np.mean(np.concatenate([np.abs(skeleton.bone_lengths(f) - lengths) for f in followers])))


def jitter_m(followers: list[np.ndarray], skeleton) -> float:
    """Mean norm of the joints' second difference relative to the body centre, metres a frame."""
    vals = []
    for f in followers:
        rel = f - f[:, skeleton.root_neighbours].mean(1, keepdims=True)
        vals.append(np.linalg.norm(rel[2:] - 2 * rel[1:-1] + rel[:-2], axis=-1).mean())
    return float(np.mean(vals))


def main() -> None:
    import torch

    from imm_model import cache
    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import EvalOptions, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.model import classifier as classifiers
    from imm_model.model import classifier_config as cc
    from imm_model.model import diffusion_sampler
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--variants", nargs="+", default=["sum", "parts:2"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per variant x seed here")
    args = ap.parse_args()
    variants = [(v, variant(v)) for v in args.variants]
    absolute = diffusion_sampler.part_responsibilities

    def relative(rms: np.ndarray, weights: np.ndarray, power: float) -> np.ndarray:
        return absolute(rms / np.maximum(rms.max(-1, keepdims=True), 1e-30), weights, power)  # each class's own profile
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    prepare_model(model, data, args.fold, EvalOptions(baselines=(), progress=False))
    shipped = model.guidance
    test = loso_fold(data.subject_pairs, args.fold).test
    leaders = [data.canonical(int(i))[0] for i in test]
    y, names, c = data.actions[test], data.class_names, len(data.class_names)
    judges = {part: cache.fold_classifier(cfg, data, args.fold, False)
              for part, cfg in (("follower", cc.FOLLOWER_JUDGE), ("upper", cc.UPPER_JUDGE), ("lower", cc.LOWER_JUDGE))}
    real_acc = {part: float((classifiers.classify(clf, classifiers.motion_inputs(
        leaders, [data.canonical(int(i))[1] for i in test], part))[0].argmax(-1) == y).mean()) for part, clf in judges.items()}
    lengths = np.asarray(model.bone_lengths)

    for seed in args.seeds:
        for spec, changes in variants:
            model.guidance = replace(shipped, **changes)
            diffusion_sampler.part_responsibilities = relative if spec.startswith("relative") else absolute
            start = time.time()
            drawn: dict[bytes, tuple[list[np.ndarray], list[np.ndarray]]] = {}

            def followers(labels: np.ndarray, seed=seed, drawn=drawn) -> tuple[list[np.ndarray], list[np.ndarray]]:
                key = np.ascontiguousarray(labels, np.float32).tobytes()
                if key not in drawn:
                    raw = model._network(leaders, model._label_array(labels, len(leaders)), [seed] * len(leaders))
                    drawn[key] = raw, [model._clean(f) for f in raw]
                return drawn[key]

            def judge(part: str, labels: np.ndarray) -> np.ndarray:
                return classifiers.classify(judges[part], classifiers.motion_inputs(leaders, followers(labels)[1], part))[0]

            mix = control.part_mix_table(lambda lb: judge("follower", lb), lambda lb: judge("upper", lb),
                                         lambda lb: judge("lower", lb), len(y), names)
            mix_labels = [np.zeros((len(y), c), np.float32) for _ in mix]
            for labels, pair in zip(mix_labels, combinations(range(c), 2), strict=True):
                labels[:, list(pair)] = 1.0
            raw_mix = [f for lb in mix_labels for f in followers(lb)[0]]
            clean_mix = [f for lb in mix_labels for f in followers(lb)[1]]
            matrix, _ = control.adherence_matrix(lambda lb: judge("follower", lb), y, c)
            avoid = control.avoid_effect(lambda lb: judge("follower", lb), y, c)
            singles = float(sum(np.abs(f.astype(np.float64)).sum() for k in range(c)
                                for f in followers(np.eye(c, dtype=np.float32)[[k] * len(y)])[1]))
            row = {"checkpoint": str(args.checkpoint), "fold": args.fold, "seed": seed, "variant": spec,
                   "guidance": model.guidance.to_dict(), "judge_real_accuracy": real_acc,
                   "mix_whole": float(np.mean([r["whole"] for r in mix])), "mix_parts": float(np.mean([r["parts"] for r in mix])),
                   "mix_mixed": float(np.mean([r["mixed"] for r in mix])),
                   "mix_worst_pair": float(min(r["mixed"] for r in mix)),
                   "mix_worst": min(mix, key=lambda r: r["mixed"])["pair"],
                   "pairs": {"+".join(r["pair"]): round(r["mixed"], 3) for r in mix},
                   "off_label": control.off_diagonal_mean(matrix), "true_label": float(np.nanmean(np.diag(matrix))),
                   "avoid_change": avoid["change"], "avoid_share_lowered": avoid["share_lowered"],
                   "single_label_checksum": singles,
                   "mix_raw_bone_error_cm": bone_error_cm(raw_mix, model.skeleton, lengths),
                   "mix_jitter_m": jitter_m(clean_mix, model.skeleton),
                   "seconds": round(time.time() - start, 1)}
            print(json.dumps(row), flush=True)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
