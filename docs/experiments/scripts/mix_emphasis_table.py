"""The student taught with more two-class mixes in its pool against the default recipe's, fold by fold: the rows
diffusion_fold.py wrote (data/mix-emphasis.jsonl, a run named by its folder, runs/NAME/fold-sXX/...), beside the
default's own rows (data/sampler-student-label-0.6-smoothed.jsonl, seed 0), per group (dev s01 s03 s04, test s02 s05
s06 s07): the means, and the difference paired by fold (the seeds of a fold averaged first) with a 95 % Student t
interval over the folds; on a single fold, over its seeds.

    python docs/experiments/scripts/mix_emphasis_table.py
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from sampler_steps import GROUPS, interval

DATA = Path(__file__).resolve().parents[1] / "data"
FIGURES = ("afd", "afd_best_of_5", "fid", "kid", "off_label", "mix_whole", "mix_parts", "mix_mixed", "part_read",
           "interior_limb_speed_ratio", "jitter_ratio", "foot_skate_mps", "lean_error_deg", "multimodality_m")
# run folders (runs/NAME/...) -> (recipe, seed); the default recipe's seed-0 rows come from its own data file
RUNS = {"student": ("default recipe", 0), "student-seed1": ("default recipe", 1),
        "mix-0.5": ("two-class share 0.5", 0), "mix-0.5-seed1": ("two-class share 0.5", 1),
        "mix-0.5-label-1.2": ("two-class share 0.5, label critic 1.2", 0)}


def rows(path: Path) -> list[dict]:
    return [json.loads(line) for line in open(path)] if path.exists() else []


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=Path, default=DATA / "mix-emphasis.jsonl")
    ap.add_argument("--default", type=Path, default=DATA / "sampler-student-label-0.6-smoothed.jsonl")
    args = ap.parse_args()
    runs: dict[str, dict[str, dict[int, dict]]] = defaultdict(lambda: defaultdict(dict))  # recipe -> fold -> seed -> row
    for r in rows(args.default):
        runs["default recipe"][r["fold"]][0] = r
    for r in rows(args.rows):
        recipe, seed = RUNS[Path(r["checkpoint"]).parts[-3]]
        runs[recipe][r["fold"]][seed] = r  # a run scored again here replaces the recorded row of its fold and seed
    base = runs["default recipe"]
    for recipe in [n for n in runs if n != "default recipe"]:
        for group, folds in GROUPS.items():
            have = [f for f in folds if f in runs[recipe] and f in base]
            if not have:
                continue
            seeds = {f: sorted(set(runs[recipe][f]) & set(base[f])) for f in have}
            print(f"\n{recipe} against the default recipe, {group} folds {' '.join(have)} "
                  f"(seeds per fold: {', '.join(f'{f} {len(s)}' for f, s in seeds.items())})")
            print(f"| {group} | default recipe | {recipe} | difference [95 % t] |")
            print("|---|---:|---:|---|")
            for fig in FIGURES:
                a = np.array([np.mean([base[f][s][fig] for s in seeds[f]]) for f in have])
                b = np.array([np.mean([runs[recipe][f][s][fig] for s in seeds[f]]) for f in have])
                if len(have) > 1:
                    lo, hi = interval(b - a)
                else:  # one fold: the interval over its seeds
                    f = have[0]
                    lo, hi = interval(np.array([runs[recipe][f][s][fig] - base[f][s][fig] for s in seeds[f]]))
                star = " *" if lo > 0 or hi < 0 else ""
                print(f"| {fig} | {a.mean():.3f} | {b.mean():.3f} | {(b - a).mean():+.3f} [{lo:+.3f}, {hi:+.3f}]{star} |")


if __name__ == "__main__":
    main()
