"""How engaged the live reaction stays against the offline one, leader by leader: the rows of `long_takes.py --online
--seed-per-leader` (one run per live setting, a sampler step count a push takes and a growth of the windows' weights,
and seed base), per setting the single clip's closest hands and torso distance live minus offline, paired by leader
and seed and pooled over the seed bases, with a 95 % t interval over the takes, beside the bar (live hands <= offline
+ 0.05 m, torso <= + 0.08 m), and each setting against `--against` steps at growth 1 (as shipped before).

    python docs/experiments/scripts/long_takes.py --repeats 1 --online --live-steps S --seed B --seed-per-leader \
        --variant live-steps-S --out docs/experiments/data/live-steps-takes.jsonl
    python docs/experiments/scripts/live_engagement.py docs/experiments/data/live-steps-takes.jsonl --against 7
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from long_takes_seeds import interval

BARS = {"hands": 0.05, "torso": 0.08}  # live at most this far (m) beyond the offline reaction


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rows")
    ap.add_argument("--against", type=int, default=None, help="a step count (at growth 1) every other setting is paired with, take by take")
    args = ap.parse_args()
    offline, live = {}, {}  # seed base -> row; ((steps, growth), seed base) -> row
    for line in open(args.rows):
        row = json.loads(line)
        if row["repeats"] == 1 and row.get("seed_per_leader") and row["mode"] == "offline":
            offline[row["seed"]] = row
        elif row["repeats"] == 1 and row.get("seed_per_leader") and row["mode"] == "online":
            live[(row["live_steps"], row.get("ensemble_growth", 1.0)), row["seed"]] = row
    settings = sorted({s for s, _ in live}, key=lambda s: (-s[0], s[1]))

    def takes(s: tuple, figure: str, seeds: list[int]) -> np.ndarray:
        return np.concatenate([np.array(live[s, b][f"{figure}_per_leader"], float)[:, 0] for b in seeds])

    print("| steps, growth | seed bases | takes | figure | offline (m) | live (m) | live - offline [95 % t] | bar |"
          + (f" live - live at {args.against} steps [95 % t] |" if args.against else ""))
    print("|---:|---|---:|---|---:|---:|---:|---:|" + ("---:|" if args.against else ""))
    against = None if args.against is None else (args.against, 1.0)
    for s in settings:
        seeds = sorted(b for t, b in live if t == s and b in offline)
        for figure, bar in BARS.items():
            mine = takes(s, figure, seeds)
            theirs = np.concatenate([np.array(offline[b][f"{figure}_per_leader"], float)[:, 0] for b in seeds])
            mean, lo, hi = interval(list(mine - theirs))
            cells = [f"{s[0]}, {s[1]:g}", " ".join(map(str, seeds)), str(len(mine)), figure, f"{theirs.mean():.3f}", f"{mine.mean():.3f}",
                     f"{mean:+.3f} [{lo:+.3f}, {hi:+.3f}]", f"{bar:+.2f}: {'met' if mean <= bar else 'not met'}"]
            if args.against is not None:
                both = [b for b in seeds if (against, b) in live]
                if s != against and both:
                    mean, lo, hi = interval(list(takes(s, figure, both) - takes(against, figure, both)))
                    cells.append(f"{mean:+.3f} [{lo:+.3f}, {hi:+.3f}]")
                else:
                    cells.append("")
            print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
