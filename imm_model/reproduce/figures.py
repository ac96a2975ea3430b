"""The report's PNG figures: the paper's numbers beside ours, per class."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.outputs import write_atomic
from imm_model.reproduce import paper_numbers as paper
from imm_model.reproduce.plan import ABLATION_RECIPES


def _bars(ax, groups: dict[str, list[float]], errors: dict[str, list[float]], labels: list[str]) -> None:
    width = 0.8 / max(1, len(groups))
    x = np.arange(len(labels))
    for k, (name, values) in enumerate(groups.items()):
        ax.bar(x + (k - (len(groups) - 1) / 2) * width, values, width, yerr=errors.get(name), label=name, capsize=2)
    ax.set_xticks(x, labels, rotation=20)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)  # beside the bars, never over them


def write_figures(results: dict, summary: dict | None, class_names: list[str], out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    if summary is not None:
        cls = summary["classes"]
        fig, ax = plt.subplots(figsize=(8, 3.5))
        groups = {"paper: IMM": list(paper.AFD["IMM (paper)"]), "paper: Men et al.": list(paper.AFD["Men et al. 2022"]),
                  "ours: IMM": [cls[c]["afd"] for c in class_names]}
        errors = {"ours: IMM": [cls[c]["afd_std"] for c in class_names]}
        if all("men" in cls[c]["baselines"] for c in class_names):
            groups["ours: label-free"] = [cls[c]["baselines"]["men"]["afd"] for c in class_names]
            errors["ours: label-free"] = [cls[c]["baselines"]["men"]["afd_std"] for c in class_names]
        _bars(ax, groups, errors, class_names)
        ax.set_ylabel("AFD (normalized units)")
        ax.set_title("AFD on SBU per class: the paper's numbers and ours")
        paths.append(_save(fig, out / "afd.png"))
    ablation = _ablation_means(results, class_names)
    if ablation:
        fig, ax = plt.subplots(figsize=(7, 3.2))
        names = list(ablation)
        _bars(ax, {"paper": [float(np.mean(paper.ABLATION_AFD[r][1])) for r in names], "ours": [ablation[r] for r in names]}, {}, names)
        ax.set_ylabel("mean AFD over classes")
        ax.set_title("Ablations on SBU")
        paths.append(_save(fig, out / "ablation.png"))
    recognition = [r for j, r in results.items() if r is not None and j.kind == "recognition" and j.run.split == "half"]
    if recognition:
        fig, ax = plt.subplots(figsize=(8, 3.2))
        mean = lambda key: np.nanmean([r[key]["per_class"] for r in recognition], axis=0).tolist()  # noqa: E731
        groups = {"paper: original": list(paper.RECOGNITION["Original"]), "paper: augmented": list(paper.RECOGNITION["Augmented"]),
                  "ours: original": mean("original"), "ours: augmented (train only)": mean("augmented")}
        _bars(ax, groups, {}, class_names)
        ax.set_ylabel("accuracy")
        ax.set_title("Recognition on SBU's half/half split, with and without synthesized data")
        paths.append(_save(fig, out / "recognition.png"))
    plt.close("all")
    return paths


def _ablation_means(results: dict, class_names: list[str]) -> dict[str, float]:
    means = {}
    for recipe in ("imm", *ABLATION_RECIPES):
        rs = [r for j, r in results.items() if r is not None and j.kind == "metrics" and j.run.recipe == recipe and j.checkpoint == "best"]
        if rs:
            means[recipe] = float(np.mean([np.mean([e["afd"] for e in r["model"]["classes"].values()]) for r in rs]))
    return means


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path
