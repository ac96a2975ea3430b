"""The online reaction against the offline one on LOSO folds: AFD (one sample and best of 5), FID, off-label adherence,
limb speed and jitter, with `imm evaluate`'s own fold judges and scores (imm_model/evaluation/loso.py).

    python docs/experiments/scripts/online_fold.py --checkpoint runs/d/fold-s01/final.safetensors --fold s01 \\
        --out docs/experiments/data/long-takes-loso.jsonl

"online" makes every follower as `model.online` does, frame by frame, each frame knowing the leader up to the
reactor's lookahead and the follower frames before it, then its causal clean-up; the many leaders a fold scores run in
lockstep, one sampler batch per frame (`online_followers`, checked against the reactor itself on a few leaders first).
"offline" is the model's own `synthesize` (clips sampled whole); "windows" makes every clip as a long take is made,
in windows (windows.take_windows). All are scored on the same test leaders and labels. `--set NAME=VALUE` changes a
windows.py setting for a variant; each row records the settings it was made with.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from diffusion_fold import record

SETTINGS = {"online": ("ONLINE_WINDOW", "LOOKAHEAD", "ENSEMBLE_GROWTH", "CONTINUE_LEVEL", "LABEL_RAMP", "LIVE_STEPS"),
            "windows": ("WINDOW", "TAKE_LOOKAHEAD", "STRIDE", "BLEND", "CONTINUE_LEVEL", "RESAMPLE")}  # recorded with each row


def online_followers(model, leaders: list[np.ndarray], label_vectors: np.ndarray, seeds) -> list[np.ndarray]:
    """What `model.online(label, seed=s)` returns for each canonical leader pushed frame by frame, then flushed."""
    from imm_model.cleanup import OnlineCleanup
    from imm_model.families.diffusion.sampler import initial_noise, leader_noise
    from imm_model.families.diffusion.windows import CONTINUE_LEVEL, LOOKAHEAD, ONLINE_WINDOW, Votes, anchored, live

    model = live(model)
    labels = model._label_input(model._label_array(label_vectors, len(leaders)))
    seeds = [0] * len(leaders) if seeds is None else [int(s) for s in seeds]
    window, d, sk = min(ONLINE_WINDOW, model.window), model.config.pose_dim, model.skeleton
    leaders = [np.asarray(a, np.float64) for a in leaders]
    noises = [initial_noise(s, len(a), d) for a, s in zip(leaders, seeds, strict=True)]
    zs = [leader_noise(s, len(a), d) for a, s in zip(leaders, seeds, strict=True)]
    raw = [np.zeros(a.shape) for a in leaders]
    votes = [Votes(a.shape[1]) for a in leaders]
    made, frames = [0] * len(leaders), [None] * len(leaders)
    for t in range(max(map(len, leaders))):  # the leader frame just pushed
        rows, jobs = [], []
        for i, a in enumerate(leaders):
            last = t == len(a) - 1
            if t >= len(a) or not (t + 1 - made[i] > LOOKAHEAD or last):
                continue
            start = max(0, t + 1 - window)
            frames[i] = anchored(model, a[start:t + 1], frames[i])
            given = frames[i].to_canonical(raw[i][start:t + 1], sk).astype(np.float32)
            rows.append(i)
            jobs.append((start, len(a) - made[i] if last else 1, frames[i].to_canonical(a[start:t + 1], sk).astype(np.float32),
                         given))
        if not rows:
            continue
        out = model._sample([j[2] for j in jobs], labels[rows], [seeds[i] for i in rows],
                            [noises[i][j[0]:t + 1] for i, j in zip(rows, jobs, strict=True)],
                            [zs[i][j[0]:t + 1] for i, j in zip(rows, jobs, strict=True)],
                            [(j[3], made[i] - j[0]) for i, j in zip(rows, jobs, strict=True)], CONTINUE_LEVEL)
        for i, (start, n, _, _), f in zip(rows, jobs, out, strict=True):
            k = made[i] - start
            raw[i][made[i]:made[i] + n] = votes[i].add(frames[i].to_world(f, sk)[k:]).take(n)
            made[i] += n
    if model.raw:
        return [r.astype(np.float32) for r in raw]
    return [OnlineCleanup(sk, model.bone_lengths)(r).astype(np.float32) for r in raw]


def check_against_the_reactor(model, data, test) -> float:
    """The largest difference (m) between `online_followers` and the reactor on the first three test leaders."""
    worst = 0.0
    for i in test[:3]:
        leader = data.canonical(int(i))[0]
        label = np.eye(len(data.class_names), dtype=np.float32)[data.actions[i]]
        reactor = model.online(label, seed=1)
        pushed = [reactor.push(f) for f in leader]
        own = np.concatenate([np.stack([p for p in pushed if p is not None]), reactor.flush()])
        batched = online_followers(model, [leader], label[None], [1])[0]
        worst = max(worst, float(np.abs(own - batched).max()))
    return worst


def table_row(model, data, judges) -> dict:
    """The LOSO table's figures of `model` (anything with `synthesize_batch_canonical`) on the fold of `judges`."""
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import method_scores, variations

    y, c = data.actions[judges.test], len(data.class_names)
    labels = np.eye(c, dtype=np.float32)[y]
    predictions = dict(zip(map(int, judges.test), model.synthesize_batch_canonical(judges.leaders, labels), strict=True))
    scores = method_scores(data, judges, predictions)
    matrix, _ = control.adherence_matrix(
        lambda lab: judges.follower_view(judges.judge, model.synthesize_batch_canonical(judges.leaders, lab)), y, c)
    spread = variations(model, data, judges, predictions)
    p = scores["plausibility"]
    return {"afd": float(np.mean([v["afd"] for v in scores["classes"].values()])), "afd_best_of_5": spread["afd_best_of_n"],
            "fid": scores["fid"], "off_label": control.off_diagonal_mean(matrix),
            "interior_limb_speed_ratio": p["interior_limb_speed_ratio"], "jitter_ratio": scores["intervals"]["jitter_ratio"],
            "foot_skate_mps": p["foot_skate_mps"], "multimodality_m": spread["multimodality_m"],
            "judge_real_accuracy": judges.real_accuracy["follower_judge"]}


def main() -> None:
    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--modes", nargs="+", default=["offline", "online"], choices=("offline", "online", "windows"))
    ap.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                    help="a windows.py setting for this variant, e.g. ENSEMBLE_GROWTH=1e12 LOOKAHEAD=8 (recorded in the row)")
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per mode here")
    args = ap.parse_args()
    from imm_model.families.diffusion import windows
    for item in args.set:
        name, value = item.split("=")
        if not hasattr(windows, name) or not name.isupper():
            ap.error(f"windows.py has no setting {name}")
        setattr(windows, name, type(getattr(windows, name))(float(value)))
    data = InteractionDataset.load(SAMPLE_DATA)
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    for mode in args.modes:
        model = ReactionModel.load(args.checkpoint)
        (model.takes or model).resample = windows.RESAMPLE  # a model reads it when it loads: --set's value
        prepare_model(model, data, args.fold, opts)
        row = {"fold": args.fold, "mode": mode, "checkpoint": str(args.checkpoint), "leaders": len(judges.test)}
        if mode != "offline":  # the windows it was made with
            row["settings"] = {name: getattr(windows, name) for name in SETTINGS[mode]}
        if mode == "windows":  # every clip made as a long take is, in windows (windows.take_windows)
            model.window = 1
        if mode == "online":
            row["reactor_difference_m"] = check_against_the_reactor(model, data, judges.test)
            model.synthesize_batch_canonical = lambda leaders, labels, seeds=None, m=model: online_followers(m, leaders, labels, seeds)
        row |= table_row(model, data, judges)
        record(row, args.out)


if __name__ == "__main__":
    main()
