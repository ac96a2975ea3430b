"""The live reactor (a causal student of the clip model, imm_model/families/diffusion/live.py) against the clip sampled
whole and against the live reaction in windows it replaces, fold by fold: a table per group (dev s01 s03 s04, test s02
s05 s06 s07), each figure's mean over the folds and the differences paired by fold with a 95 % Student t interval;
then the live engagement by fold (closest hands and torso, live minus the clip's offline reaction, each over its takes).

    python docs/experiments/scripts/causal_reactor.py --fold sXX --clip-model runs/teachers/fold-sXX/final.safetensors \\
        --past-in-context --teacher-pool 32 --long-takes 200 --part-share 0.2 --ensemble 2 --variant live-reactor \\
        --out docs/experiments/data/live-reactor-folds.jsonl                                             # per fold
    python docs/experiments/scripts/live_reactor_table.py

The whole clip and the windows' live rows are data/live-steps-loso.jsonl's (online_fold.py, 4 sampler steps a push, as
shipped before); the windows' engagement by fold data/live-engagement-folds.jsonl's (live_engagement_folds.py).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from sampler_steps import GROUPS, interval

DATA = Path(__file__).resolve().parents[1] / "data"
FIGURES = ("afd", "afd_best_of_5", "fid", "off_label", "interior_limb_speed_ratio", "jitter_high", "foot_skate_mps",
           "multimodality_m", "push_ms_median")


def rows(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--live", type=Path, default=DATA / "live-reactor-folds.jsonl")
    ap.add_argument("--variant", default="live-reactor")
    args = ap.parse_args()
    columns: dict[str, dict[str, dict]] = {"whole clip": {}, "windows, live": {}, "live reactor": {}}
    for row in rows(DATA / "live-steps-loso.jsonl"):
        settings = row.get("settings") or {}
        if row["mode"] == "offline":
            columns["whole clip"][row["fold"]] = row
        elif settings.get("LIVE_STEPS") == 4 and settings.get("ENSEMBLE_GROWTH") == 1.0:
            columns["windows, live"][row["fold"]] = row
    for row in rows(args.live):
        if row.get("variant") == args.variant:
            columns["live reactor"][row["fold"]] = row
    for column in columns.values():
        for row in column.values():
            row["jitter_high"] = row["jitter_ratio"][1]  # the upper end of the jitter against real followers
    names = list(columns)
    for group, folds in GROUPS.items():
        have = [f for f in folds if all(f in columns[n] for n in names)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print("| figure | " + " | ".join(names) + " | reactor - whole [95 % t] | reactor - windows [95 % t] |")
        print("|---|" + "---:|" * (len(names) + 2))
        for key in FIGURES:
            present = [n for n in names if all(key in columns[n][f] for f in have)]
            values = {n: np.array([columns[n][f][key] for f in have], float) for n in present}
            cells = [f"{values[n].mean():.3f}" if n in values else "" for n in names]
            diffs = []
            for ref in ("whole clip", "windows, live"):
                if ref not in values:
                    diffs.append("")
                    continue
                d = values["live reactor"] - values[ref]
                lo, hi = interval(d)
                apart = "" if np.isnan(lo) or lo <= 0 <= hi else " *"
                diffs.append(f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]{apart}")
            print(f"| {key} | " + " | ".join(cells + diffs) + " |")
    print("\n* the interval leaves out 0: a difference beyond the folds' spread")
    windows = {row["fold"]: row for row in rows(DATA / "live-engagement-folds.jsonl")}
    print("\nEngagement, live minus the clip's offline reaction (m), mean [95 % t over the takes]; bar: hands <= +0.05, "
          "torso <= +0.08")
    print("| fold | takes | windows, hands | windows, torso | live reactor, hands | live reactor, torso |")
    print("|---|---:|---|---|---|---|")
    fmt = lambda v: f"{v[0]:+.3f} [{v[1]:+.3f}, {v[2]:+.3f}]"  # noqa: E731
    for fold in (*GROUPS["dev"], *GROUPS["test"]):
        live, win = columns["live reactor"].get(fold), windows.get(fold)
        if live is None:
            continue
        cells = [fmt(win["live_hands_minus_offline"]), fmt(win["live_torso_minus_offline"])] if win else ["", ""]
        print(f"| {fold} | {win['takes'] if win else ''} | " + " | ".join(
            cells + [fmt(live["causal_hands_minus_offline"]), fmt(live["causal_torso_minus_offline"])]) + " |")


if __name__ == "__main__":
    main()
