"""OUT/report.md (+ PNG figures, + summary.json): each of the paper's tables with the paper's numbers, ours
(mean ± std over folds and seeds) and the difference."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from imm_model.evaluation import intervals
from imm_model.evaluation.report import CONTACT_TOLERANCE, FoldFigures, fold_figure_intervals, group_summary
from imm_model.evaluation.tables import BASELINE_TITLES, _pm
from imm_model.outputs import write_files
from imm_model.reproduce import paper_numbers as paper
from imm_model.reproduce.jobs import HALF_SPLIT
from imm_model.reproduce.plan import ABLATION_RECIPES, MODEL_RECIPES, ReproducePlan

REPORT_FILES = ("report.md", "summary.json")  # in OUT, beside the figures
CLASS_TITLES = ("Kick", "Push", "Shake hands", "Hug", "Exchange obj.", "Punch")


def _table(head: list[str], rows: list[list[str]]) -> str:
    return "\n".join(["| " + " | ".join(head) + " |", "|---|" + "---:|" * (len(head) - 1)]
                     + ["| " + " | ".join(r) + " |" for r in rows])


def _metrics(results: dict, recipe: str, checkpoint: str) -> list[dict]:
    return [r for j, r in results.items() if r is not None and j.kind == "metrics"
            and j.run.recipe == recipe and j.checkpoint == checkpoint]


def afd_section(summary: dict, class_names: list[str]) -> str:
    cls = summary["classes"]
    names = list(next(iter(cls.values()))["baselines"])
    head = ["class", *paper.AFD_METHODS, "**ours: IMM**", *(f"ours: {BASELINE_TITLES[b]}" for b in names),
            "ours - paper", "strongest baseline (ours)", "IMM / strongest"]
    rows = []
    for k, c in enumerate(class_names):
        e = cls[c]
        rows.append([CLASS_TITLES[k], *(f"{paper.AFD[m][k]:.2f}" for m in paper.AFD_METHODS), f"**{_pm(e['afd'], e['afd_std'])}**",
                     *(_pm(e["baselines"][b]["afd"], e["baselines"][b]["afd_std"]) for b in names),
                     f"{e['afd'] - paper.AFD['IMM (paper)'][k]:+.3f}", BASELINE_TITLES.get(e["strongest_baseline"], "-"),
                     _pm(e["ratio_strongest"])])
    mean = lambda f: float(np.mean([f(cls[c]) for c in class_names]))  # noqa: E731
    rows.append(["**mean**", *(f"{np.mean(paper.AFD[m]):.2f}" for m in paper.AFD_METHODS), f"**{mean(lambda e: e['afd']):.3f}**",
                 *(f"{mean(lambda e, b=b: e['baselines'][b]['afd']):.3f}" for b in names),
                 f"{mean(lambda e: e['afd']) - np.mean(paper.AFD['IMM (paper)']):+.3f}", "", _pm(mean(lambda e: e["ratio_strongest"]))])
    sq = mean(lambda e: e["afd_squared"])
    paper_ratio = np.mean(np.array(paper.AFD["IMM (paper)"]) / np.array(paper.AFD["NN"]))
    ours_ratio = mean(lambda e: e["afd"] / e["baselines"]["nn1"]["afd"]) if "nn1" in names else float("nan")
    nn_scale = mean(lambda e: e["baselines"]["nn1"]["afd"]) / np.mean(paper.AFD["NN"]) if "nn1" in names else float("nan")
    return (_table(head, rows) + f"\n\nAFD in the paper's normalized units (docs/evaluation-protocol.md). Our 1-NN scores {nn_scale:.1f}x "
            f"the paper's NN in these units, so compare ratios: IMM / nearest neighbour, mean over classes, is "
            f"{paper_ratio:.2f} in the paper and {ours_ratio:.2f} here. With the authors' code's squared distance "
            f"(`afd_squared`) our IMM scores {sq:.3f} on average.")


def fid_section(summary: dict, class_names: list[str]) -> str:
    cls = summary["classes"]
    head = ["", *CLASS_TITLES[: len(class_names)]]
    rows = [[f"paper: {m}", *(f"{v:.1f}" for v in paper.FID_SBU[m])] for m in paper.FID_SBU]
    ratio_paper = np.array(paper.FID_SBU["IMM (paper)"]) / np.array(paper.FID_SBU["Men et al. 2022"])
    rows.append(["paper: IMM / Men", *(f"{r:.2f}" for r in ratio_paper)])
    men = [cls[c]["baselines"].get("men", {}) for c in class_names]
    rows.append(["ours: label-free (Men-style)", *(_pm(m.get("fid", np.nan), m.get("fid_std"), 2) for m in men)])
    rows.append(["ours: IMM", *(_pm(cls[c]["fid"], cls[c]["fid_std"], 2) for c in class_names)])
    ratios = [cls[c]["fid"] / m.get("fid", np.nan) for c, m in zip(class_names, men, strict=True)]
    rows.append(["ours: IMM / label-free", *(_pm(r, digits=2) for r in ratios)])
    return (_table(head, rows) + "\n\nOur FID is computed on the 64-d features of our interaction classifier "
            "(docs/evaluation-protocol.md); the paper does not say which features it used, so only the ratios are comparable.")


def k3hi_section(results: dict) -> str:
    rs = [r for j, r in results.items() if r is not None and j.kind == "k3hi"]
    if not rs:
        return "Not run: K3HI was not found (../shared/datasets/k3hi) or its runs failed."
    names = rs[0]["class_names"]
    mean = lambda recipe, split, c, key: float(np.nanmean([r[recipe][split][c][key] for r in rs]))  # noqa: E731
    paper_cols = {"kicking": 0, "punching": 1}
    head = ["K3HI class", "paper 2C: Men", "paper 2C: IMM", "test n (own split)", "ours, own split: label-free",
            "ours, own split: IMM", "n (4-fold CV)", "ours, CV: label-free", "ours, CV: IMM", "ours, CV: IMM / label-free",
            "AFD, CV: label-free", "AFD, CV: IMM"]
    rows = []
    for c in names:
        k = paper_cols.get(c)
        rows.append([c, *((f"{paper.FID_2C[m][k]:.1f}" for m in paper.FID_2C) if k is not None else ("-", "-")),
                     str(rs[0]["imm"]["official"][c]["n"]), _pm(mean("men", "official", c, "fid"), digits=2),
                     _pm(mean("imm", "official", c, "fid"), digits=2), str(rs[0]["imm"]["cv"][c]["n"]),
                     _pm(mean("men", "cv", c, "fid"), digits=2), _pm(mean("imm", "cv", c, "fid"), digits=2),
                     _pm(mean("imm", "cv", c, "fid") / mean("men", "cv", c, "fid"), digits=2),
                     _pm(mean("men", "cv", c, "afd")), _pm(mean("imm", "cv", c, "afd"))])
    return (_table(head, rows) + "\n\nThe paper's 2C set (kick, punch) is not public. K3HI's classes shared with SBU are "
            "used (approaching and departing are left out as the paper leaves them out of SBU; pointing has no SBU "
            "counterpart). Its own split (InterFormer's Train.txt/Test.txt) leaves 2-8 test sequences per class, so every "
            "recipe is also trained on 4 class-stratified folds and FID is taken over the pooled held-out predictions "
            "(reproduce/k3hi_table.py). Paper ratio IMM / Men: kick 0.85, punch 0.83. Mean over training seeds.")


def ablation_section(results: dict, class_names: list[str]) -> str:
    head = ["recipe", "paper row", *CLASS_TITLES[: len(class_names)], "mean", "paper mean", "ours - paper", "FID",
            "label adherence (judge)"]
    rows = []
    for recipe in ("imm", *ABLATION_RECIPES):
        rs = _metrics(results, recipe, "best")
        title, ref = paper.ABLATION_AFD[recipe]
        if not rs:
            rows.append([recipe, title, *["-"] * (len(class_names) + 5)])
            continue
        s = group_summary(rs, tuple(class_names))
        afd = [s["classes"][c]["afd"] for c in class_names]
        rows.append([f"`{recipe}`", title, *(_pm(s["classes"][c]["afd"], s["classes"][c]["afd_std"]) for c in class_names),
                     f"**{np.mean(afd):.3f}**", f"{np.mean(ref):.3f}", f"{np.mean(afd) - np.mean(ref):+.3f}",
                     _pm(s["model_overall"]["fid"], digits=2), _pm(s["adherence_off_diagonal_judge"], digits=2)])
    return (_table(head, rows) + "\n\nAll rows are selection models (best.safetensors, chosen on the validation split, no refit), "
            "so `imm` here is not the refit model of the AFD table. Label adherence: how often a follower asked for another "
            "class than the leader's reads as it to the independent judge (chance 0.17).")


def recognition_section(results: dict, class_names: list[str]) -> str:
    C = len(class_names)
    head = ["split", "# train", "# test", *CLASS_TITLES[:C], "overall"]
    rows = [[f"paper: {k}", *(("99", "98") if k == "Original" else ("124", "123")), *(f"{v:.3f}" for v in vals), "-"]
            for k, vals in paper.RECOGNITION.items()]
    half = [r for j, r in results.items() if r is not None and j.kind == "recognition" and j.run.split == HALF_SPLIT]
    loso = [r for j, r in results.items() if r is not None and j.kind == "recognition" and j.run.split != HALF_SPLIT]
    titles = {"original": "original", "augmented": "augmented, synthesized in training only",
              "augmented_paper": "augmented, the paper's protocol (synthesized in training and test)"}
    for label, rs in (("half/half", half), ("LOSO", loso)):
        for key, title in titles.items():
            if rs and key in rs[0]:
                per_class = np.nanmean([r[key]["per_class"] for r in rs], axis=0)
                acc = [r[key]["accuracy"] for r in rs]
                rows.append([f"ours, {label}: {title}", str(rs[0][key]["train"]) if label == "half/half" else "-",
                             str(rs[0][key]["test"]) if label == "half/half" else "-",
                             *(f"{v:.3f}" for v in per_class), _pm(float(np.mean(acc)), float(np.std(acc)))])
    return (_table(head, rows) + "\n\nOurs: the evaluation's interaction classifier (GRU), one per condition (and per fold under LOSO), "
            "with the evaluation's classifier seed for every training seed (the conditions are paired; the spread "
            "over training seeds is the generator's); mean over training seeds (and folds); "
            "50 synthesized interactions per class from the training leaders "
            "(reproduce/recognition.py).")


# the models table's rows: (title, evaluation/report.py FoldFigures' flat name, digits)
MODEL_FIGURES = (
    ("FID", "fid", 2), ("FID, 1-NN retrieval", "fid_nn1", 2), ("KID", "kid", 3), ("KID, 1-NN retrieval", "kid_nn1", 3),
    ("precision (k = 3)", "precision", 2), ("... 1-NN retrieval", "precision_nn1", 2),
    ("recall (k = 3)", "recall", 2), ("... 1-NN retrieval", "recall_nn1", 2), ("AFD, one sample", "afd", 3),
    ("AFD, best of 5 samples", "afd_best_of_n", 3), ("AFD, 1-NN retrieval", "afd_nn1", 3),
    ("judge's accuracy on real followers", "judge_real_accuracy", 2), ("asked for another class: reads as it", "off_label", 2),
    ("asked for the leader's class: reads as it", "true_label", 2), ("two-class mixes read as mixed", "mixed", 2),
    ("... by the whole-body judge alone", "mixed_whole_body", 2), ("... worst pair", "mixed_worst_pair", 2),
    ("-1 lowers the class's reading", "avoid_share_lowered", 2),
    ("limb speed between the ends / real", "interior_limb_speed_ratio", 2), ("lean error (degrees)", "lean_error_deg", 1),
    ("bone error (cm)", "bone_error_cm", 1), ("feet sliding (m/s)", "foot_skate_mps", 3),
    ("jitter: joint acceleration (m/s²)", "jitter_mps2", 1), ("... real followers", "real_jitter_mps2", 1),
    ("... generated / real", "jitter_ratio", 2), ("... 1-NN retrieval / real", "jitter_ratio_nn1", 2),
    ("frames in contact / real", "contact_ratio", 2), ("... in the worst class", "contact_ratio_worst_class", 2),
    (f"classes with contact beyond {CONTACT_TOLERANCE:g} x the real pairs'", "classes_beyond_real_contact", 1),
    ("variations: multimodality / real diversity", "multimodality_ratio", 2),
    ("... / real diversity against one leader", "multimodality_same_leader_ratio", 2),
)


def models_section(results: dict, class_names: list[str]) -> str:
    """The bundled GAN recipe beside the diffusion model (evaluation/report.py FoldFigures), each figure with its 95 %
    interval (evaluation/intervals.py: t over the folds and seeds of a column, or one run's bootstrap over its test
    sequences), dev and test folds apart; then FID per class."""
    runs = {(r, g): [res for j, res in results.items() if res is not None and j.kind == "metrics"
                     and j.run.recipe == r and res["group"] == g and j.baselines == ("nn1",)]
            for g in ("dev", "test") for r in MODEL_RECIPES}
    figures = {k: [FoldFigures.of(res).flat() for res in v] for k, v in runs.items()}
    bootstrap = {k: [fold_figure_intervals(res) for res in v] for k, v in runs.items()}
    columns = [k for k, v in figures.items() if v]
    if not columns:
        return "No run of this table has finished."

    def cell(key: tuple[str, str], name: str, digits: int) -> str:
        scored = [(f[name], b.get(name)) for f, b in zip(figures[key], bootstrap[key], strict=True) if name in f]
        if not scored:
            return "-"
        mean, ci = intervals.pooled([v for v, _ in scored], scored[0][1] if len(scored) == 1 else None)
        return intervals.with_interval(mean, ci, digits)

    titles = [f"{r}, {g} folds ({len(figures[r, g])} runs)" for r, g in columns]
    rows = [[title, *(cell(k, name, d) for k in columns)] for title, name, d in MODEL_FIGURES]
    # each group's 1-NN once (every run scores it)
    retrieval = list({group: (recipe, group) for recipe, group in reversed(columns)}.values())
    per_class = [[c, *(cell(k, f"fid_{c}", 2) for k in columns), *(cell(k, f"fid_nn1_{c}", 2) for k in retrieval)]
                 for c in class_names]
    note = ("Each figure: mean [95 % interval]. With two or more runs in a column (folds x seeds) the interval is the "
            "t-interval over them (mean ± t·sd/√n); with one run, its bootstrap over the fold's test sequences "
            f"({intervals.RESAMPLES} resamples), for the figures that have one. AFD in the paper's normalized units; FID, "
            "KID and precision/recall (k = 3 nearest neighbours: a fold holds ~30 sequences) over the interaction "
            "classifier's features; jitter is the mean joint acceleration at the data's frame rate "
            "(docs/evaluation-protocol.md). Dev folds s01, s03, s04 chose the recipes; s02, s05, s06, s07 are test folds.")
    return "\n\n".join([_table(["", *titles], rows), note, "FID per class:",
                         _table(["class", *titles, *(f"1-NN, {g} folds" for _, g in retrieval)], per_class)])


def disagreements_section() -> str:
    rows = [[what, text, code, ours] for what, text, code, ours in paper.DISAGREEMENTS]
    return _table(["", "paper's text", "authors' code", "this project"], rows)


def _run_seconds(plan: ReproducePlan, runs: Path) -> float:
    """Training time of every run (what done.json recorded, in its worker), summed."""
    total = 0.0
    for job in plan.training_jobs():
        try:
            total += float(json.loads((job.run_dir(runs) / "done.json").read_text())["seconds"])
        except (OSError, ValueError, KeyError):
            pass
    return total


def write_report(plan: ReproducePlan, results: dict, out: Path, wall_s: float | None, runs: Path) -> Path:
    """Write report.md, summary.json and figures; a table whose runs are missing says so. wall_s None: nothing was
    run (--report-only)."""
    from imm_model.reproduce.figures import write_figures

    class_names = next((list(r["model"]["classes"]) for j, r in results.items() if r is not None and j.kind == "metrics"),
                       next((r["class_names"] for j, r in results.items() if r is not None and j.kind == "recognition"), []))
    imm = _metrics(results, "imm", "final")
    summary = group_summary(imm, tuple(class_names)) if imm else None
    when = "written from finished runs (--report-only)" if wall_s is None else \
        f"this invocation {wall_s / 60:.1f} min wall on {os.cpu_count()} CPUs"
    parts = [f"# The paper's tables, reproduced\n\n`imm reproduce --seeds {','.join(map(str, plan.seeds))} --tables "
             f"{','.join(plan.tables)}` · folds {', '.join(plan.folds)} · {when}; "
             f"the {len(plan.training_jobs())} training runs took {_run_seconds(plan, runs) / 60:.0f} "
             f"worker-minutes in all · {time.strftime('%Y-%m-%d')}. Mean ± std over folds and seeds; lower is better for AFD and FID."]
    if summary and "afd" in plan.tables:
        parts.append("## AFD on SBU (paper Table 1)\n\n" + afd_section(summary, class_names) + _dev_test(imm, class_names))
    if summary and "fid" in plan.tables:
        parts.append("## FID on SBU (paper Table 2)\n\n" + fid_section(summary, class_names))
        parts.append("## FID on the MoCap set (paper Table 3): K3HI in place of 2C\n\n" + k3hi_section(results))
    if "ablation" in plan.tables:
        parts.append("## Ablation on SBU (paper Table 4)\n\n" + ablation_section(results, class_names))
    if "recognition" in plan.tables:
        parts.append("## Recognition with synthesized data (paper Table 5)\n\n" + recognition_section(results, class_names))
    if "models" in plan.tables:
        parts.append(f"## The models: {' and '.join(MODEL_RECIPES)} against the 1-NN retrieval\n\n" + models_section(results, class_names))
    parts.append("## Where the paper's text and its code disagree\n\n" + disagreements_section())
    missing = [j.name for j, r in results.items() if r is None]
    if missing:
        parts.append("## Missing\n\n" + "\n".join(f"- {m}" for m in missing))
    figures = write_figures(results, summary, class_names, out) if class_names else []
    parts.append("## Figures\n\n" + "\n".join(f"![{p.stem}]({p.name})" for p in figures))
    path, summary_path = (out / name for name in REPORT_FILES)
    write_files([(path, "\n\n".join(parts) + "\n"),
                 (summary_path, json.dumps({"imm": summary, "seeds": plan.seeds, "folds": plan.folds, "wall_s": wall_s},
                                           indent=1, default=float) + "\n")])
    return path


def _dev_test(imm: list[dict], class_names: list[str]) -> str:
    lines = []
    for group in ("dev", "test"):
        rs = [r for r in imm if r["group"] == group]
        if rs:
            s = group_summary(rs, tuple(class_names))
            lines.append(f"{group} folds: IMM {s['mean']['afd']:.3f}, IMM / strongest baseline {s['mean']['ratio_strongest']:.3f}")
    return ("\n\n" + "; ".join(lines) + ".") if lines else ""
