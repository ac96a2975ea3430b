"""The live reaction at other settings (sampler steps a push, windows.LIVE_STEPS; how much more each later window's
sample weighs, windows.ENSEMBLE_GROWTH) against a reference setting (the model's own 7 steps), fold by fold: the rows
online_fold.py wrote (each fold's own diffusion checkpoint, seed 0, its own judges), a table per group (dev s01 s03
s04, test s02 s05 s06 s07) with each setting's difference from the reference paired by fold and a 95 % Student t
interval over the folds, beside the clip sampled whole.

    python docs/experiments/scripts/online_fold.py --checkpoint runs/teachers/fold-sXX/final.safetensors --fold sXX \\
        --modes offline online --set LIVE_STEPS=7 --out docs/experiments/data/live-steps-loso.jsonl    # per fold
    python docs/experiments/scripts/online_fold.py ... --modes online --set LIVE_STEPS=S [ENSEMBLE_GROWTH=G] ...
    python docs/experiments/scripts/live_steps_table.py [--settings 4 3 4/2] [--against 7]

A setting is S steps, or S/G at growth G (1 when left out). A row for a fold and a setting is the last one written.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from online_table import print_rows
from sampler_steps import GROUPS

DATA = Path(__file__).resolve().parents[1] / "data" / "live-steps-loso.jsonl"


def setting(row: dict) -> str:
    """A live row's setting as the command line names it: "S" or "S/G"."""
    steps, growth = row["settings"]["LIVE_STEPS"], row["settings"].get("ENSEMBLE_GROWTH", 1.0)
    return f"{steps}" if growth == 1 else f"{steps}/{growth:g}"


def title(name: str) -> str:
    steps, _, growth = name.partition("/")
    return f"live, {steps} steps" + (f", growth {growth}" if growth else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--settings", nargs="+", default=["4", "3"], help='live settings, "S" steps or "S/G" at growth G')
    ap.add_argument("--against", default="7", help="the setting each other one is paired with (the model's own 7 steps)")
    args = ap.parse_args()
    columns: dict = {"whole": {}}
    for line in args.data.read_text().splitlines():
        row = json.loads(line)
        row["jitter_high"] = row["jitter_ratio"][1]  # the upper end of the jitter against real followers
        key = "whole" if row["mode"] == "offline" else setting(row)
        columns.setdefault(key, {})[row["fold"]] = row
    names = ["whole", args.against, *args.settings]
    for group, folds in GROUPS.items():
        have = [f for f in folds if all(f in columns.get(n, {}) for n in names)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print("| figure | whole clip | " + " | ".join(title(n) for n in names[1:]) + " | "
              + " | ".join(f"{s} - {args.against} [95 % t]" for s in args.settings) + " |")
        print("|---|" + "---:|" * (2 + 2 * len(args.settings)))
        print_rows(columns, names, have, [(s, args.against) for s in args.settings])
    print("\n* the interval leaves out 0: a difference beyond the folds' spread")


if __name__ == "__main__":
    main()
