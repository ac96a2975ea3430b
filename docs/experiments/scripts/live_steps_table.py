"""The live reaction at fewer sampler steps a push (windows.LIVE_STEPS) against the model's own 7, fold by fold: the
rows online_fold.py wrote (each fold's own diffusion checkpoint, seed 0, its own judges), a table per group (dev s01
s03 s04, test s02 s05 s06 s07) with each step count's difference from 7 paired by fold and a 95 % Student t interval
over the folds, beside the clip sampled whole.

    python docs/experiments/scripts/online_fold.py --checkpoint runs/teachers/fold-sXX/final.safetensors --fold sXX \\
        --modes offline online --set LIVE_STEPS=7 --out docs/experiments/data/live-steps-loso.jsonl    # per fold
    python docs/experiments/scripts/online_fold.py ... --modes online --set LIVE_STEPS=S ...            # per fold, S
    python docs/experiments/scripts/live_steps_table.py [--steps 4 3]

A row for a fold and a step count is the last one written.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from online_table import print_rows
from sampler_steps import GROUPS

DATA = Path(__file__).resolve().parents[1] / "data" / "live-steps-loso.jsonl"
BASE = 7  # the model's own sampler steps, what a push took before LIVE_STEPS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--steps", type=int, nargs="+", default=[4, 3])
    args = ap.parse_args()
    columns: dict = {"whole": {}}
    for line in args.data.read_text().splitlines():
        row = json.loads(line)
        row["jitter_high"] = row["jitter_ratio"][1]  # the upper end of the jitter against real followers
        key = "whole" if row["mode"] == "offline" else row["settings"]["LIVE_STEPS"]
        columns.setdefault(key, {})[row["fold"]] = row
    names = ["whole", BASE, *args.steps]
    for group, folds in GROUPS.items():
        have = [f for f in folds if all(f in columns.get(n, {}) for n in names)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print(f"| figure | whole clip | live, {BASE} steps | " + " | ".join(f"live, {s} steps" for s in args.steps) + " | "
              + " | ".join(f"{s} - {BASE} [95 % t]" for s in args.steps) + " |")
        print("|---|" + "---:|" * (2 + 2 * len(args.steps)))
        print_rows(columns, names, have, [(s, BASE) for s in args.steps])
    print("\n* the interval leaves out 0: a difference beyond the folds' spread")


if __name__ == "__main__":
    main()
