"""The default model at fewer sampler steps, fold by fold: the rows diffusion_fold.py wrote (one per fold x steps),
as a table per group (dev s01 s03 s04, test s02 s05 s06 s07) of each figure at each step count, and its difference
from the shipped 7 steps paired by fold, with a 95 % Student t interval over the folds.

    python docs/experiments/scripts/diffusion_fold.py --checkpoint CK --fold sXX --sample-steps N \\
        --out docs/experiments/data/sampler-steps.jsonl          # per fold and N (CK: the fold's seed-0 model)
    python docs/experiments/scripts/sampler_steps.py docs/experiments/data/sampler-steps.jsonl
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy import stats

GROUPS = {"dev": ("s01", "s03", "s04"), "test": ("s02", "s05", "s06", "s07")}
FIGURES = ("afd", "afd_best_of_5", "fid", "off_label", "mix_mixed", "part_read", "interior_limb_speed_ratio",
           "foot_skate_mps", "lean_error_deg", "multimodality_m")
SHIPPED = 7


def interval(values: np.ndarray) -> tuple[float, float]:
    if len(values) < 2:
        return float("nan"), float("nan")
    half = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values))
    return float(values.mean() - half), float(values.mean() + half)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows")
    args = ap.parse_args()
    rows = [json.loads(line) for line in open(args.rows)]
    by = {(r["fold"], r["guidance"]["sample_steps"]): r for r in rows}
    counts = sorted({s for _, s in by}, reverse=True)
    for group, folds in GROUPS.items():
        have = [f for f in folds if all((f, s) in by for s in counts)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print("| figure | " + " | ".join(f"{s} steps" for s in counts) + " | "
              + " | ".join(f"{s} - {SHIPPED} [95 % t]" for s in counts if s != SHIPPED) + " |")
        print("|---|" + "---:|" * (2 * len(counts) - 1))
        for key in FIGURES:
            values = {s: np.array([by[(f, s)][key] for f in have], float) for s in counts}
            cells = [f"{values[s].mean():.3f}" for s in counts]
            diffs = []
            for s in counts:
                if s == SHIPPED:
                    continue
                d = values[s] - values[SHIPPED]
                lo, hi = interval(d)
                apart = "" if np.isnan(lo) or lo <= 0 <= hi else " *"
                diffs.append(f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]{apart}")
            print(f"| {key} | " + " | ".join(cells) + " | " + " | ".join(diffs) + " |")
    print("\n* the interval leaves out 0: a difference beyond the folds' spread")


if __name__ == "__main__":
    main()
