"""Compare the diffusion sampler's label compositions ("sum", "parts" with a routing power) on one LOSO fold: the
+1/+1 mix table by the whole-body and body-part judges, single-label adherence and avoid by the whole-body judge, and
two realism figures of the mixed reactions, one JSON line per composition x sampler seed (docs/experiments/mix-composition.md).

"sum" is the library's sampler (imm_model.families.diffusion.sampler.sample). "parts" and "relative" live in this script
only: `routed_sample` runs the library's DDIM loop (`ddim`) with the sum of the class terms replaced by `compose_parts` (the
routing of the record's Design section). Before measuring, `self_check` asserts on a tiny synthetic batch that the
routed sampler with one positive class, or with p = 0, gives the library's sum rule.

    python docs/experiments/scripts/mix_composition.py --checkpoint sample_data/imm_diffusion.safetensors --fold s04 \\
        --variants sum parts:2 parts:8 relative:4 --seeds 0 --out docs/experiments/data/mix-composition.jsonl
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path

import numpy as np


def variant(spec: str) -> tuple[str, float]:
    """"sum", "parts:P" or "relative:P" -> (composition, routing power). "relative" routes by each class's own profile
    over the body: its per-part magnitudes divided by its largest before the classes compete."""
    name, _, power = spec.partition(":")
    if name == "sum" and not power:
        return "sum", 0.0
    if name in ("parts", "relative"):
        try:
            p = float(power or 2.0)
        except ValueError:
            p = -1.0
        if 0 <= p <= 64:
            return name, p
    raise SystemExit(f"mix_composition: error: unknown variant {spec!r} (sum, parts:P, relative:P with 0 <= P <= 64)")


# ---- "parts" routing: the classes at a positive value share the body ------------------------------------------
@dataclass(frozen=True)
class BodyRouting:
    """What "parts" composition needs from the model: the joint groups that share out the body, the joints whose mean
    is the body centre, and the followers' per-coordinate std (D,) to turn normalized differences into metres."""

    groups: tuple[tuple[int, ...], ...]
    centre: tuple[int, ...]
    scale: np.ndarray

    @classmethod
    def of(cls, skeleton, follower_std: np.ndarray) -> BodyRouting:
        """The skeleton's body parts (every joint in none of them is a group of its own) and centre (the root's
        neighbours, as the body-part judges read it)."""
        groups = [tuple(int(j) for j in js) for js in skeleton.body_parts.values()]
        seen = {j for g in groups for j in g}
        groups += [(j,) for j in range(skeleton.num_joints) if j not in seen]
        scale = np.asarray(follower_std, np.float64).reshape(-1)
        if scale.shape != (3 * skeleton.num_joints,) or not np.all(scale > 0):
            raise ValueError(f"body routing needs {3 * skeleton.num_joints} positive follower stds")
        return cls(tuple(groups), tuple(int(j) for j in skeleton.root_neighbours), scale)


def part_responsibilities(rms: np.ndarray, weights: np.ndarray, power: float, relative: bool = False) -> np.ndarray:
    """rms (K, R, P) each class's difference per row and part (metres), weights (K, R) its positive value ->
    r (K, R, P), summing to 1 over the classes: w_c m^p / sum_c' w_c' m^p (by the value alone where no class moves the
    part). relative: each class's magnitudes are first divided by its own largest part."""
    if relative:
        rms = rms / np.maximum(rms.max(-1, keepdims=True), 1e-30)  # each class's own profile
    rel = rms / np.maximum(rms.max(0, keepdims=True), 1e-30)  # scale-free before the power
    score = weights[..., None] * rel ** power
    norm = score.sum(0, keepdims=True)
    fallback = np.broadcast_to((weights / weights.sum(0))[..., None], score.shape)
    return np.where(norm > 0, score / np.where(norm > 0, norm, 1.0), fallback)


def compose_parts(base: np.ndarray, class_terms: np.ndarray, weights: np.ndarray, routing: BodyRouting, power: float,
                  relative: bool = False, mask: np.ndarray | None = None) -> np.ndarray:
    """One step's routed label composition: base x0(A, -) (B, T, D), class terms x0(A, e_c) (K, B, T, D), weights
    (K, B) the signed label values times s -> x0 (B, T, D). Rows with at most one positive class, and every negative
    value, keep the sum rule. mask (B, T) bool: the frames the part magnitudes read (default all)."""
    d = class_terms - base
    w = weights.astype(np.float32)[..., None, None]
    positive = np.maximum(weights, 0).astype(np.float64)  # (K, B)
    out = base + (w * d).sum(0)  # the sum rule: kept by rows with one positive class or none
    rows = np.flatnonzero((positive > 0).sum(0) > 1)
    if len(rows) == 0:
        return out
    out[rows] = base[rows] + (np.minimum(w, 0)[:, rows] * d[:, rows]).sum(0)  # negations keep the sum rule
    k, _, t, dim = d.shape
    frames = np.ones((len(rows), t), bool) if mask is None else np.asarray(mask, bool)[rows]
    m = frames[None, :, :, None, None].astype(np.float64)  # (1, R, T, 1, 1)
    metres = (d[:, rows].astype(np.float64) * routing.scale).reshape(k, len(rows), t, dim // 3, 3)
    centre = metres[:, :, :, list(routing.centre)].mean(3, keepdims=True)  # (K, R, T, 1, 3): placement
    rel_centre = metres - centre
    wp, total = positive[:, rows], positive[:, rows].sum(0)  # (K, R), (R,)
    count = np.maximum(m.sum((2, 3, 4)), 1.0)  # valid frames per row (1, R)

    parts = [centre] + [rel_centre[:, :, :, list(g)] for g in routing.groups]  # placement, then each group
    rms = np.stack([np.sqrt((x ** 2 * m).sum((2, 3, 4)) / (count * x.shape[3])) for x in parts], -1)  # (K, R, P)
    r = part_responsibilities(rms, wp, power, relative)
    mixed = np.zeros(metres.shape[1:])  # (R, T, J, 3)
    mixed += ((total * r[..., 0])[..., None, None, None] * centre).sum(0)
    for p, group in enumerate(routing.groups, start=1):
        g = list(group)
        mixed[:, :, g] += ((total * r[..., p])[..., None, None, None] * rel_centre[:, :, :, g]).sum(0)
    out[rows] += (mixed.reshape(len(rows), t, dim) / routing.scale).astype(np.float32)
    return out


def routed_sample(denoise, leaders: np.ndarray, mask: np.ndarray, labels: np.ndarray, noise: np.ndarray, guidance,
                  diffusion_steps: int, routing: BodyRouting, power: float, relative: bool = False, seeds=None) -> np.ndarray:
    """imm_model.families.diffusion.sampler.sample (same arguments and terms) with the classes composed by
    compose_parts instead of the sum rule, on the library's DDIM loop (`ddim`)."""
    from imm_model.families.diffusion.sampler import ddim

    b, t, d = noise.shape
    c = labels.shape[1]
    classes = np.flatnonzero(np.abs(labels).sum(0) > 0).tolist()  # classes some row asks about
    n_terms = 1 + len(classes) + (guidance.leader_scale != 1.0)
    one_hot = np.zeros((n_terms, b, c), np.float32)
    label_on = np.zeros((n_terms, b), bool)
    for k, cls in enumerate(classes, start=1):
        one_hot[k, :, cls] = 1.0
        label_on[k] = True
    leader_on = np.ones((n_terms, b), bool)
    if guidance.leader_scale != 1.0:
        leader_on[-1] = False
    one_hot, label_on, leader_on = one_hot.reshape(-1, c), label_on.reshape(-1), leader_on.reshape(-1)
    weights = (labels[:, classes].T * guidance.label_scale).astype(np.float32)  # (K, B)
    m = mask[..., None].astype(np.float32)

    def predict(x: np.ndarray, step: int) -> np.ndarray:
        terms = denoise(np.tile(x, (n_terms, 1, 1)), step, leader_on, one_hot, label_on).reshape(n_terms, b, t, d)
        base = terms[0]
        x0 = base
        if classes:
            x0 = compose_parts(base, terms[1:1 + len(classes)], weights, routing, power, relative, mask)
        if guidance.leader_scale != 1.0:
            x0 = terms[-1] + guidance.leader_scale * (x0 - terms[-1])
        return np.clip(x0, -guidance.clip, guidance.clip) * m

    return ddim(predict, noise, mask, guidance, diffusion_steps, seeds)


def routed_sampler(model, power: float, relative: bool = False):
    """A sampler for `model.sampler` (the diffusion model's sampling loop): routed_sample in place of the library's
    sum rule."""
    routing = BodyRouting.of(model.skeleton, model.weights["follower_std"])

    def sampler(denoise, x, mask, labels, noise, guidance, steps, seeds=None, **network):
        return routed_sample(denoise, x, mask, labels, noise, guidance, steps, routing, power, relative, seeds)

    return sampler


def self_check() -> None:
    """On a tiny synthetic batch and a random linear stand-in for the network: the routed sampler gives the library's
    sum rule with one positive class per row and with p = 0, and differs from it with two classes and p = 8."""
    from imm_model.families.diffusion.sampler import Guidance, sample
    from imm_model.skeleton import KINECT15

    rng = np.random.default_rng(0)
    b, t, d, c = 3, 9, 45, 4
    lift = rng.standard_normal((d + 2 * c + 1, d)).astype(np.float32) * 0.3

    def denoise(x_t, step, leader_on, label, label_on):
        feats = np.concatenate([np.repeat(label[:, None], t, 1), np.repeat((label * label_on[:, None])[:, None], t, 1),
                                np.repeat(leader_on[:, None, None], t, 1).astype(np.float32)], -1)
        return np.tanh(np.concatenate([x_t, feats], -1) @ lift)

    leaders, noise = rng.standard_normal((b, t, d)).astype(np.float32), rng.standard_normal((b, t, d)).astype(np.float32)
    mask = np.ones((b, t), bool)
    mask[0, -3:] = False
    routing = BodyRouting.of(KINECT15, 0.2 + rng.random(d))
    for g in (Guidance(label_scale=2.5, sample_steps=5), Guidance(label_scale=2.5, leader_scale=1.5, sample_steps=5)):
        one = np.array([[1, 0, 0, -1], [0, 0.5, 0, 0], [0, 0, 0, 0]], np.float32)
        two = np.array([[1, 1, 0, 0], [0, 0.5, 1, -0.5], [1, 0, 0, 1]], np.float32)
        for labels, power, same in ((one, 8.0, True), (two, 0.0, True), (two, 8.0, False)):
            summed = sample(denoise, leaders, mask, labels, noise, g, 50)
            routed = routed_sample(denoise, leaders, mask, labels, noise, g, 50, routing, power)
            if np.allclose(routed, summed, atol=1e-5) != same:
                raise SystemExit(f"mix_composition: error: self-check failed (power {power}, same {same})")


def bone_error_cm(followers: list[np.ndarray], skeleton, lengths: np.ndarray) -> float:
    """Mean |bone length - the training followers' length| over bones and frames, centimetres."""
    return float(100 * np.mean(np.concatenate([np.abs(skeleton.bone_lengths(f) - lengths) for f in followers])))


def jitter_m(followers: list[np.ndarray], skeleton) -> float:
    """Mean norm of the joints' second difference relative to the body centre, metres a frame."""
    vals = []
    for f in followers:
        rel = f - f[:, skeleton.root_neighbours].mean(1, keepdims=True)
        vals.append(np.linalg.norm(rel[2:] - 2 * rel[1:-1] + rel[:-2], axis=-1).mean())
    return float(np.mean(vals))


def main() -> None:
    import torch
    from diffusion_fold import record  # the script beside this one

    from imm_model import cache
    from imm_model.cleanup import clean_follower
    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation import control
    from imm_model.evaluation.loso import EvalOptions, prepare_model
    from imm_model.families.diffusion.sampler import sample
    from imm_model.inference import ReactionModel
    from imm_model.model import classifier as classifiers
    from imm_model.model import classifier_config as cc
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, required=True)
    ap.add_argument("--fold", required=True)
    ap.add_argument("--variants", nargs="+", default=["sum", "parts:2"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per variant x seed here")
    args = ap.parse_args()
    variants = [(v, *variant(v)) for v in args.variants]
    self_check()
    torch.set_num_threads(1)
    data = InteractionDataset.load(SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    prepare_model(model, data, args.fold, EvalOptions(baselines=(), progress=False))
    test = loso_fold(data.subject_pairs, args.fold).test
    leaders = [data.canonical(int(i))[0] for i in test]
    y, names, c = data.actions[test], data.class_names, len(data.class_names)
    judges = {part: cache.fold_classifier(cfg, data, args.fold, False)
              for part, cfg in (("follower", cc.FOLLOWER_JUDGE), ("upper", cc.UPPER_JUDGE), ("lower", cc.LOWER_JUDGE))}
    real_acc = {part: float((classifiers.classify(clf, classifiers.motion_inputs(
        leaders, [data.canonical(int(i))[1] for i in test], part))[0].argmax(-1) == y).mean()) for part, clf in judges.items()}
    lengths = np.asarray(model.bone_lengths)

    for seed in args.seeds:
        for spec, composition, power in variants:
            start = time.time()
            drawn: dict[bytes, tuple[list[np.ndarray], list[np.ndarray]]] = {}

            def followers(labels: np.ndarray, seed=seed, drawn=drawn, composition=composition,
                          power=power) -> tuple[list[np.ndarray], list[np.ndarray]]:
                key = np.ascontiguousarray(labels, np.float32).tobytes()
                if key not in drawn:
                    model.sampler = sample if composition == "sum" else routed_sampler(model, power, composition == "relative")
                    model.raw = True  # the network's own followers, and the same through the clean-up
                    raw = model.synthesize_batch_canonical(leaders, np.asarray(labels, np.float32), [seed] * len(leaders))
                    drawn[key] = raw, [clean_follower(f.astype(np.float64), model.skeleton, model.bone_lengths).astype(np.float32)
                                       for f in raw]
                return drawn[key]

            def judge(part: str, labels: np.ndarray) -> np.ndarray:
                return classifiers.classify(judges[part], classifiers.motion_inputs(leaders, followers(labels)[1], part))[0]

            mix = control.part_mix_table(lambda lb: judge("follower", lb), lambda lb: judge("upper", lb),
                                         lambda lb: judge("lower", lb), len(y), names)
            mix_labels = [np.zeros((len(y), c), np.float32) for _ in mix]
            for labels, pair in zip(mix_labels, combinations(range(c), 2), strict=True):
                labels[:, list(pair)] = 1.0
            raw_mix = [f for lb in mix_labels for f in followers(lb)[0]]
            clean_mix = [f for lb in mix_labels for f in followers(lb)[1]]
            matrix, _ = control.adherence_matrix(lambda lb: judge("follower", lb), y, c)
            avoid = control.avoid_effect(lambda lb: judge("follower", lb), y, c)
            singles = float(sum(np.abs(f.astype(np.float64)).sum() for k in range(c)
                                for f in followers(np.eye(c, dtype=np.float32)[[k] * len(y)])[1]))
            row = {"checkpoint": str(args.checkpoint), "fold": args.fold, "seed": seed, "variant": spec,
                   "guidance": model.guidance.to_dict() | ({"composition": "sum"} if composition == "sum" else
                                                           {"composition": "parts", "routing_power": power}),
                   "judge_real_accuracy": real_acc,
                   "mix_whole": float(np.mean([r["whole"] for r in mix])), "mix_parts": float(np.mean([r["parts"] for r in mix])),
                   "mix_mixed": float(np.mean([r["mixed"] for r in mix])),
                   "mix_worst_pair": float(min(r["mixed"] for r in mix)),
                   "mix_worst": min(mix, key=lambda r: r["mixed"])["pair"],
                   "pairs": {"+".join(r["pair"]): round(r["mixed"], 3) for r in mix},
                   "off_label": control.off_diagonal_mean(matrix), "true_label": float(np.nanmean(np.diag(matrix))),
                   "avoid_change": avoid["change"], "avoid_share_lowered": avoid["share_lowered"],
                   "single_label_checksum": singles,
                   "mix_raw_bone_error_cm": bone_error_cm(raw_mix, model.skeleton, lengths),
                   "mix_jitter_m": jitter_m(clean_mix, model.skeleton),
                   "seconds": round(time.time() - start, 1)}
            record(row, args.out)


if __name__ == "__main__":
    main()
