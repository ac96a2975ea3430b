"""Dev and test tables of part_folds.py's JSON lines: per sampler (checkpoint kind x join), the mean over folds of each
fold's seed mean with its 95 % t-interval over the folds (over the seeds where a group has one fold), and the
per-fold rows.

    python docs/experiments/scripts/part_folds_table.py docs/experiments/data/part-folds.jsonl
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.evaluation.intervals import t_interval
from imm_model.paths import SAMPLE_DATA

GROUPS = {"dev": ("s01", "s03", "s04"), "test": ("s02", "s05", "s06", "s07")}


def figures(row: dict) -> dict[str, float]:
    realism = row["realism"]
    return {"part read": row["part_read"], "held-out composites": row["held_out_composites"],
            "ratio": row["part_read"] / row["held_out_composites"], "pairs < 0.10": row["pairs_under_0.1"],
            "hug upper (own)": realism["hugging/upper"][0], "real hug upper": realism["hugging/upper"][2],
            "punch lower (own)": realism["punching/lower"][0], "real punch lower": realism["punching/lower"][2],
            "mix both, sum": row["mix_sum"], "mix both, by part": row["mix_by_part"],
            "mix both, by part swapped": row["mix_by_part_swapped"]}


def sampler_of(row: dict) -> str:
    kind = "parts model" if "parts" in row["checkpoint"] else "default model"
    join = "joined reactions" if row.get("join_outputs") else "joined every step"
    return f"{kind}, {join}" + (f", branch x{row['branch_scale']:g}" if row.get("branch_scale", 1) != 1 else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", type=Path, nargs="+")
    args = ap.parse_args()
    runs: dict[str, dict[str, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for path in args.paths:
        for line in path.read_text().splitlines():
            row = json.loads(line)
            runs[sampler_of(row)][row["fold"]].append(figures(row))
    data = InteractionDataset.load(SAMPLE_DATA)
    counts = {f: np.bincount(data.actions[loso_fold(data.subject_pairs, f).test], minlength=len(data.class_names))
              for g in GROUPS.values() for f in g}
    hug, punch = data.class_names.index("hugging"), data.class_names.index("punching")
    for sampler, folds in sorted(runs.items()):
        print(f"\n## {sampler}")
        for group, members in GROUPS.items():
            present = [f for f in members if f in folds]
            if not present:
                continue
            per_fold = {f: {k: float(np.mean([r[k] for r in folds[f]])) for k in folds[f][0]} for f in present}
            print(f"{group} ({', '.join(f'{f} x{len(folds[f])}' for f in present)}):")
            for key in per_fold[present[0]]:
                values = [per_fold[f][key] for f in present]
                spread = values if len(values) > 1 else [r[key] for r in folds[present[0]]]  # one fold: over its seeds
                lo, hi = t_interval(spread) if len(spread) > 1 else (float("nan"), float("nan"))
                seeds = ", ".join(f"{f} {per_fold[f][key]:.3f}" for f in present)
                worst = f" (most in a run: {max(r[key] for f in present for r in folds[f]):.0f})" if key == "pairs < 0.10" else ""
                print(f"  {key}: {np.mean(values):.3f} [{lo:.3f}, {hi:.3f}]{worst}   {seeds}")
            # part realism pooled over the group's leaders of the class (a fold holds 2-10 of them)
            for key, k in (("hug upper", hug), ("punch lower", punch)):
                weights = np.array([counts[f][k] for f in present], float)
                model = np.array([per_fold[f][f"{key} (own)"] for f in present]) @ weights / weights.sum()
                real = np.array([per_fold[f][f"real {key}"] for f in present]) @ weights / weights.sum()
                print(f"  {key}, pooled over {weights.sum():.0f} leaders: model {model:.3f}, real held-out {real:.3f}, "
                      f"ratio {model / real:.2f}")


if __name__ == "__main__":
    main()
