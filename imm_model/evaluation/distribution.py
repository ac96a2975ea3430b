"""Distribution metrics on classifier features: FID, diversity, recognition accuracy.

Features are the penultimate layer of the fold's interaction classifier (model/classifier.py),
computed for real test interactions (A, B) and generated ones (A, B'), as Action2Motion/ACTOR do.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg


def fid(real: np.ndarray, generated: np.ndarray) -> float:
    """Fréchet distance between Gaussians fitted to two feature sets (N, F) and (M, F); nan with < 2 of either.

    With a handful of sequences per class (SBU LOSO: 2-19) the covariances are rank-deficient and the
    estimate is biased upward; compare methods on the same folds, never with another paper's sample sizes.
    """
    if len(real) < 2 or len(generated) < 2:
        return float("nan")
    mu1, mu2 = real.mean(0), generated.mean(0)
    s1, s2 = np.cov(real, rowvar=False), np.cov(generated, rowvar=False)
    with warnings.catch_warnings():  # singular by construction with fewer sequences than features
        warnings.simplefilter("ignore", linalg.LinAlgWarning)
        covmean = linalg.sqrtm(s1 @ s2)
    if not np.isfinite(covmean).all():  # near-singular product: the usual small-ridge fallback
        eps = np.eye(len(s1)) * 1e-6
        covmean = linalg.sqrtm((s1 + eps) @ (s2 + eps))
    return float(np.sum((mu1 - mu2) ** 2) + np.trace(s1 + s2 - 2.0 * np.real(covmean)))


def diversity(features: np.ndarray, pairs: int = 300, seed: int = 0) -> float:
    """Action2Motion's diversity: mean feature distance between random pairs of distinct sequences."""
    n = len(features)
    if n < 2:
        return float("nan")
    rng = np.random.default_rng(seed)
    a = rng.integers(0, n, pairs)
    b = (a + rng.integers(1, n, pairs)) % n  # never the same sequence
    return float(np.linalg.norm(features[a] - features[b], axis=-1).mean())


def accuracy(probs: np.ndarray, labels: np.ndarray) -> float:
    return float((probs.argmax(-1) == np.asarray(labels)).mean()) if len(labels) else float("nan")
