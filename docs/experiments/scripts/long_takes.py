"""Long takes and live reactions: how engaged the default model's follower stays when the leader goes on.

Each held-out leader of the model's fold is played k times in a row (k = 1, 4, 8; the copies joined end to end, the
leader jumping back at each join) and the model reacts with the leader's true class, seed 0. Per copy: the closest
hand-to-hand distance (over the copy's frames, the nearest of the leader's hands to the nearest of the follower's) and
the torso distance (the two torso joints, mean over the copy's frames), each averaged over leaders, beside the same
figures of the recorded followers (one clip). `--online` also reacts frame by frame (`model.online`, as shipped) and
times each push.

    python docs/experiments/scripts/long_takes.py --repeats 1 4 8 --online --gan sample_data/imm_sbu.safetensors \
        --out docs/experiments/data/long-takes.jsonl
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.data.splits import loso_fold
from imm_model.families.base import ReactionModel

HANDS = ("left_hand", "right_hand")


def copy_figures(leader: np.ndarray, follower: np.ndarray, skeleton, copies: int) -> list[dict]:
    """World leader and follower (k*T, J, 3) -> per copy: closest hands (m) and mean torso distance (m)."""
    names = skeleton.joint_names
    hands = [names.index(h) for h in HANDS]
    torso = names.index("torso")
    frames = len(leader) // copies
    out = []
    for c in range(copies):
        seg = slice(c * frames, (c + 1) * frames)
        gaps = np.linalg.norm(leader[seg][:, hands, None] - follower[seg][:, None, hands], axis=-1)
        out.append({"hands": float(gaps.min()), "torso": float(np.linalg.norm(leader[seg, torso] - follower[seg, torso], axis=-1).mean())})
    return out


def online_follower(model, leader: np.ndarray, label: dict, seed: int) -> tuple[np.ndarray, list[float]]:
    reactor = model.online(label, seed=seed)
    frames, times = [], []
    for frame in leader:
        start = time.perf_counter()
        out = reactor.push(frame)
        times.append(time.perf_counter() - start)
        if out is not None:
            frames.append(out)
    rest = reactor.flush()
    return np.concatenate([np.stack(frames), rest]) if frames else rest, times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(paths.SAMPLE_DEFAULT))
    ap.add_argument("--repeats", type=int, nargs="+", default=[1, 4, 8])
    ap.add_argument("--online", action="store_true", help="also react frame by frame")
    ap.add_argument("--gan", default=None, help="also this GAN checkpoint's reaction to the same takes (a reference)")
    ap.add_argument("--limit", type=int, default=None, help="the first N held-out leaders only")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="append one JSON line per (mode, repeats) here")
    args = ap.parse_args()

    data = load_any(paths.SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    held_out = loso_fold(data.subject_pairs, model.held_out_subject).test[: args.limit]
    modes = ["real", "offline"] + (["online"] if args.online else []) + (["gan"] if args.gan else [])
    gan = ReactionModel.load(args.gan) if args.gan else None
    for mode in modes:
        for k in [1] if mode == "real" else args.repeats:
            per_copy, push_times = [], []
            for i in held_out:
                leader = np.concatenate([data.world(i)[0]] * k)
                label = {data.class_names[data.actions[i]]: 1.0}
                if mode == "real":  # the recorded follower of the single clip: where real reactions stand
                    follower = data.world(i)[1]
                elif mode in ("offline", "gan"):
                    follower = (model if mode == "offline" else gan).synthesize(leader, label, seed=args.seed)
                else:
                    follower, times = online_follower(model, leader, label, args.seed)
                    push_times += times
                per_copy.append(copy_figures(leader, follower, model.skeleton, k))
            hands = np.array([[c["hands"] for c in row] for row in per_copy])
            torso = np.array([[c["torso"] for c in row] for row in per_copy])
            row = {"mode": mode, "repeats": k, "leaders": len(held_out), "fold": model.held_out_subject,
                   "checkpoint": args.gan if mode == "gan" else args.checkpoint, "seed": args.seed,
                   "hands_per_copy": hands.mean(0).round(4).tolist(), "torso_per_copy": torso.mean(0).round(4).tolist()}
            if push_times:
                row["push_ms_median"] = round(1000 * float(np.median(push_times)), 2)
                row["push_ms_p95"] = round(1000 * float(np.percentile(push_times, 95)), 2)
            print(json.dumps(row))
            if args.out:
                with open(args.out, "a") as f:
                    f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
