"""Long takes over several seeds: per variant and take length, each copy's closest hands and torso distance minus the
single clip's of the same seed, averaged over the seeds with a 95 % t interval, beside the bar (hands <= the clip's
+ 0.03 m, torso <= + 0.05 m in every copy).

One seed's draw is shared by every leader of a length (sampler.py `initial_noise`), so the mean over the 49 leaders
moves with the seed (the single clip's closest hands: 0.28-0.36 m over seeds 0-3), and a copy is compared with the
clip of its own seed: with one seed for all leaders, the interval is over the seeds; with a seed per leader
(`long_takes.py --seed-per-leader`, independent draws), over the leaders, each copy paired with its leader's clip.
Reads the rows of `long_takes.py` (one per variant, seed, mode and take length):

    python docs/experiments/scripts/long_takes_seeds.py docs/experiments/data/long-takes-resample.jsonl --against resample-0
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

import numpy as np
from scipy import stats

BARS = {"hands": 0.03, "torso": 0.05}  # a copy at most this far (m) beyond the single clip


def interval(values: list[float]) -> tuple[float, float, float]:
    v = np.asarray(values, float)
    if len(v) < 2:
        return float(v.mean()), float("nan"), float("nan")
    half = stats.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v))
    return float(v.mean()), float(v.mean() - half), float(v.mean() + half)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows", nargs="+", help="long_takes.py output files (JSON lines)")
    ap.add_argument("--kind", default="repeat")
    ap.add_argument("--against", default=None, help="also each variant's copies minus this variant's, paired by seed and leader")
    args = ap.parse_args()
    rows = [json.loads(line) for path in args.rows for line in open(path) if line.strip()]
    rows = [r for r in rows if r["mode"] == "offline" and r["kind"] == args.kind]
    per_leader = lambda r: bool(r.get("seed_per_leader"))  # noqa: E731
    clips = {(r["variant"], per_leader(r), r["seed"]): r for r in rows if r["repeats"] == 1}
    takes = defaultdict(dict)  # (variant, a seed per leader, repeats) -> seed -> row
    for r in rows:
        if r["repeats"] > 1 and (r["variant"], per_leader(r), r["seed"]) in clips:
            takes[(r["variant"], per_leader(r), r["repeats"])][r["seed"]] = r
    for (variant, by_leader, k), by_seed in sorted(takes.items()):
        seeds = sorted(by_seed)
        over = "leaders, each its own seed" if by_leader else "seeds, one for every leader"
        print(f"\n{variant}, {args.kind} x{k}, seeds {seeds}; the interval over {over}")
        for figure in ("hands", "torso"):
            clip_rows = [clips[(variant, by_leader, s)] for s in seeds]
            print(f"  {figure}: the clip {np.mean([r[f'{figure}_per_copy'][0] for r in clip_rows]):.3f} m; each copy minus "
                  f"the clip, mean [95 %] (bar + {BARS[figure]:.2f}):")
            cells = []
            for c in range(k):
                if by_leader:
                    gaps = [g for s, r in zip(seeds, clip_rows, strict=True)
                            for g in np.array(by_seed[s][f"{figure}_per_leader"])[:, c] - np.array(r[f"{figure}_per_leader"])[:, 0]]
                else:
                    gaps = [by_seed[s][f"{figure}_per_copy"][c] - r[f"{figure}_per_copy"][0] for s, r in zip(seeds, clip_rows, strict=True)]
                mean, low, high = interval(gaps)
                cells.append(f"{mean:+.3f} [{low:+.3f}, {high:+.3f}]{'' if mean <= BARS[figure] else ' over'}")
            print("    " + "; ".join(cells))
            base = takes.get((args.against, by_leader, k), {})
            paired = [s for s in seeds if s in base]
            if args.against and variant != args.against and paired and by_leader:
                cells = []
                for c in range(k):
                    gaps = [g for s in paired for g in np.array(by_seed[s][f"{figure}_per_leader"])[:, c]
                            - np.array(base[s][f"{figure}_per_leader"])[:, c]]
                    mean, low, high = interval(gaps)
                    cells.append(f"{mean:+.3f} [{low:+.3f}, {high:+.3f}]")
                print(f"    minus {args.against}'s, seeds {paired}: " + "; ".join(cells))


if __name__ == "__main__":
    main()
