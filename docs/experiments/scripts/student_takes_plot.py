"""Closest hands and torso distance per copy of a long take, the default (teacher) beside its students: the rows
long_takes.py wrote (held-out s04, 49 leaders), one line per model and mode, seed 0; the teacher's and the
window-taught student's repeat x8 on seeds 1 and 2 as thin lines.

    python docs/experiments/scripts/student_takes_plot.py --out docs/experiments/data/student-takes.png
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data"
# (file, variant in it, the name plotted)
MODELS = (("long-takes.jsonl", "shipped-w30", "teacher (the default), 7 steps"),
          ("sampler-student-label-long-takes.jsonl", "student-label", "student, whole clips only"),
          ("sampler-student-windows-long-takes.jsonl", "student-window", "student + window rows"),
          ("sampler-student-windows-long-takes.jsonl", "student-onpolicy", "student + window rows, remade from its own"))


def rows() -> list[dict]:
    out = []
    for file, variant, name in MODELS:
        for line in open(DATA / file):
            r = json.loads(line)
            if r["variant"] == variant and r["kind"] == "repeat" and r["mode"] in ("offline", "online"):
                out.append(r | {"name": name})
    return out


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    data = rows()
    colours = dict(zip([name for *_, name in MODELS], ("black", "tab:red", "tab:blue", "tab:green"), strict=True))
    fig, axes = plt.subplots(2, 2, figsize=(12, 7.5), sharex=True)
    for col, mode in enumerate(("offline", "online")):
        for row, (key, label) in enumerate((("hands_per_copy", "closest hands (m)"), ("torso_per_copy", "torso (m)"))):
            ax = axes[row, col]
            for name in colours:
                picked = [r for r in data if r["name"] == name and r["mode"] == mode]
                longest = {}
                for r in picked:  # per seed the longest take
                    if r["repeats"] > longest.get(r["seed"], {"repeats": 0})["repeats"]:
                        longest[r["seed"]] = r
                for seed, r in sorted(longest.items()):
                    copies = range(1, len(r[key]) + 1)
                    ax.plot(copies, r[key], c=colours[name], lw=2 if seed == 0 else 0.8, marker="o" if seed == 0 else None,
                            ms=4, label=name if seed == 0 else None)
            ax.set_ylabel(label)
            ax.set_title(f"{'in windows (offline)' if mode == 'offline' else 'live, frame by frame'}")
            ax.grid(alpha=0.3)
        axes[1, col].set_xlabel("copy of the held-out leader")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Held-out s04 leaders played again and again: seed 0 (thick), seeds 1 and 2 (thin, windows only)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
