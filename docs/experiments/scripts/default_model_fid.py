"""FID of `imm-diffusion` against `imm-steer` over the 7 LOSO folds, from the committed data alone, for the choice of
the default model (docs/experiments/default-model.md).

    python docs/experiments/scripts/default_model_fid.py

`imm-diffusion`: the rows of data/reaction-memory.jsonl scored with the shipped sampler (IMM_DIFFUSION.guidance; rows of
another guidance, e.g. the reaction memory's memory_level 0.5, are left out), one checkpoint per fold and seed: seeds 0
and 1 trained on a GPU (runs/gpu/seedN), seed 2 on the CPU (runs/cpu-seed2). `imm-steer`: per fold, seed 0 only, the
rows of data/reaction-diffusion.jsonl without guidance (the GAN's); seeds 0-2, the means over folds then seeds of its
model card's table (docs/model-cards/imm-steer.md), the only committed form of its seeds 1 and 2. Both FIDs are
`imm evaluate`'s fold evaluation (imm_model/evaluation/distribution.py), all classes, cleaned followers, on the
held-out subject.

Per seed, the mean FID over the folds of a group; then the mean over seeds with a 95 % Student t interval
(mean +- t(0.975, n - 1) * sd / sqrt(n)).
"""

from __future__ import annotations

import json
import math
import re
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data"
CARD = HERE.parents[1] / "model-cards" / "imm-steer.md"
DEV, TEST = ("s01", "s03", "s04"), ("s02", "s05", "s06", "s07")
GROUPS = {"all 7": DEV + TEST, "dev": DEV, "test": TEST}
DIFFUSION_SEEDS = {0: "runs/gpu/seed0/", 1: "runs/gpu/seed1/", 2: "runs/cpu-seed2/"}
# imm-steer's seed-0 checkpoints of each fold as the rows name them (s04's is the bundled model, its seed-0 refit)
STEER_SEED0 = {"s01": "steer-s01.", "s02": "steer-s02.", "s03": "imm-steer-seed0/fold-s03/", "s04": "sample_data/imm_sbu.",
               "s05": "steer-s05.", "s06": "steer-s06.", "s07": "steer-s07."}
T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447}  # Student t, 0.975 quantile, by degrees of freedom


def rows(name: str) -> list[dict]:
    return [json.loads(line) for line in (DATA / name).read_text().splitlines() if line.strip()]


def shipped_guidance() -> dict:
    from imm_model.families.diffusion.recipes import IMM_DIFFUSION
    from imm_model.families.diffusion.sampler import Guidance

    return Guidance.from_dict(IMM_DIFFUSION.guidance).to_dict()


def diffusion_fids() -> dict[int, dict[str, float]]:
    """{seed: {fold: FID}} of the shipped recipe at its shipped sampler; a fold scored twice the same way takes its last row."""
    from imm_model.families.diffusion.sampler import Guidance

    shipped, defaults = shipped_guidance(), Guidance().to_dict()  # a row without a field sampled with the field's default
    out: dict[int, dict[str, float]] = {s: {} for s in DIFFUSION_SEEDS}
    for row in rows("reaction-memory.jsonl"):
        seed = next((s for s, prefix in DIFFUSION_SEEDS.items() if row["checkpoint"].startswith(prefix)), None)
        guidance = defaults | (row.get("guidance") or {})
        if seed is None or row.get("raw") or any(guidance[k] != v for k, v in shipped.items()):
            continue
        out[seed][row["fold"]] = row["fid"]
    return out


def steer_seed0_fids() -> dict[str, float]:
    out = {}
    for row in rows("reaction-diffusion.jsonl"):
        fold = row["fold"]
        if row.get("guidance") is None and not row.get("raw") and STEER_SEED0[fold] in row["checkpoint"]:
            out[fold] = row["fid"]
    return out


def steer_card_means() -> dict[str, float]:
    """{group: FID} of `imm-steer`, seeds 0-2, from its card's measured-results table (the last column)."""
    out = {}
    for line in CARD.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) > 3 and cells[0] in GROUPS and re.fullmatch(r"\**`imm-steer`\**", cells[1]):
            out[cells[0]] = float(cells[-1].strip("*"))
    return out


def interval(values: list[float]) -> tuple[float, float | None]:
    """Mean and the 95 % t interval's half-width (None for one value)."""
    m = statistics.fmean(values)
    if len(values) < 2:
        return m, None
    return m, T975[len(values) - 1] * statistics.stdev(values) / math.sqrt(len(values))


def fmt(mean: float, half: float | None) -> str:
    return f"{mean:.2f}" if half is None else f"{mean:.2f} +- {half:.2f} [{mean - half:.2f}, {mean + half:.2f}]"


def main() -> int:
    diff, steer0, steer_card = diffusion_fids(), steer_seed0_fids(), steer_card_means()
    for seed, folds in diff.items():
        missing = set(DEV + TEST) - set(folds)
        if missing:
            print(f"imm-diffusion seed {seed}: no shipped-guidance row for {sorted(missing)}", file=sys.stderr)
            return 1
    if set(steer0) != set(DEV + TEST) or set(steer_card) != set(GROUPS):
        print(f"imm-steer: rows for {sorted(steer0)}, card means for {sorted(steer_card)}", file=sys.stderr)
        return 1

    print("Per fold, FID (imm-diffusion seeds 0 / 1 / 2; imm-steer seed 0):")
    print("| fold | imm-diffusion s0 | s1 | s2 | mean | imm-steer s0 |")
    print("|---|---:|---:|---:|---:|---:|")
    for fold in DEV + TEST:
        values = [diff[s][fold] for s in DIFFUSION_SEEDS]
        print(f"| {fold} | " + " | ".join(f"{v:.2f}" for v in values) + f" | {statistics.fmean(values):.2f} | {steer0[fold]:.2f} |")

    print("\nPooled over the folds (per seed the mean over the group's folds; then mean +- 95 % t over seeds):")
    print("| folds | imm-diffusion per seed 0 / 1 / 2 | imm-diffusion, 3 seeds | imm-steer seed 0 | imm-steer, 3 seeds (card) |"
          " diffusion - steer (3 seeds) | diffusion worse beyond the interval? |")
    print("|---|---|---|---:|---:|---:|---|")
    verdict = {}
    for group, folds in GROUPS.items():
        per_seed = [statistics.fmean(diff[s][f] for f in folds) for s in DIFFUSION_SEEDS]
        mean, half = interval(per_seed)
        s0 = statistics.fmean(steer0[f] for f in folds)
        card = steer_card[group]
        worse = mean - half > card  # the whole interval above imm-steer's mean
        verdict[group] = worse
        print(f"| {group} | " + " / ".join(f"{v:.2f}" for v in per_seed) + f" | {fmt(mean, half)} | {s0:.2f} | {card:.2f} |"
              f" {mean - card:+.2f} | {'yes' if worse else 'no'} |")

    # the same question paired by fold, where imm-steer has a per-fold figure (seed 0): 7 differences, t over folds
    diffs = [statistics.fmean(diff[s][f] for s in DIFFUSION_SEEDS) - steer0[f] for f in DEV + TEST]
    mean, half = interval(diffs)
    print(f"\nPaired by fold, imm-diffusion (3 seeds) - imm-steer (seed 0), 95 % t over the 7 folds: {fmt(mean, half)}")
    print("\nRule: imm-diffusion becomes the default unless its FID pooled over the 7 folds is worse than imm-steer's "
          "beyond the 95 % interval.")
    print("Decision:", "imm-steer stays the default" if verdict["all 7"] else "imm-diffusion becomes the default")
    return 0


if __name__ == "__main__":
    sys.exit(main())
