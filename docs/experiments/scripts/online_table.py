"""The live reaction and the windowed one against the clip sampled whole, fold by fold: the rows online_fold.py wrote
(the fold's own diffusion checkpoint, seed 0), as a table per group (dev s01 s03 s04, test s02 s05 s06 s07) with each
one's difference from the whole clip paired by fold and a 95 % Student t interval over the folds.

    python docs/experiments/scripts/online_fold.py --checkpoint runs/imm-diffusion/fold-sXX/final.safetensors --fold sXX \\
        --modes offline online windows --out docs/experiments/data/long-takes-loso.jsonl     # per fold
    python docs/experiments/scripts/online_table.py

A mode's row on a fold is the last one whose settings match the shipped windows.py (or --online-window, --window and
--take-lookahead for an earlier variant).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from sampler_steps import GROUPS, interval

from imm_model.families.diffusion import windows

DATA = Path(__file__).resolve().parents[1] / "data" / "long-takes-loso.jsonl"
FIGURES = ("afd", "afd_best_of_5", "fid", "off_label", "interior_limb_speed_ratio", "jitter_high", "foot_skate_mps",
           "multimodality_m")


def wanted(row: dict, args) -> bool:
    settings = row.get("settings", {})
    if row["mode"] == "online":
        return (settings.get("ONLINE_WINDOW") == args.online_window and settings.get("ENSEMBLE_GROWTH") == 1.0
                and settings.get("LOOKAHEAD") == windows.LOOKAHEAD)
    if row["mode"] == "windows":
        return settings.get("WINDOW") == args.window and settings.get("TAKE_LOOKAHEAD") == args.take_lookahead
    return "takes" not in row["checkpoint"]  # the default's own rows, not the takes recipe's


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--online-window", type=int, default=windows.ONLINE_WINDOW)
    ap.add_argument("--window", type=int, default=windows.WINDOW)
    ap.add_argument("--take-lookahead", type=int, default=windows.TAKE_LOOKAHEAD)
    args = ap.parse_args()
    columns: dict[str, dict[str, dict]] = {"offline": {}, "online": {}, "windows": {}}
    for line in args.data.read_text().splitlines():
        row = json.loads(line)
        if row["mode"] in columns and wanted(row, args):
            row["jitter_high"] = row["jitter_ratio"][1]  # the upper end of the jitter against real followers
            columns[row["mode"]][row["fold"]] = row
    names = ["offline", "online", "windows"]
    print(f"live: windows of {args.online_window} frames, {windows.LOOKAHEAD} ahead; long takes: windows of {args.window}, "
          f"{args.take_lookahead} ahead")
    for group, folds in GROUPS.items():
        have = [f for f in folds if all(f in columns[n] for n in names)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print("| figure | whole clip | live | in windows | live - whole [95 % t] | windows - whole [95 % t] |")
        print("|---|---:|---:|---:|---:|---:|")
        print_rows(columns, names, have, [(n, "offline") for n in names[1:]])
    print("\n* the interval leaves out 0: a difference beyond the folds' spread")


def print_rows(columns: dict, names: list, folds: list[str], pairs: list[tuple]) -> None:
    """One table row per figure: each column's mean over the folds, then each (column, reference) pair's difference
    paired by fold with its 95 % t interval (* where it leaves out 0)."""
    for key in FIGURES:
        values = {n: np.array([columns[n][f][key] for f in folds], float) for n in names}
        diffs = []
        for n, reference in pairs:
            d = values[n] - values[reference]
            lo, hi = interval(d)
            apart = "" if np.isnan(lo) or lo <= 0 <= hi else " *"
            diffs.append(f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]{apart}")
        print(f"| {key} | " + " | ".join(f"{values[n].mean():.3f}" for n in names) + " | " + " | ".join(diffs) + " |")


if __name__ == "__main__":
    main()
