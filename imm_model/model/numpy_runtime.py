"""The judge's conv reaction classifier on one sequence with numpy alone (model/classifier.py's numbers).

Why: the studio reads every synthesized reaction with it, and `import torch` took 2.0-2.2 s of its 3.7 s start here;
numpy was already loaded. Weights are the torch module's state dict as float32 numpy arrays, under the same names.
"""

from __future__ import annotations

import numpy as np


def linear(x: np.ndarray, weights: dict[str, np.ndarray], prefix: str) -> np.ndarray:
    y = x @ weights[prefix + ".weight"].T
    return y + weights[prefix + ".bias"] if prefix + ".bias" in weights else y


class NumpyConvClassifier:
    """model.classifier.MotionClassifier with arch="conv", for one sequence: (T, D) -> (C,) class probabilities."""

    def __init__(self, weights: dict[str, np.ndarray]):
        self.w = {k: np.asarray(v, np.float32) for k, v in weights.items()}

    @staticmethod
    def expected_shapes(hidden: int, features: int, pose_dim: int, num_classes: int) -> dict[str, tuple[int, ...]]:
        """The shapes of MotionClassifier(arch="conv")'s state dict (kernel 5)."""
        d = 2 * pose_dim
        return {"mean": (d,), "std": (d,), "body.0.weight": (hidden, d, 5), "body.0.bias": (hidden,),
                "body.1.weight": (hidden, hidden, 5), "body.1.bias": (hidden,), "embed.1.weight": (features, hidden),
                "embed.1.bias": (features,), "head.weight": (num_classes, features), "head.bias": (num_classes,)}

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        w = self.w
        x = np.asarray(x, np.float32)
        h = (np.concatenate([x, np.diff(x, axis=0, prepend=x[:1])], 1) - w["mean"]) / w["std"]
        for layer in ("body.0", "body.1"):
            kernel = w[layer + ".weight"]  # (out, in, K), zero padding K // 2 on both sides (as trained)
            pad = kernel.shape[2] // 2
            windows = np.lib.stride_tricks.sliding_window_view(np.pad(h, ((pad, pad), (0, 0))), kernel.shape[2], axis=0)
            h = np.maximum(np.einsum("tik,oik->to", windows, kernel, optimize=True) + w[layer + ".bias"], 0.0)
        logits = linear(np.maximum(linear(h.mean(0), w, "embed.1"), 0.0), w, "head")
        p = np.exp(logits - logits.max())
        return (p / p.sum()).astype(np.float64)
