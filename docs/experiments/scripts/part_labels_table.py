"""The label per body part against the shipped diffusion recipe, fold by fold and as dev / test means, from the
committed scored rows (`diffusion_fold.py` JSON lines):

    python docs/experiments/scripts/part_labels_table.py

`imm-diffusion-parts` rows: docs/experiments/data/part-labels.jsonl; the shipped `imm-diffusion` (seeds 0-2, its
shipped guidance): docs/experiments/data/reaction-memory.jsonl. A mean over seeds carries its 95 % t-interval
(mean +- t(0.975, n-1) * sd / sqrt(n)) where there are several seeds.
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy import stats

from imm_model.families.diffusion.recipes import IMM_DIFFUSION

DATA = Path(__file__).resolve().parents[1] / "data"
DEV, TEST = ("s01", "s03", "s04"), ("s02", "s05", "s06", "s07")
COLUMNS = (("part_read", "part pairs read", 2), ("part_real", "real composites", 2), ("part_ratio", "ratio", 2),
           ("part_worst_ratio", "worst pair ratio", 2), ("part_avoid_lower_share", "lower:-1 lowers", 2),
           ("mix_mixed", "whole two-hot mixed", 2), ("afd", "AFD", 3), ("afd_nn1", "AFD 1-NN", 3),
           ("afd_best_of_5", "best of 5", 3), ("fid", "FID", 2), ("off_label", "off-label", 2),
           ("interior_limb_speed_ratio", "limbs / real", 2), ("foot_skate_mps", "feet m/s", 3),
           ("lean_error_deg", "lean deg", 1), ("multimodality", "multimodality", 2))


def shipped_rows() -> list[dict]:
    """The shipped recipe's rows at its shipped guidance (the reaction memory's other levels left out)."""
    shipped = IMM_DIFFUSION.guidance
    rows = [json.loads(line) for line in open(DATA / "reaction-memory.jsonl")]
    keep = [r for r in rows if all(r["guidance"].get(k) == v for k, v in shipped.items())
            and r["guidance"].get("memory_level", 1.0) == 1.0]
    for r in keep:
        r["seed"] = 2 if "seed2" in r["checkpoint"] else 1 if "seed1" in r["checkpoint"] else 0
    return keep


def part_rows() -> list[dict]:
    path = DATA / "part-labels.jsonl"
    rows = [json.loads(line) for line in open(path)] if path.exists() else []
    for r in rows:
        r["part_ratio"] = r["part_read"] / r["part_real"] if r.get("part_real") else None
    return rows


def interval(values: list[float]) -> str:
    values = [v for v in values if v is not None]
    if not values:
        return "–"
    mean = float(np.mean(values))
    if len(values) < 2:
        return f"{mean:.3g}"
    half = stats.t.ppf(0.975, len(values) - 1) * np.std(values, ddof=1) / np.sqrt(len(values))
    return f"{mean:.3g} ± {half:.2g}"


def table(recipes: dict[str, list[dict]]) -> str:
    head = "| recipe | folds | seeds | " + " | ".join(title for _, title, _ in COLUMNS) + " |"
    lines = [head, "|" + "---|" * (3 + len(COLUMNS))]
    for recipe, rows in recipes.items():
        by_fold = defaultdict(list)
        for r in rows:
            by_fold[r["fold"]].append(r)
        for fold in sorted(by_fold):
            cells = [interval([r.get(k) for r in by_fold[fold]]) for k, _, _ in COLUMNS]
            seeds = ",".join(str(r.get("seed", 0)) for r in by_fold[fold])
            lines.append(f"| {recipe} | {fold} | {seeds} | " + " | ".join(cells) + " |")
        for group, folds in (("dev", DEV), ("test", TEST)):
            present = [f for f in folds if f in by_fold]
            if not present:
                continue
            # per seed the mean over the group's folds present, then the interval over seeds
            seeds = sorted({r.get("seed", 0) for f in present for r in by_fold[f]})
            cells = []
            for k, _, _ in COLUMNS:
                per_seed = []
                for s in seeds:
                    vals = [r.get(k) for f in present for r in by_fold[f] if r.get("seed", 0) == s and r.get(k) is not None]
                    if len(vals) == len(present):
                        per_seed.append(float(np.mean(vals)))
                cells.append(interval(per_seed))
            lines.append(f"| {recipe} | **{group}: {', '.join(present)}** | {','.join(map(str, seeds))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parts = part_rows()
    folds = sorted({r["fold"] for r in parts})
    shipped = [r for r in shipped_rows() if r["fold"] in folds]
    print(table({"imm-diffusion-parts": parts, "imm-diffusion (shipped recipe)": shipped}))
    if parts:
        print("\nPer pair (upper / lower): read as asked, real composites; mean over the part rows")
        pairs = parts[0]["part_per_pair"]
        for pair in pairs:
            read = np.mean([r["part_per_pair"][pair][0] for r in parts])
            real = np.mean([r["part_per_pair"][pair][1] for r in parts])
            print(f"| {pair} | {read:.2f} | {real:.2f} | {read / real if real else float('nan'):.2f} |")


if __name__ == "__main__":
    main()
