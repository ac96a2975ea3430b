"""Can a whole-body judge read "both classes" at all, and what does one that can read of the default's mixes?

The fold's whole-body judge is trained on one class per reaction. This script trains a second judge of the same
architecture, settings and seed on the fold's training followers (one-hot) and on composites of training followers
(one class's trunk and arms on another's legs and placement, both assignments; `compose_parts`, as the evaluation's
held-out composites are made) whose target is half each class. It then reads, by the project's rule (each class at
MIX_SHARE = 0.25 or more) and with the fold's own whole-body judge beside it:
- the real held-out followers (accuracy, and how many read as two classes: a judge that reads everything as two
  classes is no judge);
- the held-out composites (motion neither judge saw; the reference);
- the model's reactions to the held-out leaders with two classes at +1 (the 15 pairs), and with one class (how often
  a one-class reaction reads as two).

    OMP_NUM_THREADS=1 python docs/experiments/scripts/two_class_judge.py --fold s04 \\
        --checkpoint sample_data/imm_diffusion_student.safetensors --out docs/experiments/data/two-class-judge.jsonl
    python docs/experiments/scripts/two_class_judge.py --table docs/experiments/data/two-class-judge.jsonl
"""

from __future__ import annotations

import argparse
import json
from itertools import combinations, permutations
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
from diffusion_fold import record

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.data.sequence import resample
from imm_model.evaluation.loso import EvalOptions, FoldJudges, held_out_composites, prepare_model
from imm_model.inference import ReactionModel
from imm_model.model import classifier as classifiers
from imm_model.model.body_parts import compose_parts, part_indices
from imm_model.reads_as import MIX_SHARE

COMPOSITES_PER_PAIR = 20  # training composites drawn for each ordered pair of classes


def train_soft(cfg, sequences: list[np.ndarray], targets: np.ndarray) -> classifiers.MotionClassifier:
    """classifier.train_classifier's loop with soft targets (N, C) instead of class indices (its mixup left out: the
    composites are the mixing)."""
    torch.manual_seed(cfg.seed)
    gen = torch.Generator().manual_seed(cfg.seed)
    x, lengths = classifiers._pad(sequences)
    y = torch.as_tensor(targets, dtype=torch.float32)
    model = classifiers.MotionClassifier(cfg, x.shape[-1], y.shape[1])
    frames = classifiers.MotionClassifier.frame_inputs(model.positions(x))[torch.arange(x.shape[1])[None] < lengths[:, None]]
    model.mean.copy_(frames.mean(0))
    model.std.copy_(frames.std(0).clamp(min=1e-2))
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    model.train()
    for _ in range(cfg.epochs):
        order = torch.randperm(len(y), generator=gen)
        for k in range(0, len(order), cfg.batch_size):
            idx = order[k:k + cfg.batch_size]
            t = int(lengths[idx].max())
            logits = model(classifiers.augment(x[idx, :t], cfg, gen), lengths[idx])
            loss = nn.functional.cross_entropy(logits, y[idx], label_smoothing=cfg.label_smoothing)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
    return model.eval()


def both(p: np.ndarray, a: int, b: int) -> np.ndarray:
    return (p[:, a] >= MIX_SHARE) & (p[:, b] >= MIX_SHARE)


def two_or_more(p: np.ndarray) -> np.ndarray:
    return (p >= MIX_SHARE).sum(1) >= 2


def table(path: Path) -> None:
    """The rows of `path` as a markdown table, and each judge's means over the dev and the test folds (a fold's
    composites' seeds averaged first)."""
    rows = [json.loads(line) for line in open(path)]
    keys = ("real_accuracy", "real_read_as_two", "composites_read_as_both", "model_mixes_read_as_both",
            "model_mix_pairs_under_0.10", "model_single_read_as_asked", "model_single_read_as_two")
    print("| fold (seed) | judge | " + " | ".join(keys) + " |")
    print("|---|---|" + "---:|" * len(keys))
    for r in rows:
        print(f"| {r['fold']} ({r['seed']}) | {r['judge']} | " + " | ".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k])
                                                                     for k in keys) + " |")
    for group, folds in (("dev", ("s01", "s03", "s04")), ("test", ("s02", "s05", "s06", "s07"))):
        for judge in dict.fromkeys(r["judge"] for r in rows):
            per_fold = [[r for r in rows if r["fold"] == f and r["judge"] == judge] for f in folds]
            per_fold = [fold_rows for fold_rows in per_fold if fold_rows]
            means = {k: np.mean([np.mean([r[k] for r in fold_rows]) for fold_rows in per_fold]) for k in keys}
            print(f"{group} ({len(per_fold)} folds), {judge}: " + ", ".join(f"{k} {v:.3f}" for k, v in means.items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", type=Path, help="print the rows of this file as a table, and nothing else")
    ap.add_argument("--fold", default="s04")
    ap.add_argument("--checkpoint", default="sample_data/imm_diffusion_student.safetensors")
    ap.add_argument("--seed", type=int, default=0, help="the composites drawn for training")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    if args.table:
        return table(args.table)
    torch.set_num_threads(1)
    data = load_any(paths.SAMPLE_DATA)
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    c, rng = len(data.class_names), np.random.default_rng(args.seed)
    upper_joints, _, centre = part_indices(data.skeleton)

    train = [(data.canonical(int(i)), int(data.actions[i])) for i in judges.train]
    by_class = [[pair for pair, k in train if k == cls] for cls in range(c)]
    sequences, targets = [], []
    for (_, follower), k in train:
        sequences.append(follower)
        targets.append(np.eye(c)[k])
    for a, b in permutations(range(c), 2):
        for _ in range(COMPOSITES_PER_PAIR):
            fa = by_class[a][rng.integers(len(by_class[a]))][1]
            fb = by_class[b][rng.integers(len(by_class[b]))][1]
            sequences.append(compose_parts(resample(fa, len(fb))[None], fb[None], upper_joints, centre)[0])
            targets.append((np.eye(c)[a] + np.eye(c)[b]) / 2)
    inputs = classifiers.motion_inputs([], sequences, "follower")  # the follower alone: no leader read
    two_class = train_soft(opts.judge, inputs, np.array(targets))

    def read(clf, leaders, followers) -> np.ndarray:
        return classifiers.classify(clf, classifiers.motion_inputs(leaders, followers, "follower"))[0]

    y = data.actions[judges.test]
    reals = [data.canonical(int(i))[1] for i in judges.test]
    model = ReactionModel.load(args.checkpoint)
    if model.held_out_subject != args.fold:
        ap.error(f"{args.checkpoint} holds out {model.held_out_subject}, not {args.fold}")
    prepare_model(model, data, args.fold, opts)
    leaders = judges.leaders
    singles = model.synthesize_batch_canonical(leaders, np.eye(c, dtype=np.float32)[y])
    pairs = list(combinations(range(c), 2))
    mixes = {}
    for a, b in pairs:
        labels = np.zeros((len(leaders), c), np.float32)
        labels[:, [a, b]] = 1
        mixes[(a, b)] = model.synthesize_batch_canonical(leaders, labels)
    composites = list(held_out_composites(data, judges))

    for name, clf in (("the fold's whole-body judge", judges.judge), ("two-class judge", two_class)):
        p_real = read(clf, leaders, reals)
        p_single = read(clf, leaders, singles)
        comp = [float(both(read(clf, ls, fs), a, b).mean()) for a, b, ls, fs in composites if fs]
        mix = {f"{data.class_names[a]}+{data.class_names[b]}": float(both(read(clf, leaders, mixes[(a, b)]), a, b).mean())
               for a, b in pairs}
        row = {"fold": args.fold, "checkpoint": args.checkpoint, "judge": name, "seed": args.seed,
               "real_accuracy": float((p_real.argmax(1) == y).mean()),
               "real_read_as_two": float(two_or_more(p_real).mean()),
               "composites_read_as_both": float(np.mean(comp)),
               "model_mixes_read_as_both": float(np.mean(list(mix.values()))),
               "model_mix_pairs_under_0.10": int(sum(v < 0.10 for v in mix.values())),
               "model_single_read_as_asked": float((p_single.argmax(1) == y).mean()),
               "model_single_read_as_two": float(two_or_more(p_single).mean()),
               "model_mixes_per_pair": {k: round(v, 3) for k, v in mix.items()}}
        record(row, args.out)


if __name__ == "__main__":
    main()
