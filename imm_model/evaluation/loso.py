"""Model vs nearest-neighbour on LOSO folds: per-class AFD (normalized units) and their ratio.

Per fold, each test sequence is synthesized with the one-hot label of its true class; the
per-class AFD is the mean over that class's test sequences. Across folds, per-class numbers are
averaged over the folds (each fold weighted equally, as in the paper's LOSO protocol); the headline
is the mean over classes of the per-class ratio model / NN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.evaluation.baseline import evaluate_predictions, nn_predictions


@dataclass
class FoldResult:
    subject: str
    afd_model: dict[str, float]
    afd_nn: dict[str, float]


def model_predictions(model, data: InteractionDataset, test_idx: np.ndarray) -> dict[int, np.ndarray]:
    """{test index: canonical follower} from a ReactionModel, conditioned on the true class."""
    leaders = [data.canonical(int(i))[0] for i in test_idx]
    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[test_idx]]
    preds = model.synthesize_batch_canonical(leaders, labels)
    return {int(i): p for i, p in zip(test_idx, preds, strict=True)}


def evaluate_fold(model, data: InteractionDataset, subject: str) -> FoldResult:
    if tuple(model.class_names) != tuple(data.class_names):
        raise ValueError(f"checkpoint classes {model.class_names} differ from the data's {data.class_names}")
    fold = loso_fold(data.subject_pairs, subject)
    return FoldResult(subject, evaluate_predictions(data, fold.test, model_predictions(model, data, fold.test)),
                      evaluate_predictions(data, fold.test, nn_predictions(data, fold)))


def summarize(results: list[FoldResult], class_names: tuple[str, ...]) -> dict:
    """Fold-averaged per-class AFD of model and NN, their ratio, and the mean ratio over classes."""
    def avg(key: str) -> dict[str, float]:
        out = {}
        for c in class_names:
            vals = [getattr(r, key)[c] for r in results if c in getattr(r, key)]
            if vals:
                out[c] = float(np.mean(vals))
        return out

    model, nn = avg("afd_model"), avg("afd_nn")
    ratio = {c: model[c] / nn[c] for c in model}
    return {
        "folds": [r.subject for r in results],
        "afd_model": model,
        "afd_nn": nn,
        "ratio": ratio,
        "mean_ratio": float(np.mean(list(ratio.values()))),
        "max_ratio": float(max(ratio.values())),
        "per_fold": {r.subject: {"afd_model": r.afd_model, "afd_nn": r.afd_nn} for r in results},
    }


def markdown_table(summary: dict) -> str:
    lines = ["| class | AFD model | AFD NN | ratio |", "|---|---:|---:|---:|"]
    for c, r in summary["ratio"].items():
        lines.append(f"| {c} | {summary['afd_model'][c]:.3f} | {summary['afd_nn'][c]:.3f} | {r:.3f} |")
    m = lambda d: float(np.mean(list(d.values())))  # noqa: E731
    lines.append(f"| **mean** | {m(summary['afd_model']):.3f} | {m(summary['afd_nn']):.3f} | **{summary['mean_ratio']:.3f}** |")
    return "\n".join(lines)
