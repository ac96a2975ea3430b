"""Continuous long takes: recorded leaders played one after another, each starting where and as the one before ended
(canonical.py `joined`), so that the leader goes on through the room as in a long real take and never jumps back
(unlike `long_takes.py`'s repeated takes).

Two kinds of take:
- `sbu`: each held-out leader of the model's fold and the next `--copies - 1` held-out leaders of its class (in the
  fold's order); the reaction uses their class. The recorded followers, moved with their leaders, are "real".
- `walk`: K3HI leaders who walk up to their partner ("approaching"; real walking, which SBU has none of), `--copies`
  in a row, 8 takes; the reaction is asked for `--walk-label` (shaking hands: someone walking up to shake hands).

Each reaction seed 0. Per copy: the closest hand-to-hand distance and the mean torso distance (as `long_takes.py`),
averaged over takes; per take the mean torso distance over its last quarter and the largest joint step from one
frame to the next (a jump); and the share of frames with a bone folded onto itself (`--raw`: the network's own
frames). Reactions: the live reactor (`model.online`, live.py) with its frame following the leader at `--reanchor`
metres (live.REANCHOR_M; `inf`: fixed at the take's start), the windows' live reaction (windows.py `OnlineReactor`),
the offline long take (windows) and, for `sbu`, the recorded followers.

    OMP_NUM_THREADS=1 python docs/experiments/scripts/continuous_takes.py --source sbu --reanchor inf \\
        --out docs/experiments/data/continuous-takes.jsonl

Record: docs/experiments/causal-reactor.md ("Continuous takes and a leader who walks").
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from long_takes import HANDS, online_follower

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.data.canonical import joined
from imm_model.data.k3hi import load_k3hi
from imm_model.data.splits import loso_fold
from imm_model.families.base import ReactionModel
from imm_model.families.diffusion import live
from imm_model.families.diffusion.windows import OnlineReactor

WALK_TAKES = 8
FOLDED = 0.3  # a bone shorter than this share of its length is folded onto itself (a knee on its foot)


def per_copy(leader: np.ndarray, follower: np.ndarray, starts: list[int], skeleton) -> list[dict]:
    names = skeleton.joint_names
    hands, torso = [names.index(h) for h in HANDS], names.index("torso")
    bounds = [*starts, len(leader)]
    out = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        gaps = np.linalg.norm(leader[a:b][:, hands, None] - follower[a:b][:, None, hands], axis=-1)
        out.append({"hands": float(gaps.min()),
                    "torso": float(np.linalg.norm(leader[a:b, torso] - follower[a:b, torso], axis=-1).mean())})
    return out


def sbu_takes(data, model, copies: int) -> list[tuple[np.ndarray, np.ndarray | None, list[int], dict]]:
    test = loso_fold(data.subject_pairs, model.held_out_subject).test
    takes = []
    for n, i in enumerate(test):
        same = [int(j) for j in np.roll(test, -n) if data.actions[j] == data.actions[i]][:copies]
        if len(same) == copies:
            (leader, real), starts = joined([data.world(j) for j in same], model.skeleton)
            takes.append((leader, real, starts, {data.class_names[data.actions[i]]: 1.0}))
    return takes


def walk_takes(model, copies: int, label: str) -> list[tuple[np.ndarray, None, list[int], dict]]:
    walking = [s.leader for s in load_k3hi(paths.k3hi_raw_root()).interactions if s.action == "approaching"]
    takes = []
    for k in range(WALK_TAKES):
        (leader,), starts = joined([(walking[(k + WALK_TAKES * c) % len(walking)],) for c in range(copies)], model.skeleton)
        takes.append((leader, None, starts, {label: 1.0}))
    return takes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(paths.SAMPLE_DEFAULT))
    ap.add_argument("--source", choices=("sbu", "walk"), default="sbu")
    ap.add_argument("--copies", type=int, default=4)
    ap.add_argument("--walk-label", default="shaking_hands")
    ap.add_argument("--modes", nargs="+", default=["real", "live", "windows", "offline"],
                    choices=("real", "live", "windows", "offline"))
    ap.add_argument("--reanchor", type=float, default=None,
                    help="live.REANCHOR_M: the live reactor's frame follows the leader this far behind (inf: fixed)")
    ap.add_argument("--raw", action="store_true", help="the network's own frames, no clean-up (the folded bones' share)")
    ap.add_argument("--limit", type=int, default=None, help="the first N takes only")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.reanchor is not None:
        live.REANCHOR_M = args.reanchor

    model = ReactionModel.load(args.checkpoint)
    model.raw = args.raw
    lengths = np.asarray(model.bone_lengths)
    sk, torso = model.skeleton, model.skeleton.joint_names.index("torso")
    if args.source == "sbu":
        takes = sbu_takes(load_any(paths.SAMPLE_DATA), model, args.copies)
    else:
        takes = walk_takes(model, args.copies, args.walk_label)
    takes = takes[: args.limit]
    for mode in args.modes:
        if mode == "real" and takes[0][1] is None:
            continue
        copies, last, jumps, folded = [], [], [], []
        for leader, real, starts, label in takes:
            if mode == "real":
                follower = real
            elif mode == "offline":
                follower = model.synthesize(leader, label, seed=0)
            elif mode == "live":
                follower = online_follower(model, leader, label, 0)[0]
            else:
                reactor = OnlineReactor(model.takes or model, label, 1.0, 0)
                frames = [f for f in (reactor.push(x) for x in leader) if f is not None]
                follower = np.concatenate([np.stack(frames), reactor.flush()])
            copies.append(per_copy(leader, follower, starts, sk))
            apart = np.linalg.norm(follower[:, torso] - leader[:, torso], axis=-1)
            last.append(float(apart[-len(leader) // 4:].mean()))
            jumps.append(float(np.linalg.norm(np.diff(follower, axis=0), axis=-1).max()))
            folded.append((sk.bone_lengths(follower) / lengths).min(1) < FOLDED)
        hands = np.array([[c["hands"] for c in r] for r in copies])
        torso_d = np.array([[c["torso"] for c in r] for r in copies])
        row = {"source": args.source, "mode": mode, "fold": model.held_out_subject, "copies": args.copies,
               "takes": len(takes), "raw": args.raw, "reanchor_m": live.REANCHOR_M if mode == "live" else None,
               "hands_per_copy": hands.mean(0).round(4).tolist(), "torso_per_copy": torso_d.mean(0).round(4).tolist(),
               "torso_last_quarter": round(float(np.mean(last)), 4), "torso_last_quarter_max": round(max(last), 4),
               "folded_frames": round(float(np.concatenate(folded).mean()), 4),
               "takes_with_folded": int(sum(f.any() for f in folded)),
               "largest_step_m": round(float(np.mean(jumps)), 4), "largest_step_max_m": round(max(jumps), 4),
               "hands_per_take": hands.round(4).tolist(), "torso_per_take": torso_d.round(4).tolist(),
               "torso_last_quarter_per_take": np.round(last, 4).tolist(), "largest_step_per_take": np.round(jumps, 4).tolist()}
        print(json.dumps({k: v for k, v in row.items() if not k.endswith("per_take")}), flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
