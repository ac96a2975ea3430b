"""Fold results (evaluation/loso.py) -> the summary `imm evaluate` prints and writes as JSON and Markdown.

Every number is a mean over the (fold, seed) results it covers, with its standard deviation beside it
(`*_std`, population std over those results) and, for the figures the tables show, its 95 % interval (`*_ci`, and
`ci` in the overall entries; evaluation/intervals.py): the t-interval over the results when there are two or more,
else the one result's bootstrap over its test sequences (none where the fold result has none). Groups: all folds,
the dev folds (s01, s03, s04: already used to choose recipes) and the test folds (s02, s05, s06, s07). Per class, the strongest
baseline is the one with the lowest mean AFD (for FID: the lowest mean FID), and the model's ratio to it is reported.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from imm_model.evaluation import intervals
from imm_model.reads_as import MIX_SHARE

PER_CLASS_METRICS = ("afd", "afd_squared", "fid", "accuracy", "contact", "real_contact")
CONTACT_TOLERANCE = 1.25  # a class's contact is beyond the real pairs' when over this many times their share of frames


def _stat(values: list[float]) -> tuple[float, float]:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=np.float64)
    return (float(v.mean()), float(v.std())) if len(v) else (float("nan"), float("nan"))


def _with_std(out: dict, key: str, values: list[float]) -> None:
    out[key], out[f"{key}_std"] = _stat(values)


def _ci(values: list[float], singles: list) -> list[float]:
    """The 95 % interval of a figure over results: t over two or more, else the one result's own bootstrap."""
    return list(intervals.pooled(values, singles[0] if len(singles) == 1 else None)[1])


def _method_afd(scores: dict) -> float:
    """A method's AFD on one result: the mean over classes of the per-class means (as FoldFigures' `afd`)."""
    return float(np.mean([c["afd"] for c in scores["classes"].values()]))


def _method_classes(results: list[dict], get, class_names) -> dict[str, dict]:
    """Per class mean/std over results of each per-class metric of one method (`get(result)` -> scores)."""
    classes = {}
    for c in class_names:
        entry: dict = {}
        for metric in PER_CLASS_METRICS:
            # results saved before a metric was measured have none of it
            scored = [get(r)["classes"][c] for r in results if metric in get(r)["classes"].get(c, {})]
            _with_std(entry, metric, [e[metric] for e in scored])
            entry[f"{metric}_ci"] = _ci([e[metric] for e in scored], [e.get(f"{metric}_ci") for e in scored])
        classes[c] = entry
    return classes


OVERALL_FIGURES = ("afd", "fid", "kid", "precision", "recall", "accuracy", "diversity")


def _overall(results: list[dict], get) -> dict:
    """A method's figures over all classes (mean, std) and `ci`, each one's 95 % interval, plausibility's included."""
    out: dict = {"ci": {}}
    singles = [get(r).get("intervals", {}) for r in results]  # results saved before intervals have none
    for key in OVERALL_FIGURES:
        values = [_method_afd(get(r)) if key == "afd" else get(r).get(key) for r in results]  # older results lack KID etc.
        _with_std(out, key, values)
        out["ci"][key] = _ci(values, [i.get(key) for i in singles])
    for part in ("plausibility", "afd_parts"):
        if all(part in get(r) for r in results):  # results saved before AFD parts were measured have none
            keys = [k for k in get(results[0])[part] if all(k in get(r)[part] for r in results)]  # measures added later
            out[part] = {k: _stat([get(r)[part][k] for r in results])[0] for k in keys}
            out["ci"] |= {k: _ci([get(r)[part][k] for r in results], [i.get(k) for i in singles]) for k in keys
                          if k not in out["ci"]}
    return out


def _strongest(classes: dict, baselines: dict, metric: str) -> tuple[str | None, float]:
    """(baseline with the lowest mean `metric` in this class, model / that baseline)."""
    scores = {b: v[metric] for b, v in baselines.items() if np.isfinite(v[metric])}
    if not scores:
        return None, float("nan")
    best = min(scores, key=scores.get)
    return best, classes[metric] / scores[best] if scores[best] > 0 else float("nan")


def group_summary(results: list[dict], class_names: tuple[str, ...]) -> dict:
    names = [b for b in results[0]["baselines"] if all(b in r["baselines"] for r in results)]
    model = _method_classes(results, lambda r: r["model"], class_names)
    base = {b: _method_classes(results, lambda r, b=b: r["baselines"][b], class_names) for b in names}
    classes = {}
    for c in class_names:
        entry = dict(model[c])
        _with_std(entry, "adherence", [r["adherence"][c] for r in results])
        _with_std(entry, "adherence_judge", [r["adherence_judge"][c] for r in results])
        entry["baselines"] = {b: base[b][c] for b in names}
        for metric in ("afd", "afd_squared", "fid"):
            entry[f"strongest_baseline_{metric}"], entry[f"ratio_strongest_{metric}"] = _strongest(entry, entry["baselines"], metric)
        entry["strongest_baseline"], entry["ratio_strongest"] = entry["strongest_baseline_afd"], entry["ratio_strongest_afd"]
        if "nn1" in names:
            entry["ratio_nn1"] = entry["afd"] / entry["baselines"]["nn1"]["afd"]
        classes[c] = entry
    def mean_over(key: str) -> float:
        vals = [classes[c][key] for c in class_names if np.isfinite(classes[c].get(key, np.nan))]
        return float(np.mean(vals)) if vals else float("nan")

    out = {
        "n_results": len(results),
        "interval": {"level": intervals.LEVEL, "method": "t over results" if len(results) > 1 else
                     f"bootstrap over sequences ({intervals.RESAMPLES} resamples)"},
        "classes": classes,
        "mean": {k: mean_over(k) for k in ("afd", "afd_squared", "fid", "accuracy", "adherence", "ratio_strongest", "ratio_nn1")}
        | {f"{b}_afd": float(np.nanmean([base[b][c]["afd"] for c in class_names])) for b in names},
        "classifier": {"real_accuracy": {k: _stat([r["classifier"]["real_accuracy"][k] for r in results])[0]
                                         for k in results[0]["classifier"]["real_accuracy"]}},
        "model_overall": _overall(results, lambda r: r["model"]),
        "baselines_overall": {b: _overall(results, lambda r, b=b: r["baselines"][b]) for b in names},
        "real_diversity": _stat([r["real_diversity"] for r in results])[0],
        "adherence_matrix": np.nanmean([r["adherence_matrix"] for r in results], axis=0).tolist(),
        "adherence_matrix_judge": np.nanmean([r["adherence_matrix_judge"] for r in results], axis=0).tolist(),
    }
    for judge in ("", "_judge"):  # the follower GRU (also the training critic of imm-critic) and the independent judge
        out[f"mix{judge}"] = _mean_mix(results, f"mix{judge}")
        out[f"mix_pairs_ok{judge}"] = sum(r["first"] >= MIX_SHARE and r["second"] >= MIX_SHARE for r in out[f"mix{judge}"])
        out[f"avoid{judge}"] = {k: _stat([r[f"avoid{judge}"][k] for r in results])[0] for k in results[0][f"avoid{judge}"]}
    if all("mix_parts" in r for r in results):  # the mixed reading by the whole body or by body parts
        out["mix_parts"] = _mean_mix(results, "mix_parts")
        out["mix_mixed_mean"] = float(np.mean([row["mixed"] for row in out["mix_parts"]]))
    if all("part_pairs" in r for r in results):  # a label per body part: each ordered pair, beside real composites
        keys = [key for key in ("read", "real", "real_nearest_training") if all(key in r["part_pairs"][0] for r in results)]
        out["part_pairs"] = [{"upper": row["upper"], "lower": row["lower"]}
                             | {key: _stat([r["part_pairs"][k][key] for r in results])[0] for key in keys}
                             for k, row in enumerate(results[0]["part_pairs"])]
        out["part_avoid"] = {part: {key: _stat([r["part_avoid"][part][key] for r in results])[0]
                                    for key in results[0]["part_avoid"][part]} for part in results[0]["part_avoid"]}
    if all("part_realism" in r for r in results):  # each class on each body part, beside real held-out followers
        out["part_realism"] = [{"class": row["class"], "part": row["part"]}
                               | {key: float(np.nanmean([r["part_realism"][k][key] for r in results])) for key in ("own", "all", "real")}
                               for k, row in enumerate(results[0]["part_realism"])]
    if all("variations" in r for r in results):  # stochastic models: multimodality and best-of-N AFD
        keys = [k for k in results[0]["variations"] if all(k in r["variations"] for r in results)]  # older results lack some
        out["variations"] = {k: _stat([r["variations"][k] for r in results])[0] for k in keys}
    _with_std(out, "adherence_off_diagonal", [r["adherence_off_diagonal"] for r in results])
    _with_std(out, "adherence_off_diagonal_judge", [r["adherence_off_diagonal_judge"] for r in results])
    out["plausibility"] = out["model_overall"]["plausibility"]
    return out


def _mean_mix(results: list[dict], key_: str) -> list[dict]:
    """Per pair, the mean of each number every result has (a result recorded before a number existed lacks it)."""
    rows = []
    for k, row in enumerate(results[0][key_]):
        keys = [key for key in row if key != "pair" and all(key in r[key_][k] for r in results)]
        rows.append({"pair": row["pair"]} | {key: _stat([r[key_][k][key] for r in results])[0] for key in keys})
    return rows


def summarize(results: list[dict], class_names: tuple[str, ...]) -> dict:
    """The whole summary: the "all" group's keys at top level, plus groups, folds, seeds and per-fold results."""
    groups = {"all": results, "dev": [r for r in results if r["group"] == "dev"], "test": [r for r in results if r["group"] == "test"]}
    seeds = sorted({r.get("seed") for r in results if r.get("seed") is not None})
    summary = {"folds": sorted({r["subject"] for r in results}), "seeds": seeds, "class_names": list(class_names)}
    summary["groups"] = {g: group_summary(rs, class_names) for g, rs in groups.items() if rs}
    summary |= summary["groups"]["all"]
    summary["per_fold"] = list(results)
    return summary


NAN = float("nan")  # a figure a result saved before it was measured lacks


@dataclass(frozen=True)
class BaselineFigures:
    """The 1-NN retrieval's figures on the same fold (flat names `<figure>_nn1`, `fid_nn1_<class>`)."""

    afd: float
    fid: float
    kid: float
    precision: float
    recall: float
    jitter_ratio: float
    fid_per_class: dict[str, float]


@dataclass(frozen=True)
class FoldFigures:
    """The figures a model is compared by on one fold (the model cards, `imm reproduce --tables models`, the experiment
    scripts), from one fold's result (evaluation/loso.py `evaluate_fold`); docs/evaluation-protocol.md defines each."""

    afd: float  # one sample's AFD, the mean over classes (the paper's normalized units)
    fid: float
    kid: float
    precision: float
    recall: float
    judge_real_accuracy: float  # the independent judge on real followers: what the label figures can be read against
    off_label: float  # asked for another class than the leader's, the share that reads as it
    true_label: float  # asked for the leader's class, the share that reads as it
    mixed: float  # two-class mixes read as both classes (the whole-body or body-part judges)
    mixed_whole_body: float  # ... by the whole-body judge alone
    mixed_worst_pair: float
    avoid_share_lowered: float  # -1 lowers the class's reading
    interior_limb_speed_ratio: float  # limb speed between the first and last frames, over real followers'
    lean_error_deg: float
    bone_error_cm: float
    foot_skate_mps: float
    interpenetration: float
    real_interpenetration: float
    contact_ratio: float  # frames in contact over real followers'
    jitter_mps2: float
    real_jitter_mps2: float
    jitter_ratio: float
    fid_per_class: dict[str, float]  # flat names `fid_<class>`
    contact_ratio_worst_class: float | None = None  # None: a result saved before per-class contact
    classes_beyond_real_contact: int | None = None
    nn1: BaselineFigures | None = None  # None: the 1-NN was not among the result's baselines
    multimodality_ratio: float | None = None  # a model that draws variations only
    afd_best_of_n: float | None = None
    multimodality_same_leader_ratio: float | None = None

    @classmethod
    def of(cls, result: dict) -> FoldFigures:
        m, nn1, mixes = result["model"], result["baselines"].get("nn1"), result["mix_parts"]
        p = m["plausibility"]
        classes = [v for v in m["classes"].values() if "real_contact" in v]
        ratios = [v["contact"] / v["real_contact"] for v in classes if v["real_contact"] > 0]
        variations = result.get("variations")
        return cls(
            afd=_method_afd(m), fid=m["fid"], kid=m.get("kid", NAN), precision=m.get("precision", NAN),
            recall=m.get("recall", NAN), judge_real_accuracy=result["classifier"]["real_accuracy"]["follower_judge"],
            off_label=result["adherence_off_diagonal_judge"],
            true_label=float(np.nanmean(np.diag(np.array(result["adherence_matrix_judge"], dtype=float)))),
            mixed=float(np.mean([r["mixed"] for r in mixes])), mixed_whole_body=float(np.mean([r["whole"] for r in mixes])),
            mixed_worst_pair=float(min(r["mixed"] for r in mixes)), avoid_share_lowered=result["avoid_judge"]["share_lowered"],
            interior_limb_speed_ratio=p["interior_limb_speed_ratio"], lean_error_deg=p["lean_error_deg"],
            bone_error_cm=p["bone_error_cm"], foot_skate_mps=p["foot_skate_mps"], interpenetration=p["interpenetration"],
            real_interpenetration=p["real_interpenetration"],
            contact_ratio=p["interpenetration"] / p["real_interpenetration"] if p["real_interpenetration"] > 0 else NAN,
            jitter_mps2=p.get("jitter_mps2", NAN), real_jitter_mps2=p.get("real_jitter_mps2", NAN),
            jitter_ratio=p.get("jitter_ratio", NAN), fid_per_class={c: v["fid"] for c, v in m["classes"].items()},
            # contact counts against a model only beyond what real pairs of the class show; a class whose real pairs
            # never touch counts with any contact at all
            contact_ratio_worst_class=(float(max(ratios)) if ratios else NAN) if classes else None,
            classes_beyond_real_contact=sum(v["contact"] > CONTACT_TOLERANCE * v["real_contact"] for v in classes) if classes else None,
            nn1=None if nn1 is None else BaselineFigures(
                afd=_method_afd(nn1), fid=nn1["fid"], kid=nn1.get("kid", NAN), precision=nn1.get("precision", NAN),
                recall=nn1.get("recall", NAN), jitter_ratio=nn1["plausibility"].get("jitter_ratio", NAN),
                fid_per_class={c: v["fid"] for c, v in nn1["classes"].items()}),
            multimodality_ratio=None if variations is None else variations["multimodality"] / variations["real_class_diversity"],
            afd_best_of_n=None if variations is None else variations["afd_best_of_n"],
            multimodality_same_leader_ratio=(variations["multimodality"] / variations["real_same_leader_diversity"]
                                             if variations and "real_same_leader_diversity" in variations else None))

    def flat(self) -> dict[str, float]:
        """The figures by the flat names the tables, the JSON and the experiment records use (`fid_<class>`, the
        1-NN's as `<figure>_nn1` and `fid_nn1_<class>`); figures not measured are left out."""
        out = {f.name: getattr(self, f.name) for f in fields(self)
               if f.name not in ("fid_per_class", "nn1") and getattr(self, f.name) is not None}
        out |= {f"fid_{c}": v for c, v in self.fid_per_class.items()}
        if self.nn1 is not None:
            out |= {f"{f.name}_nn1": getattr(self.nn1, f.name) for f in fields(self.nn1) if f.name != "fid_per_class"}
            out |= {f"fid_nn1_{c}": v for c, v in self.nn1.fid_per_class.items()}
        return out


def fold_figure_intervals(result: dict) -> dict[str, tuple[float, float]]:
    """The 95 % bootstrap interval over one fold's test sequences of each FoldFigures figure that has one (AFD, FID,
    KID, precision, recall, jitter, the same for the 1-NN as `*_nn1`); empty for a result saved before intervals."""
    out = {k: intervals.as_interval(v) for k, v in result["model"].get("intervals", {}).items()}
    nn1 = result["baselines"].get("nn1", {})
    out |= {f"{k}_nn1": intervals.as_interval(v) for k, v in nn1.get("intervals", {}).items()}
    return out
