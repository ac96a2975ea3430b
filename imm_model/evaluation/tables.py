"""The evaluation summary (evaluation/report.py) as Markdown tables: what `imm evaluate` prints and writes."""

from __future__ import annotations

import numpy as np

from imm_model.evaluation.intervals import with_interval

BASELINE_TITLES = {"nn1": "1-NN", "knn_dtw": "DTW 3-NN avg", "template": "class template", "men": "label-free (Men-style)"}


def _pm(mean: float, std: float | None = None, digits: int = 3) -> str:
    if mean is None or not np.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f}" if std is None or not np.isfinite(std) or std == 0 else f"{mean:.{digits}f} ± {std:.{digits}f}"


def _cell(entry: dict, key: str, digits: int = 3, ci: dict | None = None) -> str:
    """`mean [low, high]` with the entry's 95 % interval (`key_ci` beside it, or `ci[key]`); a summary saved before
    intervals has none and shows mean ± std."""
    interval = ci.get(key) if ci is not None else entry.get(f"{key}_ci")
    if interval is not None and all(np.isfinite(interval)):
        return with_interval(entry[key], interval, digits)
    return _pm(entry[key], entry.get(f"{key}_std"), digits)


def metric_table(group: dict, metric: str, digits: int = 3) -> str:
    """Per class: model, every baseline (mean [95 % interval] over folds/seeds, or over one fold's sequences), the
    strongest baseline and the ratio."""
    classes = group["classes"]
    names = list(next(iter(classes.values()))["baselines"])
    strongest, ratio = f"strongest_baseline_{metric}", f"ratio_strongest_{metric}"
    head = ["class", "model", *(BASELINE_TITLES.get(b, b) for b in names), "strongest baseline", "model / strongest"]
    if metric == "afd" and "nn1" in names:
        head.append("model / 1-NN")
    lines = ["| " + " | ".join(head) + " |", "|---|" + "---:|" * (len(head) - 1)]
    for c, e in classes.items():
        row = [c, _cell(e, metric, digits)]
        row += [_cell(e["baselines"][b], metric, digits) for b in names]
        row += [BASELINE_TITLES.get(e[strongest], str(e[strongest])), _pm(e[ratio])]
        if metric == "afd" and "nn1" in names:
            row.append(_pm(e["ratio_nn1"]))
        lines.append("| " + " | ".join(row) + " |")
    mean = lambda key, src=None: float(np.nanmean([(src(e) if src else e)[key] for e in classes.values()]))  # noqa: E731
    # the mean over classes has an interval for AFD (evaluation/report.py `_overall`), computed per result
    ci = lambda o: o.get("ci", {}).get(metric) if metric == "afd" else None  # noqa: E731
    row = ["**mean**", f"**{with_interval(mean(metric), ci(group['model_overall']), digits)}**"]
    row += [with_interval(mean(metric, lambda e, b=b: e["baselines"][b]), ci(group["baselines_overall"][b]), digits) for b in names]
    row += ["", f"**{_pm(mean(ratio))}**"]
    if metric == "afd" and "nn1" in names:
        row.append(_pm(mean("ratio_nn1")))
    lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def control_table(group: dict) -> str:
    classes = group["classes"]
    lines = ["| requested class | adherence (follower GRU) | adherence (independent conv judge) "
             "| recognition of the model's interactions |", "|---|---:|---:|---:|"]
    for c, e in classes.items():
        lines.append(f"| {c} | {_pm(e['adherence'], e['adherence_std'])} | {_pm(e['adherence_judge'], e['adherence_judge_std'])} | "
                     f"{_pm(e['accuracy'], e['accuracy_std'])} |")
    off = [_pm(group[k], group[f"{k}_std"]) for k in ("adherence_off_diagonal", "adherence_off_diagonal_judge")]
    lines.append(f"| **off-diagonal mean** (label differs from the leader's class) | {off[0]} | {off[1]} | |")
    return "\n".join(lines)


def mix_table(group: dict) -> str:
    lines = ["| mix (+1 each) | first / second, follower GRU | first / second, independent judge | mass on the pair (judge) "
             "| both in the top 2 (judge) | leaders read as both (judge) |", "|---|---:|---:|---:|---:|---:|"]
    for r, j in zip(group["mix"], group["mix_judge"], strict=True):
        lines.append(f"| {r['pair'][0]} + {r['pair'][1]} | {r['first']:.2f} / {r['second']:.2f} | {j['first']:.2f} / {j['second']:.2f} "
                     f"| {j['mass']:.2f} | {j['both_top2']:.2f} | {j.get('both_read', float('nan')):.2f} |")
    lines.append(f"| **pairs with >= 0.25 on each member** | {group['mix_pairs_ok']} / {len(group['mix'])} "
                 f"| {group['mix_pairs_ok_judge']} / {len(group['mix'])} | | | |")
    return "\n".join(lines)


def part_mix_table(group: dict) -> str:
    """The share of leaders whose reaction reads as mixed, per pair: by the whole-body judge, by the body-part judges,
    by either (evaluation/control.py); empty for results recorded without them."""
    if "mix_parts" not in group:
        return ""
    rows = group["mix_parts"]
    real = all("real_whole" in r for r in rows)
    lines = ["| mix (+1 each) | whole body (each >= 0.25) | body parts (one each, >= 0.4) | mixed (either) |"
             + (" held-out part composites, whole body |" if real else ""), "|---|---:|---:|---:|" + ("---:|" if real else "")]
    for r in rows:
        lines.append(f"| {r['pair'][0]} + {r['pair'][1]} | {r['whole']:.2f} | {r['parts']:.2f} | {r['mixed']:.2f} |"
                     + (f" {r['real_whole']:.2f} |" if real else ""))
    lines.append(f"| **mean** | {np.mean([r['whole'] for r in rows]):.2f} | {np.mean([r['parts'] for r in rows]):.2f} | "
                 f"**{group['mix_mixed_mean']:.2f}** |" + (f" {np.nanmean([r['real_whole'] for r in rows]):.2f} |" if real else ""))
    return "\n".join(lines)


def part_realism_table(group: dict) -> str:
    """Per class and body part, the share of the model's reactions asked for the class that its part judge reads as
    it (>= 0.4), on the leaders of that class and on all leaders, beside the class's real held-out followers."""
    if "part_realism" not in group:
        return ""
    lines = ["| class | part | leaders of the class | all leaders | real held-out followers | model / real |",
             "|---|---|---:|---:|---:|---:|"]
    for r in group["part_realism"]:
        ratio = f"{r['own'] / r['real']:.2f}" if r["real"] > 0 else "–"
        lines.append(f"| {r['class']} | {r['part']} | {r['own']:.2f} | {r['all']:.2f} | {r['real']:.2f} | {ratio} |")
    return "\n".join(lines)


def part_pair_table(group: dict) -> str:
    """A model with a label per body part: per ordered pair (A on the trunk and arms, B on the legs and placement), the
    share of leaders whose parts read so, beside real part composites' share; and the part negations. Empty for a
    model without part labels."""
    if "part_pairs" not in group:
        return ""
    rows = group["part_pairs"]
    nearest = all("real_nearest_training" in r for r in rows)
    lines = ["| upper body | lower body | read as asked (each part >= 0.4) | held-out composites (judges never saw them) | ratio |"
             + (" nearest training composites (judges' memory) |" if nearest else ""),
             "|---|---|---:|---:|---:|" + ("---:|" if nearest else "")]
    for r in rows:
        ratio = f"{r['read'] / r['real']:.2f}" if r["real"] > 0 else "–"
        lines.append(f"| {r['upper']} | {r['lower']} | {r['read']:.2f} | {r['real']:.2f} | {ratio} |"
                     + (f" {r['real_nearest_training']:.2f} |" if nearest else ""))
    read, real = np.mean([r["read"] for r in rows]), np.nanmean([r["real"] for r in rows])
    memory = f" {np.mean([r['real_nearest_training'] for r in rows]):.2f} |" if nearest else ""
    lines.append((f"| **mean** | | **{read:.2f}** | {real:.2f} | {read / real:.2f} |" if real > 0 else f"| **mean** | | {read:.2f} | 0 | |")
                 + memory)
    avoid = group.get("part_avoid", {})
    lines += ["\n-1 on the leader's class on one part, against an all-zero label: "
              + "; ".join(f"the {part} body's judge lowers it for {v['share_lowered']:.2f} of leaders (mean change "
                          f"{v['change']:+.3f})" for part, v in avoid.items())]
    return "\n".join(lines)


def variations_table(group: dict) -> str:
    """A stochastic model's spread and best-of-N AFD; empty for a deterministic model."""
    v = group.get("variations")
    if not v:
        return ""
    same_leader = v.get("real_same_leader_diversity", float("nan"))
    return "\n".join([
        f"| reactions per leader | multimodality (features) | real within-class diversity | the same, against one leader "
        f"| multimodality (m) | AFD, one sample | AFD, best of {v['samples']:.0f} |", "|---:|---:|---:|---:|---:|---:|---:|",
        f"| {v['samples']:.0f} | {v['multimodality']:.3f} | {v['real_class_diversity']:.3f} | {same_leader:.3f} "
        f"| {v['multimodality_m']:.3f} | {v['afd_single']:.3f} | {v['afd_best_of_n']:.3f} |"])


def plausibility_table(group: dict) -> str:
    cols = ("bone_error_cm", "interpenetration", "foot_skate_mps", "speed_ratio", "limb_speed_ratio", "smooth_limb_speed_ratio",
            "body_limb_speed_ratio", "interior_limb_speed_ratio", "root_sway_mps", "lean_error_deg")
    lines = ["| method | bone error (cm) | interpenetrating frames | foot skate (m/s) | speed / real | limb speed / real "
             "| limb speed, both smoothed / real | limb speed from the body centre / real | the same, interior frames "
             "| root sway (m/s) | torso lean error (deg) |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    rows = [("model", group["model_overall"]["plausibility"])]
    rows += [(BASELINE_TITLES.get(b, b), v["plausibility"]) for b, v in group["baselines_overall"].items()]
    real = group["model_overall"]["plausibility"]
    rows.append(("real followers", {"bone_error_cm": real["real_bone_error_cm"], "interpenetration": real["real_interpenetration"],
                                    "foot_skate_mps": real["real_foot_skate_mps"], "speed_ratio": 1.0, "limb_speed_ratio": 1.0,
                                    "smooth_limb_speed_ratio": 1.0, "body_limb_speed_ratio": 1.0, "interior_limb_speed_ratio": 1.0,
                                    "root_sway_mps": real.get("real_root_sway_mps", float("nan")), "lean_error_deg": 0.0}))
    for name, p in rows:
        lines.append(f"| {name} | " + " | ".join(f"{p.get(k, float('nan')):.3f}" for k in cols) + " |")
    return "\n".join(lines)


def afd_parts_table(group: dict) -> str:
    """Where the AFD comes from (metrics.afd_parts), model beside each baseline; empty without the numbers."""
    rows = [("model", group["model_overall"])] + [(BASELINE_TITLES.get(b, b), v) for b, v in group["baselines_overall"].items()]
    if not all("afd_parts" in o for _, o in rows):
        return ""
    lines = ["| method | root offset, first frame (m) | root offset, mean (m) | joints relative to the root (m) |",
             "|---|---:|---:|---:|"]
    for name, o in rows:
        p = o["afd_parts"]
        lines.append(f"| {name} | {p['start_root_m']:.3f} | {p['root_m']:.3f} | {p['limb_m']:.3f} |")
    return "\n".join(lines)


def contact_table(group: dict) -> str:
    """Per class, the share of frames in which the two bodies touch (plausibility.interpenetration), the model beside
    the real pairs of the class; empty for results saved before it was measured."""
    classes = group["classes"]
    if not all(np.isfinite(e.get("real_contact", np.nan)) for e in classes.values()):
        return ""
    lines = ["| class | model | real pairs | model / real |", "|---|---:|---:|---:|"]
    for c, e in classes.items():
        ratio = e["contact"] / e["real_contact"] if e["real_contact"] > 0 else float("nan")
        lines.append(f"| {c} | {_pm(e['contact'], e['contact_std'])} | {_pm(e['real_contact'])} | {_pm(ratio, digits=2)} |")
    return "\n".join(lines)


def overall_table(group: dict) -> str:
    lines = ["| method | FID (all classes) | recognition accuracy | diversity (real: {:.2f}) |".format(group["real_diversity"]),
             "|---|---:|---:|---:|"]
    rows = [("model", group["model_overall"])] + [(BASELINE_TITLES.get(b, b), v) for b, v in group["baselines_overall"].items()]
    for name, o in rows:
        cells = [_cell(o, k, 2, o.get("ci", {})) for k in ("fid", "accuracy", "diversity")]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def distribution_table(group: dict) -> str:
    """Per method: AFD, FID, KID, precision and recall (k = 3) and jitter, each with its 95 % interval; the real
    followers' jitter beside. Empty for a summary saved before KID was measured."""
    rows = [("model", group["model_overall"])] + [(BASELINE_TITLES.get(b, b), v) for b, v in group["baselines_overall"].items()]
    if not all(np.isfinite(o.get("kid", np.nan)) for _, o in rows):
        return ""
    lines = ["| method | AFD | FID | KID | precision | recall | jitter (m/s²) | jitter / real |", "|---|" + "---:|" * 7]
    for name, o in rows:
        p, ci = o["plausibility"], o["ci"]
        cells = [_cell(o, "afd", 3, ci), _cell(o, "fid", 2, ci), _cell(o, "kid", 3, ci), _cell(o, "precision", 2, ci),
                 _cell(o, "recall", 2, ci), _cell(p, "jitter_mps2", 1, ci), _cell(p, "jitter_ratio", 2, ci)]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    real = group["model_overall"]
    lines.append(f"| real followers | | | | | | {_cell(real['plausibility'], 'real_jitter_mps2', 1, real['ci'])} | 1 |")
    return "\n".join(lines)


def headline(summary: dict) -> str:
    """One line per group: the model's mean AFD ratio to the strongest baseline and to 1-NN."""
    lines = []
    for g, s in summary["groups"].items():
        folds = sorted({r["subject"] for r in summary["per_fold"] if g == "all" or r["group"] == g})
        acc = s["classifier"]["real_accuracy"]
        m = s["mean"]
        nn1 = f", to 1-NN {m['ratio_nn1']:.3f}" if np.isfinite(m["ratio_nn1"]) else ""
        afd = with_interval(m["afd"], s["model_overall"].get("ci", {}).get("afd"))
        lines.append(f"{g} ({', '.join(folds)}; {s['n_results']} results): AFD {afd}, ratio to the strongest baseline "
                     f"{m['ratio_strongest']:.3f}{nn1}; off-label adherence {s['adherence_off_diagonal']:.2f} "
                     f"(judge {s['adherence_off_diagonal_judge']:.2f}); classifiers on real data: interaction "
                     f"{acc['interaction']:.2f}, follower {acc['follower']:.2f}, judge {acc['follower_judge']:.2f}")
    return "\n".join(lines)


def _section(title: str, table: str) -> list[str]:
    return [f"### {title}", "", table, ""] if table else []


def report_groups(summary: dict) -> dict[str, dict]:
    """all, dev and test; only all when the folds are of one group (it equals that group)."""
    return summary["groups"] if len(summary["groups"]) > 2 else {"all": summary["groups"]["all"]}


def printed_distribution(summary: dict) -> str:
    """What `imm evaluate` prints beside the AFD table: each group's distribution_table."""
    return "\n\n".join(f"{g} folds: {_distribution_title(s)}\n{t}" for g, s in report_groups(summary).items()
                       if (t := distribution_table(s)))


def markdown_report(summary: dict) -> str:
    parts = ["# Evaluation", "", headline(summary).replace("\n", "\n\n"), ""]
    groups = report_groups(summary)
    for g, s in groups.items():
        parts += [f"## {g} folds", "", "### AFD (normalized SBU units, lower is better)", "", metric_table(s, "afd"), "",
                  *_section("Where the AFD comes from (canonical metres, per joint and frame)", afd_parts_table(s)),
                  "### AFD squared (the authors' code's variant)", "", metric_table(s, "afd_squared"), "",
                  "### FID per class (interaction-classifier features)", "", metric_table(s, "fid", 2), "",
                  "### All classes", "", overall_table(s), "",
                  *_section(_distribution_title(s), distribution_table(s)),
                  "### Label control (follower-only classifiers)", "", control_table(s), "",
                  f"Avoid (-1 on the leader's class vs all zero): P(leader's class) {s['avoid']['p_zero']:.2f} -> "
                  f"{s['avoid']['p_avoid']:.2f} (change {s['avoid']['change']:+.2f}); independent judge "
                  f"{s['avoid_judge']['p_zero']:.2f} -> {s['avoid_judge']['p_avoid']:.2f}.", "",
                  "### Mix", "", mix_table(s), "",
                  *_section("Mixed, by the whole body or by body parts (share of leaders)", part_mix_table(s)),
                  *_section("A label per body part (share of leaders)", part_pair_table(s)),
                  *_section("Part realism: each class on each body part, asked for the whole body (share read as it)",
                            part_realism_table(s)),
                  *_section("Variations (stochastic models)", variations_table(s)),
                  "### Plausibility", "", plausibility_table(s), "",
                  *_section("Contact per class (share of frames the bodies touch)", contact_table(s))]
    return "\n".join(parts)


def _distribution_title(group: dict) -> str:
    return f"AFD, distribution and jitter (95 % interval: {group.get('interval', {}).get('method', 'none')})"
