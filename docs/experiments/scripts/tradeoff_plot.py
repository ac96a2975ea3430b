"""Every scored diffusion row of the experiments' data files on two planes that hold the reaction model's bars:
a single sample's AFD (over the fold's 1-NN retrieval's) against the variations' spread (over the real followers'
spread against one leader), and FID (over the 1-NN's) against the limbs' speed between the ends (over real).

    python docs/experiments/scripts/tradeoff_plot.py docs/experiments/data/*.jsonl --out docs/experiments/data/tradeoffs.png

A point is one checkpoint x fold x sampler setting, coloured by its data file (the experiment), filled on dev folds and
hollow on test folds; the dashed lines are the bars (AFD <= 0.8, variations >= 0.5, FID <= 1, limbs >= 0.8). Prints,
for every two of the four figures, the rows' Spearman rank correlation and how many rows meet both bars.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from fold_means import DEV, read_rows  # noqa: E402

# each figure's bar: (threshold, True when the bar is an upper limit)
BARS = {"afd": (0.8, True), "variations": (0.5, False), "fid": (1.0, True), "limbs": (0.8, False)}


def meets(point: dict, figure: str) -> bool:
    threshold, upper = BARS[figure]
    return point[figure] <= threshold if upper else point[figure] >= threshold


def points(paths: list[Path]) -> list[dict]:
    """Rows with every figure both planes need, as ratios to their references."""
    out = []
    for r in read_rows(paths):
        if r.get("multimodality") is None or not r.get("afd_nn1") or not r.get("fid_nn1") or not r.get("real_same_leader_diversity"):
            continue
        out.append({"file": r["file"], "dev": r["fold"] in DEV, "afd": r["afd"] / r["afd_nn1"],
                    "variations": r["multimodality"] / r["real_same_leader_diversity"], "fid": r["fid"] / r["fid_nn1"],
                    "limbs": r["interior_limb_speed_ratio"]})
    return out


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import spearmanr

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", type=Path, nargs="+")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    pts = points(args.files)
    files = sorted({p["file"] for p in pts})
    colours = dict(zip(files, plt.cm.tab20(np.linspace(0, 1, len(files))), strict=True))
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2))
    planes = (("variations", "afd", "variations / real (one leader)", "single-sample AFD / 1-NN", 0.5, 0.8),
              ("limbs", "fid", "limb speed between the ends / real", "FID / 1-NN", 0.8, 1.0))
    for ax, (x, y, xlabel, ylabel, xbar, ybar) in zip(axes, planes, strict=True):
        for f in files:
            for dev in (True, False):
                sel = [p for p in pts if p["file"] == f and p["dev"] == dev]
                if sel:
                    ax.scatter([p[x] for p in sel], [p[y] for p in sel], s=22, edgecolors=colours[f],
                               facecolors=colours[f] if dev else "none", label=f if dev else None)
        ax.axvline(xbar, ls="--", c="grey", lw=1)
        ax.axhline(ybar, ls="--", c="grey", lw=1)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        rho = spearmanr([p[x] for p in pts], [p[y] for p in pts]).statistic
        both = sum(meets(p, x) and meets(p, y) for p in pts)
        ax.set_title(f"{len(pts)} rows; Spearman {rho:+.2f}; meeting both bars: {both}")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Reaction diffusion rows of docs/experiments/data (filled: dev folds; hollow: test folds)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"{len(pts)} rows\n| figures | Spearman | rows meeting both bars |\n|---|---:|---:|")
    for a, b in itertools.combinations(BARS, 2):
        rho = spearmanr([p[a] for p in pts], [p[b] for p in pts]).statistic
        print(f"| {a}, {b} | {rho:+.2f} | {sum(meets(p, a) and meets(p, b) for p in pts)} |")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
