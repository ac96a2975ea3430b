"""Long takes and live reactions: how engaged the follower stays when the leader goes on, and how smoothly it moves.

Each held-out leader of the model's fold is played k times in a row (k = 1, 4, 8; "repeat": the copies joined end to
end, the leader jumping back at each join; "pingpong": every other copy played backwards, so that the leader never
jumps) and the model reacts with the leader's true class, seed 0. Per copy: the closest hand-to-hand distance (over
the copy's frames, the nearest of the leader's hands to the nearest of the follower's) and the torso distance (the two
torso joints, mean over the copy's frames), each averaged over leaders, beside the recorded followers of the single
clip ("real"). And how the follower moves: per leader the largest mean-joint step from one frame to the next (m), at
the frames where a window of a long take begins ("seam": its first new frame) and elsewhere, averaged over leaders,
beside the single clip sampled whole and the recorded follower (raw network output, no clean-up, for the steps).

`--online` also reacts frame by frame (`model.online`) and times each push; `--gan` adds a GAN's reaction to the same
takes; `--whole` samples each take as one clip, as the model did before windows; `--own-takes` has a student make its
takes itself instead of its teacher; `--label-scale` sets the label's guidance scale of the model that makes them;
`--resample` how many times a window takes each sampler step again (windows.py RESAMPLE).
`--window/--online-window/--blend/--stride/--lookahead/--live-steps/--take-lookahead/--continue-level/--ensemble-growth/
--anchor` set the windows (imm_model/families/diffusion/windows.py) for the variants the record compares; without them,
as shipped.

    python docs/experiments/scripts/long_takes.py --repeats 1 4 8 --online --gan sample_data/imm_sbu.safetensors \\
        --out docs/experiments/data/long-takes.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.data.canonical import CanonicalFrame
from imm_model.data.splits import loso_fold
from imm_model.families.base import ReactionModel
from imm_model.families.diffusion import windows

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


def steps(motion: np.ndarray) -> np.ndarray:
    """(T, J, 3) -> (T - 1,) the mean joint displacement from each frame to the next (m)."""
    return np.linalg.norm(np.diff(motion, axis=0), axis=-1).mean(1)


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


def take(clip: np.ndarray, k: int, kind: str) -> np.ndarray:
    return np.concatenate([clip if kind == "repeat" or c % 2 == 0 else clip[::-1] for c in range(k)])


def set_windows(args) -> None:
    """The windows' settings for a variant (module constants, read at every call)."""
    for name in ("window", "online_window", "blend", "stride", "lookahead", "take_lookahead", "live_steps"):
        if getattr(args, name) is not None:
            setattr(windows, name.upper(), getattr(args, name))
    if args.continue_level is not None:
        windows.CONTINUE_LEVEL = args.continue_level
    if args.ensemble_growth is not None:
        windows.ENSEMBLE_GROWTH = args.ensemble_growth
    if args.anchor == "own":  # every window standardized on its own first frames
        windows.anchored = lambda model, leader, anchor: CanonicalFrame.from_leader(
            np.asarray(leader, np.float64), model.skeleton, model.canonical_mode)
    elif args.anchor == "fixed":  # every window in the first one's frame
        windows.REANCHOR_M, windows.REANCHOR_DEG = float("inf"), 360.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(paths.SAMPLE_DEFAULT))
    ap.add_argument("--repeats", type=int, nargs="+", default=[1, 4, 8])
    ap.add_argument("--kind", choices=("repeat", "pingpong"), default="repeat")
    ap.add_argument("--online", action="store_true", help="also react frame by frame")
    ap.add_argument("--gan", default=None, help="also this GAN checkpoint's reaction to the same takes (a reference)")
    ap.add_argument("--limit", type=int, default=None, help="the first N held-out leaders only")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seed-per-leader", action="store_true",
                    help="leader n reacts with seed + n (a seed's draw is shared by every leader of a length)")
    ap.add_argument("--window", type=int, default=None)
    ap.add_argument("--online-window", type=int, default=None)
    ap.add_argument("--blend", type=int, default=None)
    ap.add_argument("--stride", type=int, default=None)
    ap.add_argument("--lookahead", type=int, default=None, help="live")
    ap.add_argument("--live-steps", type=int, default=None, help="live: sampler steps a push takes")
    ap.add_argument("--take-lookahead", type=int, default=None, help="offline, a long take's windows")
    ap.add_argument("--continue-level", type=float, default=None)
    ap.add_argument("--ensemble-growth", type=float, default=None,
                    help="live: how much more each later window's sample of a frame weighs")
    ap.add_argument("--anchor", choices=("shipped", "own", "fixed"), default="shipped")
    ap.add_argument("--whole", action="store_true", help="sample every take whole, as one clip (no windows)")
    ap.add_argument("--own-takes", action="store_true", help="a student makes its long takes itself, not its teacher")
    ap.add_argument("--label-scale", type=float, default=None, help="the label's guidance scale for the takes' model")
    ap.add_argument("--resample", type=int, default=None, help="a window's steps each taken again this many times (RePaint)")
    ap.add_argument("--variant", default="shipped", help="a name for the row")
    ap.add_argument("--out", default=None, help="append one JSON line per (mode, repeats) here")
    args = ap.parse_args()
    set_windows(args)

    data = load_any(paths.SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    if args.whole:
        model.window = model.max_length
    if args.own_takes:
        model.takes = None
    if args.label_scale is not None:
        takes = model.takes or model
        takes.guidance = replace(takes.guidance, label_scale=args.label_scale)
    if args.resample is not None:
        (model.takes or model).resample = args.resample
    gan = ReactionModel.load(args.gan) if args.gan else None
    held_out = loso_fold(data.subject_pairs, model.held_out_subject).test[: args.limit]
    modes = ["real", "offline"] + (["online"] if args.online else []) + (["gan"] if gan else [])
    for mode in modes:
        for k in [1] if mode == "real" else args.repeats:
            per_copy, push_times, seam, elsewhere = [], [], [], []
            for n, i in enumerate(held_out):
                seed = args.seed + n if args.seed_per_leader else args.seed
                clip, real = data.world(i)
                leader = take(clip, k, args.kind)
                label = {data.class_names[data.actions[i]]: 1.0}
                if mode == "real":  # the recorded follower of the single clip: where real reactions stand
                    follower = real
                elif mode in ("offline", "gan"):
                    follower = (model if mode == "offline" else gan).synthesize(leader, label, seed=seed)
                else:
                    follower, times = online_follower(model, leader, label, seed)
                    push_times += times
                per_copy.append(copy_figures(leader, follower, model.skeleton, k))
                if mode != "gan":
                    raw = follower if mode == "real" else _raw(model, mode, leader, label, seed)
                    st = steps(raw)
                    starts = _seams(len(leader), model) if mode == "offline" and len(leader) > model.window else (
                        np.arange(len(st)) if mode == "online" else np.zeros(0, int))
                    seam.append(float(st[starts].max()) if len(starts) else float("nan"))
                    rest = np.setdiff1d(np.arange(len(st)), starts)
                    elsewhere.append(float(st[rest].max()) if len(rest) else float("nan"))
            hands = np.array([[c["hands"] for c in row] for row in per_copy])
            torso = np.array([[c["torso"] for c in row] for row in per_copy])
            row = {"variant": args.variant, "kind": args.kind, "mode": mode, "repeats": k, "leaders": len(held_out),
                   "fold": model.held_out_subject, "checkpoint": args.gan if mode == "gan" else args.checkpoint,
                   "seed": args.seed, "seed_per_leader": args.seed_per_leader, "window": windows.WINDOW,
                   "online_window": windows.ONLINE_WINDOW, "blend": windows.BLEND,
                   "stride": windows.STRIDE, "lookahead": windows.LOOKAHEAD, "live_steps": windows.LIVE_STEPS,
                   "take_lookahead": windows.TAKE_LOOKAHEAD,
                   "continue_level": windows.CONTINUE_LEVEL, "ensemble_growth": windows.ENSEMBLE_GROWTH,
                   "anchor": args.anchor, "resample": (model.takes or model).resample,
                   "hands_per_copy": hands.mean(0).round(4).tolist(), "torso_per_copy": torso.mean(0).round(4).tolist(),
                   "hands_per_leader": hands.round(4).tolist(), "torso_per_leader": torso.round(4).tolist()}
            if seam:
                row["seam_step_m"] = None if np.isnan(seam).all() else round(float(np.nanmean(seam)), 4)
                row["other_step_m"] = None if np.isnan(elsewhere).all() else round(float(np.nanmean(elsewhere)), 4)
            if push_times:
                row["push_ms_median"] = round(1000 * float(np.median(push_times)), 2)
                row["push_ms_p95"] = round(1000 * float(np.percentile(push_times, 95)), 2)
            print(json.dumps(row), flush=True)
            if args.out:
                with open(args.out, "a") as f:
                    f.write(json.dumps(row) + "\n")


def _raw(model, mode: str, leader: np.ndarray, label: dict, seed: int) -> np.ndarray:
    """The network's own follower (no clean-up) for the step figures."""
    model.raw = True
    try:
        return model.synthesize(leader, label, seed=seed) if mode == "offline" else online_follower(model, leader, label, seed)[0]
    finally:
        model.raw = False


def _seams(frames: int, model) -> np.ndarray:
    """The steps (indices into `steps`) into each window's first new frame: frames STRIDE, 2 STRIDE, ... of the take."""
    return np.arange(windows.STRIDE, frames, windows.STRIDE) - 1


if __name__ == "__main__":
    main()
