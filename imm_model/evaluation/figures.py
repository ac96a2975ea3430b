"""PNG figures of an evaluation: per-class bars, the adherence and mix heatmaps, and the latent t-SNE."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.evaluation.tables import BASELINE_TITLES


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=90)
    _plt().close(fig)
    tmp.replace(path)
    return path


def metric_bars(group: dict, metric: str, path: Path, title: str) -> Path:
    """Per-class bars of the model and every baseline, error bars = std over folds (and seeds)."""
    plt = _plt()
    classes = group["classes"]
    names = ["model", *next(iter(classes.values()))["baselines"]]
    get = lambda e, n: e if n == "model" else e["baselines"][n]  # noqa: E731
    x, width = np.arange(len(classes)), 0.8 / len(names)
    fig, ax = plt.subplots(figsize=(11, 4))
    for k, n in enumerate(names):
        means = [get(e, n)[metric] for e in classes.values()]
        stds = [get(e, n)[f"{metric}_std"] for e in classes.values()]
        ax.bar(x + (k - (len(names) - 1) / 2) * width, means, width, yerr=stds, capsize=2, label=BASELINE_TITLES.get(n, n))
    ax.set_xticks(x, list(classes), rotation=15)
    ax.set_ylabel(metric)
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def _heatmap(ax, matrix: np.ndarray, rows: list[str], cols: list[str], title: str) -> None:
    im = ax.imshow(matrix, vmin=0, vmax=1, cmap="viridis")
    ax.set_xticks(range(len(cols)), cols, rotation=40, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    for (i, j), v in np.ndenumerate(matrix):
        if np.isfinite(v):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7, color="w" if v < 0.6 else "k")
    ax.set_title(title, fontsize=10)
    return im


def adherence_heatmaps(group: dict, class_names: list[str], path: Path) -> Path:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(15, 6), layout="constrained")
    for ax, key, who in zip(axes, ("adherence_matrix", "adherence_matrix_judge"), ("follower GRU", "independent conv judge"), strict=True):
        im = _heatmap(ax, np.asarray(group[key], float), class_names, class_names, f"judged as the requested class\n({who})")
        ax.set_xlabel("requested (one-hot) label")
        ax.set_ylabel("leader's class")
    fig.colorbar(im, ax=axes, shrink=0.8)
    return _save(fig, path)


def mix_heatmap(group: dict, class_names: list[str], path: Path) -> Path:
    """Cell (i, j): mean probability of class i when classes i and j are both asked for at +1."""
    plt = _plt()
    idx = {c: k for k, c in enumerate(class_names)}
    m = np.full((len(class_names),) * 2, np.nan)
    for r in group["mix_judge"]:
        i, j = idx[r["pair"][0]], idx[r["pair"][1]]
        m[i, j], m[j, i] = r["first"], r["second"]
    fig, ax = plt.subplots(figsize=(7, 6))
    im = _heatmap(ax, m, class_names, class_names, "mix (independent judge): P(row class) when row + column are both +1")
    ax.set_xlabel("mixed with")
    fig.colorbar(im, ax=ax, shrink=0.8)
    fig.tight_layout()
    return _save(fig, path)


def latent_tsne(latents: dict[str, np.ndarray], actions: np.ndarray, class_names: list[str], path: Path, subject: str) -> Path:
    """t-SNE of the encoder's per-sequence embeddings (true labels), one panel per model (the paper's Fig. 7/8)."""
    from sklearn.manifold import TSNE

    plt = _plt()
    fig, axes = plt.subplots(1, len(latents), figsize=(6 * len(latents), 5), squeeze=False)
    for ax, (name, z) in zip(axes[0], latents.items(), strict=True):
        xy = TSNE(n_components=2, perplexity=min(30, len(z) - 1), random_state=0, init="pca").fit_transform(np.asarray(z))
        for c, cname in enumerate(class_names):
            sel = actions == c
            ax.scatter(xy[sel, 0], xy[sel, 1], s=12, label=cname)
        ax.set_title(f"{'IMM model' if name == 'model' else BASELINE_TITLES.get(name, name)} (fold {subject} model)")
        ax.set_xticks([])
        ax.set_yticks([])
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def write_figures(summary: dict, latent: dict | None, actions: np.ndarray, out_dir: Path, progress=print) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    group = summary["groups"]["all"]
    names = summary["class_names"]
    paths = [metric_bars(group, "afd", out_dir / "afd.png", "AFD per class (normalized units), mean ± std over folds"),
             metric_bars(group, "fid", out_dir / "fid.png", "FID per class (interaction-classifier features)"),
             adherence_heatmaps(group, names, out_dir / "adherence.png"),
             mix_heatmap(group, names, out_dir / "mix.png")]
    if latent:
        progress("t-SNE of the latent space ...")
        paths.append(latent_tsne(latent["latents"], actions, names, out_dir / "latent_tsne.png", latent["subject"]))
    return paths
