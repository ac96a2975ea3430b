"""Second opinions on the default model's part mixes: the 30 ordered pairs upper:A=1, lower:B=1 on one fold's held-out
leaders, read by the project's body-part judges (temporal conv, seed 1) and by judges of other architectures that the
model never met, each trained on the fold's training subjects' real followers only: the project's classifier as a
bidirectional GRU with another seed (cache.fold_classifier, as every judge is trained), and a scikit-learn logistic
regression on fixed-length summary features of what a part judge reads (body_part_view: the part's joints about the
body centre; the legs' judge also the centre itself), once on positions and velocities (`sklearn`) and once on
positions alone (`sklearn-positions`: does it read the motion's speed or its posture?).

Per judge family: its accuracy on the fold's real held-out followers per part; the share of the model's part mixes
read as asked (the project's rule, control.part_pair_table: the upper judge at PART_SHARE or more for A and the lower
judge at PART_SHARE or more for B; and by argmax alike), the pairs under 0.10, the worst pairs, and the same share for
composites of real held-out followers (A's trunk and arms on B's legs, loso.held_out_composites), with 95 %
percentile-bootstrap intervals over the fold's held-out sequences (the same draws for the model's leaders and for the
followers the composites are made of); and, as a control, the share of the unmixed labels upper:A=1, lower:A=1 read
as asked, per class, and (no judge's figure) how fast each part of those reactions moves beside the class's real
held-out followers. One JSON line per judge family (docs/experiments/part-judges-second.md).

    OMP_NUM_THREADS=1 python docs/experiments/scripts/part_judges_second.py --fold s04 --seed 0 \\
        --out docs/experiments/data/part-judges-second.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from itertools import permutations
from pathlib import Path

import numpy as np

PARTS = ("upper", "lower")
FAMILIES = ("conv", "gru", "sklearn", "sklearn-positions")
UNDER = 0.10  # a pair reads as asked for fewer than this share of leaders: "under 0.10"
C_GRID = (0.003, 0.01, 0.03, 0.1, 0.3, 1.0)  # the logistic regression's inverse L2 strengths, chosen by grouped CV
AUGMENTED_COPIES = 4  # extra copies of each training sequence under the project's judges' augmentation (classifier.augment)


# ---- the non-neural judge --------------------------------------------------------------------------
def part_joints(skeleton, part: str) -> list[int]:
    """The joints body_part_view fills for `part`: trunk and arms, or legs and the centre in the root's slot."""
    from imm_model.model.body_parts import part_indices

    upper, legs, _ = part_indices(skeleton)
    return upper if part == "upper" else sorted([*legs, skeleton.root])


def summary_features(views: list[np.ndarray], joints: list[int], velocities: bool = True) -> np.ndarray:
    """Part views (T, J*3) as classifier.motion_inputs gives them -> (N, F): per joint and axis the mean, std, min and
    max over time of the position and (`velocities`) of the per-frame velocity, and per joint the mean and max speed
    (26 a joint; 12 with positions only). No length."""
    rows = []
    for v in views:
        p = np.asarray(v, np.float64).reshape(len(v), -1, 3)[:, joints]
        d = np.diff(p, axis=0) if len(p) > 1 else np.zeros_like(p)
        speed = np.linalg.norm(d, axis=-1)
        stats = [f(x, 0).ravel() for x in ((p, d) if velocities else (p,)) for f in (np.mean, np.std, np.min, np.max)]
        rows.append(np.concatenate(stats + ([speed.mean(0), speed.max(0)] if velocities else [])))
    return np.stack(rows)


class SummaryJudge:
    """Standardized summary features -> multinomial logistic regression (L2), C chosen by leave-one-subject-pair-out
    accuracy on the training sequences, trained on them and AUGMENTED_COPIES augmented copies of each."""

    def __init__(self, part: str, skeleton, views: list[np.ndarray], labels: np.ndarray, groups: np.ndarray, seed: int,
                 velocities: bool = True):
        from sklearn.linear_model import LogisticRegression
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler

        self.part, self.joints, self.velocities = part, part_joints(skeleton, part), velocities
        copies = self._augmented(views, seed)  # [original, copy 1, ...], each a list of views
        feats = [summary_features(c, self.joints, velocities) for c in copies]
        labels, groups = np.asarray(labels), np.asarray(groups)

        def fit(c: float, rows: np.ndarray):
            model = make_pipeline(StandardScaler(), LogisticRegression(C=c, max_iter=5000))
            return model.fit(np.concatenate([f[rows] for f in feats]), np.tile(labels[rows], len(feats)))

        self.cv_accuracy = {}
        for c in C_GRID:
            hits = [fit(c, groups != g).predict(feats[0][groups == g]) == labels[groups == g] for g in np.unique(groups)]
            self.cv_accuracy[c] = float(np.concatenate(hits).mean())
        self.c = max(C_GRID, key=lambda c: (self.cv_accuracy[c], -c))  # ties: the stronger regularization
        self.model = fit(self.c, np.ones(len(labels), bool))

    @staticmethod
    def _augmented(views: list[np.ndarray], seed: int) -> list[list[np.ndarray]]:
        import torch

        from imm_model.model.classifier import augment
        from imm_model.model.classifier_config import ClassifierConfig

        cfg, gen = ClassifierConfig(), torch.Generator().manual_seed(seed)
        out = [views]
        for _ in range(AUGMENTED_COPIES):
            out.append([augment(torch.from_numpy(np.asarray(v, np.float32))[None], cfg, gen)[0].numpy() for v in views])
        return out

    def probs(self, views: list[np.ndarray]) -> np.ndarray:
        return self.model.predict_proba(summary_features(views, self.joints, self.velocities))


# ---- reading --------------------------------------------------------------------------------------
def judge_views(family: str, judges, data, fold: str, gru_seed: int, seed: int) -> tuple[dict, dict]:
    """{part: followers -> (N, C) probabilities} for one judge family, and what describes it."""
    from imm_model import cache
    from imm_model.model import classifier as classifiers
    from imm_model.model.classifier_config import ClassifierConfig

    if family == "conv":
        return ({part: (lambda f, part=part: judges.part_view(part, f)) for part in PARTS},
                {part: judges.parts[part].cfg.to_dict() for part in PARTS})
    if family == "gru":
        nets = {part: cache.fold_classifier(ClassifierConfig(inputs=part, arch="gru", seed=gru_seed), data, fold, progress=False)
                for part in PARTS}
        return ({part: (lambda f, part=part: classifiers.classify(nets[part], classifiers.motion_inputs(judges.leaders, f, part))[0])
                 for part in PARTS}, {part: nets[part].cfg.to_dict() for part in PARTS})
    train = judges.train
    followers = [data.canonical(int(i))[1] for i in train]
    models = {part: SummaryJudge(part, data.skeleton, classifiers.motion_inputs(followers, followers, part), data.actions[train],
                                 np.asarray(data.subject_pairs)[train], seed, velocities=family == "sklearn") for part in PARTS}
    return ({part: (lambda f, part=part: models[part].probs(classifiers.motion_inputs(f, f, part))) for part in PARTS},
            {part: {"model": "StandardScaler + LogisticRegression (L2, multinomial)", "C": m.c, "augmented_copies": AUGMENTED_COPIES,
                    "cv_accuracy_by_C": m.cv_accuracy, "features": len(m.joints) * (26 if m.velocities else 12)}
                   for part, m in models.items()})


def part_speed(followers: list[np.ndarray], joints: list[int], part: str, fps: float) -> float:
    """Mean speed (m/s) over frames and joints of what a part judge reads of the followers (body_part_view)."""
    from imm_model.model import classifier as classifiers

    views = classifiers.motion_inputs(followers, followers, part)
    return float(np.mean([np.linalg.norm(np.diff(v.reshape(len(v), -1, 3)[:, joints], axis=0), axis=-1).mean() for v in views]) * fps)


def reads(pu: np.ndarray, pl: np.ndarray, a: int, b: int) -> dict[str, np.ndarray]:
    """Whether each reaction reads as asked: the project's rule (each part judge at PART_SHARE or more), and by argmax."""
    from imm_model.evaluation.control import PART_SHARE

    return {"share": (pu[:, a] >= PART_SHARE) & (pl[:, b] >= PART_SHARE), "argmax": (pu.argmax(1) == a) & (pl.argmax(1) == b)}


def composite_shares(matrices: dict[tuple[int, int], np.ndarray], members: list[np.ndarray], draws: np.ndarray) -> np.ndarray:
    """{(a, b): (n_a, n_b) reads of held-out composites}, each class's positions among the held-out sequences, (R, N)
    bootstrap draws of those sequences -> (R,) the mean over pairs of each pair's share, each composite weighted by how
    often the draw holds both its followers."""
    counts = np.stack([np.bincount(d, minlength=draws.shape[1]) for d in draws]).astype(np.float64)  # (R, N)
    per_pair = []
    for (a, b), m in matrices.items():
        wa, wb = counts[:, members[a]], counts[:, members[b]]
        with np.errstate(invalid="ignore", divide="ignore"):
            per_pair.append(np.einsum("ri,ij,rj->r", wa, m.astype(np.float64), wb) / (wa.sum(1) * wb.sum(1)))
    return np.nanmean(np.stack(per_pair, 1), 1)


def main() -> None:
    import torch

    from imm_model import paths
    from imm_model.data.bundle import load_any
    from imm_model.evaluation import distribution, intervals
    from imm_model.evaluation.control import PART_SHARE
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, held_out_composites, held_out_part_readings, prepare_model
    from imm_model.evaluation.plausibility import frame_rate
    from imm_model.inference import ReactionModel

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=paths.SAMPLE_DEFAULT)
    ap.add_argument("--fold", default="s04", help="the LOSO fold: the checkpoint's held-out subject")
    ap.add_argument("--seed", type=int, default=0, help="the sampler's seed for every leader")
    ap.add_argument("--gru-seed", type=int, default=7, help="the GRU part judges' seed (the project's part judges: 1)")
    ap.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per judge family here")
    args = ap.parse_args()
    torch.set_num_threads(1)
    start = time.time()
    data = load_any(paths.SAMPLE_DATA)
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    model = ReactionModel.load(args.checkpoint)
    if model.held_out_subject != args.fold:
        ap.error(f"{args.checkpoint} holds out {model.held_out_subject}, not {args.fold}")
    prepare_model(model, data, args.fold, opts)
    shown = args.checkpoint.resolve()
    shown = shown.relative_to(paths.REPO_ROOT) if shown.is_relative_to(paths.REPO_ROOT) else shown
    names, c, n = data.class_names, len(data.class_names), len(judges.leaders)
    y = data.actions[judges.test]
    reals = [data.canonical(int(i))[1] for i in judges.test]
    pairs = list(permutations(range(c), 2))
    followers = {}
    for a, b in pairs:
        labels = np.zeros((n, 2 * c), np.float32)
        labels[:, a], labels[:, c + b] = 1.0, 1.0
        followers[a, b] = model.synthesize_batch_canonical(judges.leaders, labels, [args.seed] * n)
    unmixed = []
    for k in range(c):
        labels = np.zeros((n, 2 * c), np.float32)
        labels[:, k], labels[:, c + k] = 1.0, 1.0
        unmixed.append(model.synthesize_batch_canonical(judges.leaders, labels, [args.seed] * n))
    composites = {(a, b): f for a, b, _, f in held_out_composites(data, judges)}
    members = [np.flatnonzero(y == k) for k in range(c)]
    fps = frame_rate(data.dataset)
    draws = intervals.bootstrap_indices(n)
    print(f"{len(pairs)} pairs x {n} leaders drawn, {time.time() - start:.0f} s", flush=True)
    project_reference = held_out_part_readings(data, judges)

    for family in args.families:
        t0 = time.time()
        view, described = judge_views(family, judges, data, args.fold, args.gru_seed, args.seed)
        real = {part: view[part](reals) for part in PARTS}
        row = {"judge": family, "fold": args.fold, "checkpoint": str(shown), "seed": args.seed, "part_share": PART_SHARE,
               "judges": described,
               "accuracy": {part: distribution.accuracy(real[part], y) for part in PARTS},
               "real_own_class_at_part_share": {part: float((real[part][np.arange(n), y] >= PART_SHARE).mean()) for part in PARTS}}
        for rule in ("share", "argmax"):
            model_reads = np.zeros((n, len(pairs)), bool)
            comp = {}
            for k, (a, b) in enumerate(pairs):
                model_reads[:, k] = reads(view["upper"](followers[a, b]), view["lower"](followers[a, b]), a, b)[rule]
                comp_read = reads(view["upper"](composites[a, b]), view["lower"](composites[a, b]), a, b)[rule]
                comp[a, b] = comp_read.reshape(len(members[a]), len(members[b]))
            per_pair = model_reads.mean(0)
            comp_per_pair = np.array([comp[p].mean() for p in pairs])
            boot_share = model_reads[draws].mean((1, 2))
            boot_under = (model_reads[draws].mean(1) < UNDER).sum(1)
            boot_comp = composite_shares(comp, members, draws)
            key = "" if rule == "share" else "_argmax"
            worst = np.argsort(per_pair, kind="stable")[:5]
            row |= {f"read{key}": float(per_pair.mean()), f"read{key}_ci": intervals.percentile_interval(boot_share),
                    f"pairs_under_0.1{key}": int((per_pair < UNDER).sum()),
                    f"pairs_under_0.1{key}_ci": intervals.percentile_interval(boot_under.astype(np.float64)),
                    f"check_passes_in_resamples{key}": float(((boot_share >= 0.45) & (boot_under <= 3)).mean()),
                    f"worst_pairs{key}": {f"{names[pairs[k][0]]}/{names[pairs[k][1]]}": round(float(per_pair[k]), 4) for k in worst},
                    f"composites{key}": float(comp_per_pair.mean()),
                    f"composites{key}_ci": intervals.percentile_interval(boot_comp),
                    f"ratio_to_composites{key}": float(per_pair.mean() / comp_per_pair.mean()),
                    f"ratio_to_composites{key}_ci": intervals.percentile_interval(boot_share / boot_comp),
                    f"per_pair{key}": {f"{names[a]}/{names[b]}": [round(float(per_pair[k]), 4), round(float(comp_per_pair[k]), 4)]
                                       for k, (a, b) in enumerate(pairs)}}
        row["unmixed"] = {names[k]: {rule: float(r.mean()) for rule, r in reads(view["upper"](f), view["lower"](f), k, k).items()}
                          for k, f in enumerate(unmixed)}
        if family == "conv":  # the composites' share must be the project's own reference figure; and no judge's figure:
            row["composites_project_reference"] = float(np.nanmean([project_reference[a, b] for a, b in pairs]))
            # per class and part, the mean speed of the unmixed reactions to the class's own leaders / its real followers'
            row["part_speed_mps"] = {f"{names[k]}/{part}": [round(part_speed([unmixed[k][i] for i in members[k]], joints, part, fps), 4),
                                                            round(part_speed([reals[i] for i in members[k]], joints, part, fps), 4)]
                                     for k in range(c) for part, joints in ((q, part_joints(data.skeleton, q)) for q in PARTS)}
        row["seconds"] = round(time.time() - t0, 1)
        print(json.dumps(row), flush=True)
        if args.out:
            with open(args.out, "a") as fh:
                fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
