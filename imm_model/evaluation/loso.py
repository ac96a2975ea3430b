"""One LOSO fold evaluated in full: the model and every baseline, on every metric of docs/evaluation-protocol.md.

Per fold, each test sequence is synthesized with the one-hot label of its true class (AFD, FID,
recognition, plausibility); label control asks every test leader for every class, every pair and
"avoid". Classifiers and the label-free baseline come from the cache (trained on the fold's training
subjects only). Aggregation over folds and seeds is evaluation/report.py.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import permutations
from pathlib import Path

import numpy as np

from imm_model import cache
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.evaluation import control, distribution, intervals
from imm_model.evaluation.baselines import (
    HEURISTIC_BASELINES,
    baseline_predictions,
    fold_baseline_model,
    sequence_afds,
)
from imm_model.evaluation.metrics import afd_parts, per_class_mean
from imm_model.evaluation.plausibility import acceleration_mps2, frame_rate, interpenetration, plausibility
from imm_model.model import classifier as classifiers
from imm_model.model import classifier_config as classifier_configs

BASELINES = (*HEURISTIC_BASELINES, "men")
DEV_FOLDS = ("s01", "s03", "s04")  # already used to choose recipes (docs/evaluation-protocol.md)


def fold_group(subject: str) -> str:
    return "dev" if subject in DEV_FOLDS else "test"


@dataclass(frozen=True)
class EvalOptions:
    baselines: tuple[str, ...] = BASELINES
    # {subject} -> a trained label-free checkpoint; None: train `men` on the fold (cached)
    men_checkpoint: Callable[[str], Path] | None = None
    men_config: str = "men"  # the recipe (a name or a JSON file of overrides) `men` is trained with when none is given
    interaction: classifier_configs.ClassifierConfig = classifier_configs.INTERACTION
    follower: classifier_configs.ClassifierConfig = classifier_configs.FOLLOWER
    judge: classifier_configs.ClassifierConfig = classifier_configs.FOLLOWER_JUDGE
    upper: classifier_configs.ClassifierConfig = classifier_configs.UPPER_JUDGE
    lower: classifier_configs.ClassifierConfig = classifier_configs.LOWER_JUDGE
    progress: bool = True
    raw: bool = False  # score the network's own followers, without the inference clean-up (cleanup.py)
    average_placement: bool = False  # place the models' followers as inference.ReactionModel.average_placement does

    def __post_init__(self) -> None:
        unknown = [b for b in self.baselines if b not in BASELINES]
        if unknown:
            raise ValueError(f"unknown baseline {unknown[0]!r}; known: {', '.join(BASELINES)}")


def model_predictions(model, data: InteractionDataset, test_idx: np.ndarray, labels: np.ndarray | None = None) -> dict[int, np.ndarray]:
    """{test index: canonical follower} from a ReactionModel, by default conditioned on the true class."""
    leaders = [data.canonical(int(i))[0] for i in test_idx]
    if labels is None:
        labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[test_idx]]
    preds = model.synthesize_batch_canonical(leaders, labels)
    return {int(i): p for i, p in zip(test_idx, preds, strict=True)}


class FoldJudges:
    """The fold's three real-data classifiers, and their accuracy on the fold's real test sequences."""

    def __init__(self, data: InteractionDataset, subject: str, opts: EvalOptions):
        fold = loso_fold(data.subject_pairs, subject)
        self.data, self.test, self.train = data, fold.test, fold.train
        self.interaction = cache.fold_classifier(opts.interaction, data, subject, opts.progress)
        self.follower = cache.fold_classifier(opts.follower, data, subject, opts.progress)
        self.judge = cache.fold_classifier(opts.judge, data, subject, opts.progress)
        self.parts = {part: cache.fold_classifier(getattr(opts, part), data, subject, opts.progress) for part in ("upper", "lower")}
        self.leaders = [data.canonical(int(i))[0] for i in self.test]
        reals = [data.canonical(int(i))[1] for i in self.test]
        self.real_probs, self.real_features = self.interaction_view(reals)
        y = data.actions[self.test]
        self.real_accuracy = {
            "interaction": distribution.accuracy(self.real_probs, y),
            "follower": distribution.accuracy(self.follower_view(self.follower, reals), y),
            "follower_judge": distribution.accuracy(self.follower_view(self.judge, reals), y),
            **{f"{part}_judge": distribution.accuracy(self.part_view(part, reals), y) for part in self.parts},
        }

    def interaction_view(self, followers: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        return classifiers.classify(self.interaction, classifiers.motion_inputs(self.leaders, followers, "interaction"))

    def follower_view(self, clf, followers: list[np.ndarray]) -> np.ndarray:
        return classifiers.classify(clf, classifiers.motion_inputs(self.leaders, followers, "follower"))[0]

    def part_view(self, part: str, followers: list[np.ndarray]) -> np.ndarray:
        return classifiers.classify(self.parts[part], classifiers.motion_inputs(self.leaders, followers, part))[0]


def _per_class(values: np.ndarray, test: np.ndarray, data: InteractionDataset) -> dict[str, float]:
    return per_class_mean({int(i): float(v) for i, v in zip(test, values, strict=True)}, data.actions, data.class_names)


def method_scores(data: InteractionDataset, judges: FoldJudges, predictions: dict[int, np.ndarray]) -> dict:
    """AFD, AFD squared, FID, KID, precision and recall, recognition accuracy, diversity and plausibility of one method's
    predictions; `intervals` holds the 95 % bootstrap interval over the test sequences of each headline figure, and
    every class its AFDs' (`afd_ci`, `afd_squared_ci`)."""
    test, y = judges.test, data.actions[judges.test]
    missing = [int(i) for i in test if int(i) not in predictions]
    if missing:
        raise ValueError(f"no prediction for {len(missing)} test sequences (e.g. {data.sequence_ids[missing[0]]})")
    followers = [predictions[int(i)] for i in test]
    by_sequence = {key: sequence_afds(data, dict(zip(map(int, test), followers, strict=True)), squared=squared)
                   for key, squared in (("afd", False), ("afd_squared", True))}
    seq = {key: np.array([v[int(i)] for i in test]) for key, v in by_sequence.items()}  # in test's order
    probs, feats = judges.interaction_view(followers)
    correct = probs.argmax(-1) == y
    per_class: dict[str, dict] = {c: {} for c in data.class_names if (y == data.class_names.index(c)).any()}
    for key, values in (("afd", _per_class(seq["afd"], test, data)), ("afd_squared", _per_class(seq["afd_squared"], test, data)),
                        ("accuracy", _per_class(correct, test, data))):
        for c, v in values.items():
            per_class[c][key] = v
    reals = [data.canonical(int(i))[1] for i in test]
    contact = np.array([interpenetration(a, b, data.skeleton) for a, b in zip(judges.leaders, followers, strict=True)])
    real_contact = np.array([interpenetration(a, b, data.skeleton) for a, b in zip(judges.leaders, reals, strict=True)])
    for c in per_class:
        members = y == data.class_names.index(c)
        per_class[c]["fid"] = distribution.fid(judges.real_features[members], feats[members])
        per_class[c]["afd_ci"] = intervals.mean_interval(seq["afd"][members])
        per_class[c]["afd_squared_ci"] = intervals.mean_interval(seq["afd_squared"][members])
        # contact counts against a method only beyond what real pairs of the class show (hugs touch, kicks rarely)
        per_class[c]["contact"], per_class[c]["real_contact"] = float(contact[members].mean()), float(real_contact[members].mean())
    parts = [afd_parts(f, r, data.skeleton.root) for f, r in zip(followers, reals, strict=True)]
    precision, recall = distribution.precision_recall(judges.real_features, feats)
    fps = frame_rate(data.dataset)
    jitter = [np.array([acceleration_mps2(m, fps) for m in ms]) for ms in (followers, reals)]
    return {"classes": per_class, "fid": distribution.fid(judges.real_features, feats),
            "kid": distribution.kid(judges.real_features, feats), "precision": precision, "recall": recall,
            "accuracy": distribution.accuracy(probs, y), "diversity": distribution.diversity(feats),
            "afd_parts": {k: float(np.mean([p[k] for p in parts])) for k in parts[0]},
            "plausibility": plausibility(judges.leaders, followers, reals, data.skeleton, fps),
            "intervals": distribution.distribution_intervals(judges.real_features, feats) | {
                "afd": intervals.group_mean_interval(seq["afd"], y), "accuracy": intervals.mean_interval(correct),
                "jitter_mps2": intervals.mean_interval(jitter[0]), "real_jitter_mps2": intervals.mean_interval(jitter[1]),
                "jitter_ratio": intervals.ratio_interval(*jitter)}}


def label_control(model, data: InteractionDataset, judges: FoldJudges) -> dict:
    """Adherence (both follower-only classifiers), mix and avoid for the model on the fold's test leaders."""
    y, c = data.actions[judges.test], len(data.class_names)
    synthesized: dict[bytes, list[np.ndarray]] = {}  # both judges read the same followers: synthesize each label set once

    def followers(labels: np.ndarray) -> list[np.ndarray]:
        key = np.ascontiguousarray(labels, np.float32).tobytes()
        if key not in synthesized:
            synthesized[key] = model.synthesize_batch_canonical(judges.leaders, labels)
        return synthesized[key]

    out: dict = {}
    for name, clf in (("", judges.follower), ("_judge", judges.judge)):
        def judge(labels: np.ndarray, clf=clf) -> np.ndarray:
            return judges.follower_view(clf, followers(labels))

        matrix, per_target = control.adherence_matrix(judge, y, c)
        out[f"adherence_matrix{name}"] = matrix.tolist()
        out[f"adherence{name}"] = dict(zip(data.class_names, per_target.tolist(), strict=True))
        out[f"adherence_off_diagonal{name}"] = control.off_diagonal_mean(matrix)
        out[f"mix{name}"] = control.mix_table(judge, len(y), data.class_names)
        out[f"avoid{name}"] = control.avoid_effect(judge, y, c)
    def whole(labels: np.ndarray) -> np.ndarray:
        return judges.follower_view(judges.judge, followers(labels))

    def upper(labels: np.ndarray) -> np.ndarray:
        return judges.part_view("upper", followers(labels))

    def lower(labels: np.ndarray) -> np.ndarray:
        return judges.part_view("lower", followers(labels))

    out["mix_parts"] = control.part_mix_table(whole, upper, lower, len(y), data.class_names, held_out_mix_readings(data, judges))
    reals = [data.canonical(int(i))[1] for i in judges.test]
    out["part_realism"] = control.part_realism(upper, lower, y, judges.part_view("upper", reals), judges.part_view("lower", reals),
                                               data.class_names)
    if model.part_labels:
        real = real_part_readings(data, judges)
        out["part_pairs"] = control.part_pair_table(upper, lower, lambda a, b: real[a, b], len(y), data.class_names,
                                                    held_out_part_readings(data, judges))
        out["part_avoid"] = control.part_avoid_effect({"upper": upper, "lower": lower}, y, c)
    return out


def real_part_readings(data: InteractionDataset, judges: FoldJudges) -> np.ndarray:
    """(C, C, N) bool: for each test leader, whether the real part composite of class a's trunk and arms and class b's
    legs and placement reads so to the body-part judges (each at PART_SHARE or more). A class's part comes from the
    real follower (of the fold's training pairs) whose leader is nearest the test leader, resampled to its length."""
    from imm_model.families.retrieval.model import nearest_follower
    from imm_model.model.body_parts import compose_parts, part_indices

    c = len(data.class_names)
    pools = [[data.canonical(int(i)) for i in judges.train if data.actions[i] == k] for k in range(c)]
    nearest = [[nearest_follower(leader, pools[k]) for k in range(c)] for leader in judges.leaders]  # (N, C) followers
    upper_joints, _, centre = part_indices(data.skeleton)
    reads = np.zeros((c, c, len(judges.leaders)), bool)
    for a, b in permutations(range(c), 2):
        composites = [compose_parts(row[a][None], row[b][None], upper_joints, centre)[0] for row in nearest]
        pu, pl = judges.part_view("upper", composites), judges.part_view("lower", composites)
        reads[a, b] = (pu[:, a] >= control.PART_SHARE) & (pl[:, b] >= control.PART_SHARE)
    return reads


def held_out_composites(data: InteractionDataset, judges: FoldJudges):
    """For each ordered pair of classes (a, b): (a, b, leaders, composites), every test follower of class a's trunk
    and arms (resampled to the length of the other) on every test follower of class b's legs and placement, beside the
    leader the second answered: motion no judge was trained on."""
    from imm_model.data.sequence import resample
    from imm_model.model.body_parts import compose_parts, part_indices

    c = len(data.class_names)
    pairs = [[data.canonical(int(i)) for i in judges.test if data.actions[i] == k] for k in range(c)]
    upper_joints, _, centre = part_indices(data.skeleton)
    for a, b in permutations(range(c), 2):
        combos = [(lb, compose_parts(resample(fa, len(fb))[None], fb[None], upper_joints, centre)[0])
                  for _, fa in pairs[a] for lb, fb in pairs[b]]
        yield a, b, [lb for lb, _ in combos], [f for _, f in combos]


def held_out_part_readings(data: InteractionDataset, judges: FoldJudges) -> np.ndarray:
    """(C, C): for each ordered pair of classes, the share of part composites of held-out followers
    (`held_out_composites`) that read as asked to the body-part judges (each at PART_SHARE or more): the reference a
    model's part mixes are compared with."""
    c = len(data.class_names)
    shares = np.full((c, c), np.nan)
    for a, b, _, composites in held_out_composites(data, judges):
        if composites:
            pu, pl = judges.part_view("upper", composites), judges.part_view("lower", composites)
            shares[a, b] = float(((pu[:, a] >= control.PART_SHARE) & (pl[:, b] >= control.PART_SHARE)).mean())
    return shares


def held_out_mix_readings(data: InteractionDataset, judges: FoldJudges) -> np.ndarray:
    """(C, C): for each ordered pair of classes, the share of part composites of held-out followers
    (`held_out_composites`) that the whole-body judge reads as both classes (each at MIX_SHARE or more), beside the
    leader the legs answered: the reference a model's whole-body mixes are compared with."""
    from imm_model.reads_as import MIX_SHARE

    c = len(data.class_names)
    shares = np.full((c, c), np.nan)
    for a, b, leaders, composites in held_out_composites(data, judges):
        if composites:
            p = classifiers.classify(judges.judge, classifiers.motion_inputs(leaders, composites, "follower"))[0]
            shares[a, b] = float(((p[:, a] >= MIX_SHARE) & (p[:, b] >= MIX_SHARE)).mean())
    return shares


VARIATIONS = 5  # reactions drawn per test leader for multimodality and best-of-N AFD


def variations(model, data: InteractionDataset, judges: FoldJudges, seed0: dict[int, np.ndarray], n: int = VARIATIONS) -> dict:
    """A stochastic model's spread, each test leader with its true label and sampler seeds 0..n-1 (seed 0 is the
    single sample every other number scores):
    - multimodality: mean interaction-classifier feature distance between two reactions to the same leader and label
      (ACTOR's and ReGenNet's definition), beside real_class_diversity, the same distance between the real followers
      of different test sequences of the same class (what a reaction may vary by); multimodality_m the same pairs'
      mean per-frame pose distance in metres;
    - afd_best_of_n: per sequence the lowest AFD of the n reactions, averaged (normalized units, as `afd`).
    `seed0`: the model's predictions already drawn with seed 0 ({test index: follower})."""
    test = judges.test
    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[test]]
    draws = [[seed0[int(i)] for i in test]]
    draws += [model.synthesize_batch_canonical(judges.leaders, labels, [k] * len(test)) for k in range(1, n)]
    features = np.stack([judges.interaction_view(d)[1] for d in draws], 1)  # (N, n, F)
    pairs = [(a, b) for a in range(n) for b in range(a + 1, n)]
    multimodality = np.mean([np.linalg.norm(features[:, a] - features[:, b], axis=-1).mean() for a, b in pairs])
    metres = np.mean([[np.linalg.norm(d1 - d2, axis=-1).mean() for d1, d2 in zip(draws[a], draws[b], strict=True)]
                      for a, b in pairs])
    real, y = judges.real_features, data.actions[test]
    same = (y[:, None] == y[None]) & ~np.eye(len(y), dtype=bool)
    distances = np.linalg.norm(real[:, None] - real[None], axis=-1)
    afds = np.array([[v for _, v in sorted(sequence_afds(data, dict(zip(map(int, test), d, strict=True))).items())]
                     for d in draws])  # (n, N)
    return {"samples": n, "multimodality": float(multimodality), "real_class_diversity": float(distances[same].mean()),
            "real_same_leader_diversity": real_same_leader_diversity(data, judges),
            "multimodality_m": float(metres), "afd_single": float(afds[0].mean()), "afd_best_of_n": float(afds.min(0).mean())}


def real_same_leader_diversity(data: InteractionDataset, judges: FoldJudges) -> float:
    """How far apart real reactions of one class are when they answer the same leader: each test leader paired with
    the other test followers of its class (resampled to its length), the mean interaction-feature distance between
    two such pairs, averaged over the leaders. multimodality's reference for a fixed leader: real_class_diversity
    also counts the differences between the leaders, which no reaction to one leader can show."""
    from imm_model.data.sequence import resample

    test, y = judges.test, data.actions[judges.test]
    reals = [data.canonical(int(i))[1] for i in test]
    per_leader = []
    for k, leader in enumerate(judges.leaders):
        others = [resample(reals[j], len(leader)) for j in np.flatnonzero(y == y[k]) if j != k]
        if len(others) < 2:
            continue
        feats = classifiers.classify(judges.interaction, classifiers.motion_inputs([leader] * len(others), others, "interaction"))[1]
        d = np.linalg.norm(feats[:, None] - feats[None], axis=-1)
        per_leader.append(d[np.triu_indices(len(others), 1)].mean())
    return float(np.mean(per_leader)) if per_leader else float("nan")


def prepare_model(model, data: InteractionDataset, subject: str, opts: EvalOptions) -> None:
    """Clean-up on (or off with `raw`) and placement averaging as asked; a checkpoint from before the clean-up stored no
    bone lengths gets those its training would have stored (the fold's training followers'), so that every model is
    cleaned up alike."""
    from imm_model.cleanup import follower_bone_lengths

    model.raw, model.average_placement = opts.raw, opts.average_placement
    if model.bone_lengths is None:
        train = loso_fold(data.subject_pairs, subject).train
        model.bone_lengths = np.asarray(follower_bone_lengths([data.canonical(int(i))[1] for i in train], data.skeleton))


def evaluate_fold(model, data: InteractionDataset, subject: str, opts: EvalOptions | None = None,
                  latents: dict | None = None) -> dict:
    """Everything about `model` on LOSO fold `subject`: see docs/evaluation-protocol.md for each number. With `latents`,
    `latents` (a dict given) receives every sequence's embedding under the model, as "model" (and the label-free
    baseline's, as "men") for the t-SNE figure."""
    from imm_model.inference import ReactionModel, check_compatible

    opts = opts or EvalOptions()
    check_compatible(model, data, str(model.path))
    prepare_model(model, data, subject, opts)
    judges = FoldJudges(data, subject, opts)
    result = {"subject": subject, "group": fold_group(subject), "checkpoint": str(model.path),
              "classifier": {"real_accuracy": judges.real_accuracy},
              "real_diversity": distribution.diversity(judges.real_features),
              "baselines": {}}
    predictions = model_predictions(model, data, judges.test)
    result["model"] = method_scores(data, judges, predictions)
    result |= label_control(model, data, judges)
    if model.settings.seed:  # a model that draws variations: their spread and best-of-N AFD
        result["variations"] = variations(model, data, judges, predictions)
    all_idx = np.arange(len(data))
    if latents is not None:
        latents["model"] = _latents(model, data, all_idx)
    for name in opts.baselines:
        if name == "men":
            path = (opts.men_checkpoint(subject) if opts.men_checkpoint
                    else fold_baseline_model(opts.men_config, data, subject, opts.progress))
            men = ReactionModel.load(path)
            check_compatible(men, data, str(men.path))
            prepare_model(men, data, subject, opts)
            preds = model_predictions(men, data, judges.test)
            if latents is not None:
                latents["men"] = _latents(men, data, all_idx)
        else:
            preds = baseline_predictions(name, data, loso_fold(data.subject_pairs, subject))
        result["baselines"][name] = method_scores(data, judges, preds)
    return result


def _latents(model, data: InteractionDataset, idx: np.ndarray) -> np.ndarray:
    """Per-sequence encoder embeddings with the true label (the paper's latent-space figures)."""
    leaders = [data.canonical(int(i))[0] for i in idx]
    return model.latent_canonical_batch(leaders, np.eye(len(data.class_names), dtype=np.float32)[data.actions[idx]])
