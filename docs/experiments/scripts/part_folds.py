"""Labels per body part and two-class mixes on every LOSO fold, the default diffusion model with its sampler's join by
part (Guidance.part_join): the 30 ordered part pairs upper:A=1, lower:B=1 read by the fold's body-part judges beside
composites of held-out followers (motion no judge saw); part realism (each class asked on the whole body, read on
each part, beside the real held-out followers); and the 15 whole-body two-class mixes A+B read as both by the
whole-body judge, composed by the sum rule (as shipped) and by part (A's trunk and arms on B's legs, the class
whose training followers move their arms more on top, `training.part_mix.upper_shares`; and the other way round).
Each part branch's values may be multiplied (`--branch-scales`), and the parts' reactions joined rather than their
predictions at every step (`--join-outputs`, Guidance.join_outputs). One JSON line per fold x seed x branch scale
(docs/experiments/part-folds.md).

    IMM_CACHE_DIR=... OMP_NUM_THREADS=1 python docs/experiments/scripts/part_folds.py \\
        --folds s01 s03 s04 s02 s05 s06 s07 --seeds 0 1 --join-outputs off on \\
        --checkpoint-pattern runs/diff-{fold}/fold-{fold}/final.safetensors \\
        --out docs/experiments/data/part-folds.jsonl

The fold whose checkpoint is missing under the pattern takes the bundled default if that model's held-out subject is
the fold (s04), else it is skipped with a line on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from itertools import combinations
from pathlib import Path

import numpy as np


def main() -> None:
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, held_out_part_readings, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT
    from imm_model.training.part_mix import upper_shares

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--folds", nargs="+", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--branch-scales", type=float, nargs="+", default=[1.0],
                    help="multiply each part branch's values by these (1: as the user asked)")
    ap.add_argument("--join-outputs", choices=("off", "on"), nargs="+", default=[None],
                    help="the sampler's Guidance.join_outputs for each variant (default: the checkpoint's)")
    ap.add_argument("--checkpoint-pattern", default="/work/runs/diff-{fold}/fold-{fold}/final.safetensors")
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per row here")
    args = ap.parse_args()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    c = len(data.class_names)
    opts = EvalOptions(baselines=(), progress=False)
    for seed in args.seeds:
        for fold in args.folds:
            path = Path(args.checkpoint_pattern.format(fold=fold))
            if not path.exists():
                path = SAMPLE_DEFAULT
            model = ReactionModel.load(path)
            if model.held_out_subject != fold:
                print(f"{fold}: no checkpoint held out on it ({path} holds out {model.held_out_subject})", file=sys.stderr)
                continue
            judges = FoldJudges(data, fold, opts)
            prepare_model(model, data, fold, opts)
            y = data.actions[judges.test]
            held_out = held_out_part_readings(data, judges)
            train = judges.train
            shares = upper_shares([data.canonical(int(i))[1] for i in train], data.actions[train], c, data.skeleton).numpy()
            reals = [data.canonical(int(i))[1] for i in judges.test]
            real_upper, real_lower = judges.part_view("upper", reals), judges.part_view("lower", reals)
            shipped = model.guidance
            for k, outputs in ((k, j) for k in args.branch_scales for j in args.join_outputs):
                model.guidance = shipped if outputs is None else replace(shipped, join_outputs=outputs == "on")
                start = time.time()
                out = {"checkpoint": str(path), "fold": fold, "seed": seed, "branch_scale": k,
                       "join_outputs": model.guidance.join_outputs,
                       **measure(Reader(model, judges, seed, k), held_out, shares, y, real_upper, real_lower),
                       "seconds": round(time.time() - start, 1)}
                print(json.dumps({k: v for k, v in out.items() if k not in ("per_pair", "mixes", "realism")}), flush=True)
                if args.out:
                    with open(args.out, "a") as fh:
                        fh.write(json.dumps(out) + "\n")


class Reader:
    """One model's reactions to the fold's held-out leaders (each label drawn once) as each judge reads them, part
    labels with their values times `branch_scale`."""

    def __init__(self, model, judges, seed: int, branch_scale: float):
        self.model, self.judges, self.seed, self.branch_scale = model, judges, seed, branch_scale
        self.n, self.c = len(judges.leaders), len(judges.data.class_names)
        self.drawn: dict[bytes, list[np.ndarray]] = {}

    def followers(self, labels: np.ndarray) -> list[np.ndarray]:
        if labels.shape[1] == 2 * self.c:
            labels = labels * np.float32(self.branch_scale)
        key = np.ascontiguousarray(labels, np.float32).tobytes()
        if key not in self.drawn:
            self.drawn[key] = self.model.synthesize_batch_canonical(self.judges.leaders, labels, [self.seed] * self.n)
        return self.drawn[key]

    def upper(self, labels: np.ndarray) -> np.ndarray:
        return self.judges.part_view("upper", self.followers(labels))

    def lower(self, labels: np.ndarray) -> np.ndarray:
        return self.judges.part_view("lower", self.followers(labels))

    def whole(self, labels: np.ndarray) -> np.ndarray:
        return self.judges.follower_view(self.judges.judge, self.followers(labels))


def measure(read: Reader, held_out: np.ndarray, shares: np.ndarray, y: np.ndarray, real_upper: np.ndarray,
            real_lower: np.ndarray) -> dict:
    from imm_model.evaluation import control
    from imm_model.reads_as import MIX_SHARE

    n, c, names = read.n, read.c, read.judges.data.class_names
    pairs = control.part_pair_table(read.upper, read.lower, lambda a, b: np.zeros(n, bool), n, names, held_out)
    realism = control.part_realism(read.upper, read.lower, y, real_upper, real_lower, names)
    mixes = []
    for i, j in combinations(range(c), 2):
        top, bottom = (i, j) if shares[i] >= shares[j] else (j, i)
        row = {"pair": f"{names[i]}+{names[j]}", "upper": names[top]}
        summed = np.zeros((n, c), np.float32)
        summed[:, [i, j]] = 1.0
        for name, labels in (("sum", summed), ("by_part", _part_label(n, c, top, bottom)),
                             ("by_part_swapped", _part_label(n, c, bottom, top))):
            p = read.whole(labels)
            row[name] = float(np.mean((p[:, i] >= MIX_SHARE) & (p[:, j] >= MIX_SHARE)))
        mixes.append(row)
    return {"part_read": float(np.mean([r["read"] for r in pairs])),
            "held_out_composites": float(np.nanmean([r["real"] for r in pairs])),
            "pairs_under_0.1": int(sum(r["read"] < 0.1 for r in pairs)),
            "per_pair": {f"{r['upper']}/{r['lower']}": [round(r["read"], 4), round(r["real"], 4)] for r in pairs},
            "realism": {f"{r['class']}/{r['part']}": [round(r["own"], 4), round(r["all"], 4), round(r["real"], 4)]
                        for r in realism},
            "mix_sum": float(np.mean([m["sum"] for m in mixes])),
            "mix_by_part": float(np.mean([m["by_part"] for m in mixes])),
            "mix_by_part_swapped": float(np.mean([m["by_part_swapped"] for m in mixes])),
            "mix_best_assignment": float(np.mean([max(m["by_part"], m["by_part_swapped"]) for m in mixes])),
            "mixes": mixes, "upper_shares": dict(zip(names, np.round(shares, 4).tolist(), strict=True))}


def _part_label(n: int, c: int, upper: int, lower: int) -> np.ndarray:
    labels = np.zeros((n, 2 * c), np.float32)
    labels[:, upper], labels[:, c + lower] = 1.0, 1.0
    return labels


if __name__ == "__main__":
    main()
