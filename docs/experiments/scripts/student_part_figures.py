"""The label figures of the part-mix bar, fold by fold, for rows diffusion_fold.py wrote: part mixes read as asked (the
project's part judges, 30 ordered pairs) beside the held-out composites' share (every held-out follower of A's trunk and
arms on every held-out follower of B's legs, which no judge saw) and the pairs under 0.10; hugging's trunk and arms and
punching's legs read as asked for the class's own leaders beside real held-out followers; whole-body two-class mixes
read as both (each >= 0.25 on the whole-body judge).

    python docs/experiments/scripts/student_part_figures.py docs/experiments/data/sampler-student-label.jsonl
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from sampler_steps import GROUPS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", help="a JSON-lines file of diffusion_fold.py rows (one per fold)")
    by_fold = {r["fold"]: r for r in map(json.loads, open(ap.parse_args().rows))}
    print("| fold | part mixes read | held-out composites | ratio | pairs < 0.10 | hug trunk+arms / real | punch legs / real |"
          " mixes read as both |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for group, folds in GROUPS.items():
        have = [f for f in folds if f in by_fold]
        cells = []
        for f in have:
            r = by_fold[f]
            pairs = np.array(list(r["part_per_pair"].values()), float)
            hug, punch = r["part_realism"]["hugging/upper"], r["part_realism"]["punching/lower"]
            cells.append((r["part_read"], pairs[:, 1].mean(), r["part_read"] / pairs[:, 1].mean(), int((pairs[:, 0] < 0.10).sum()),
                          hug[0], hug[2], punch[0], punch[2], r["mix_mixed"]))
            c = cells[-1]
            print(f"| {f} | {c[0]:.3f} | {c[1]:.3f} | {c[2]:.2f} | {c[3]} | {c[4]:.2f} / {c[5]:.2f} | "
                  f"{c[6]:.2f} / {c[7]:.2f} | {c[8]:.3f} |")
        if have:
            m = np.array(cells).mean(0)
            print(f"| **{group} mean** | **{m[0]:.3f}** | {m[1]:.3f} | {m[2]:.2f} | max {max(c[3] for c in cells)} | "
                  f"{m[4]:.2f} / {m[5]:.2f} | {m[6]:.2f} / {m[7]:.2f} | **{m[8]:.3f}** |")


if __name__ == "__main__":
    main()
