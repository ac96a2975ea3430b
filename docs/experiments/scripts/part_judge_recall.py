"""How well each body part of a real follower tells its class: the body-part judges' recall per class on every fold's
real held-out followers (summed over the seven LOSO folds), and which side of each pair a rule built on it would
give the trunk and arms, beside the side `imm-diffusion-mixed` takes from its followers' motion (`upper_shares`).

    python docs/experiments/scripts/part_judge_recall.py
    python docs/experiments/scripts/part_judge_recall.py --checkpoint runs/mixed-fixed/fold-s04/final.safetensors \
        --fold s04 --label shaking_hands+punching --label punching

With --checkpoint: what the same judges read, part by part, in that model's reactions to the fold's held-out leaders
for each --label (classes joined by '+', each at +1; the model's own seed 0), beside the fold's real followers of
each class. A diagnosis only: a training recipe may not choose from the judges that score it.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.evaluation.loso import EvalOptions, FoldJudges
from imm_model.paths import SAMPLE_DATA
from imm_model.training.part_mix import upper_shares

FOLDS = ("s01", "s02", "s03", "s04", "s05", "s06", "s07")


def shares(read: np.ndarray, names: tuple[str, ...]) -> str:
    """Class indices as read -> "class share, ..." for the classes read at least 5 % of the time."""
    counts = np.bincount(read, minlength=len(names)) / max(len(read), 1)
    return ", ".join(f"{names[c]} {counts[c]:.2f}" for c in np.argsort(-counts) if counts[c] >= 0.05)


def part_readings(judges: FoldJudges, followers: list) -> tuple[np.ndarray, np.ndarray]:
    """Followers to the fold's held-out leaders -> the class each part judge reads, (trunk and arms, legs and placement)."""
    return tuple(judges.part_view(part, followers).argmax(-1) for part in ("upper", "lower"))


def model_readings(checkpoint: str, fold: str, labels: list[str]) -> None:
    """Per --label, the body-part judges' readings of the model's reactions to the fold's held-out leaders."""
    from imm_model.inference import ReactionModel

    data = InteractionDataset.load(SAMPLE_DATA)
    names = data.class_names
    judges = FoldJudges(data, fold, EvalOptions(progress=False))
    model = ReactionModel.load(checkpoint)
    print(f"| {fold} | trunk and arms read as | legs and placement read as |\n|---|---|---|")
    for label in labels:
        vector = np.zeros(len(names), dtype=np.float32)
        vector[[names.index(c) for c in label.split("+")]] = 1
        followers = model.synthesize_batch_canonical(judges.leaders, np.tile(vector, (len(judges.leaders), 1)))
        upper, lower = part_readings(judges, followers)
        print(f"| {label} | {shares(upper, names)} | {shares(lower, names)} |")
    reals = [data.canonical(int(i))[1] for i in judges.test]
    y = data.actions[judges.test]
    upper, lower = part_readings(judges, reals)
    for c in sorted({names.index(c) for label in labels for c in label.split("+")}):
        print(f"| real {names[c]} followers | {shares(upper[y == c], names)} | {shares(lower[y == c], names)} |")


def real_recall() -> None:
    """The part judges' recall per class over the seven folds, and the side of each pair two rules would choose."""
    data = InteractionDataset.load(SAMPLE_DATA)
    names = data.class_names
    hits = {part: np.zeros((len(names), 2)) for part in ("upper", "lower")}  # (recognized, followers) per class
    for fold in FOLDS:
        judges = FoldJudges(data, fold, EvalOptions(progress=False))
        reals = [data.canonical(int(i))[1] for i in judges.test]
        y = data.actions[judges.test]
        for read, counts in zip(part_readings(judges, reals), hits.values(), strict=True):
            for c in range(len(names)):
                counts[c] += ((read[y == c] == c).sum(), (y == c).sum())
    recall = {part: counts[:, 0] / counts[:, 1] for part, counts in hits.items()}
    followers = [torch.from_numpy(data.canonical(i)[1]) for i in range(len(data))]
    motion_share = upper_shares(followers, torch.as_tensor(data.actions), len(names), data.skeleton).numpy()
    print("| class | upper-body judge | lower-body judge | trunk-and-arms share of motion |\n|---|---:|---:|---:|")
    for c, name in enumerate(names):
        print(f"| {name} | {recall['upper'][c]:.2f} | {recall['lower'][c]:.2f} | {motion_share[c]:.3f} |")
    print("\n| pair | upper body by motion | upper body by the judges' recall | product, kept / swapped |\n|---|---|---|---:|")
    for i, j in itertools.combinations(range(len(names)), 2):
        by_motion = i if motion_share[i] >= motion_share[j] else j
        keep = recall["upper"][i] * recall["lower"][j]
        swap = recall["upper"][j] * recall["lower"][i]
        by_recall = i if keep >= swap else j
        print(f"| {names[i]} + {names[j]} | {names[by_motion]} | {names[by_recall]} | {keep:.2f} / {swap:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", help="a reaction model whose reactions the part judges read")
    ap.add_argument("--fold", default="s04", help="with --checkpoint: the fold whose held-out leaders it reacts to")
    ap.add_argument("--label", action="append", default=[], help="with --checkpoint: classes joined by '+', each at +1")
    args = ap.parse_args()
    names = InteractionDataset.load(SAMPLE_DATA).class_names
    unknown = sorted({c for label in args.label for c in label.split("+")} - set(names))
    if unknown:
        ap.error(f"--label: unknown class {', '.join(unknown)}; expected classes among {', '.join(names)} joined by '+'")
    if args.checkpoint and not args.label:
        ap.error("--checkpoint needs at least one --label")
    if args.checkpoint:
        model_readings(args.checkpoint, args.fold, args.label)
    else:
        real_recall()


if __name__ == "__main__":
    main()
