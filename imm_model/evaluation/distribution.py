"""Distribution metrics on classifier features: FID, KID, precision and recall, diversity, recognition accuracy.

Features are the penultimate layer of the fold's interaction classifier (model/classifier.py),
computed for real test interactions (A, B) and generated ones (A, B'), as Action2Motion/ACTOR do.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import linalg

from imm_model.evaluation import intervals


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


def _fid_by_factors(real: np.ndarray, generated: np.ndarray) -> float:
    """fid() without a matrix square root, for the bootstrap's many resamples: with each covariance written as
    S = F Fᵀ (F the centred features / √(n - 1)), tr √(S1 S2) is the nuclear norm of F1ᵀ F2, the sum of the singular
    values of an (N, M) matrix (Ns of ~30 here, against a 64 x 64 sqrtm). Equal to fid() up to rounding (tested)."""
    if len(real) < 2 or len(generated) < 2:
        return float("nan")
    a, b = real - real.mean(0), generated - generated.mean(0)
    na, nb = len(a) - 1, len(b) - 1
    cross = np.linalg.svd(a @ b.T, compute_uv=False).sum() / np.sqrt(na * nb)
    return float(np.sum((real.mean(0) - generated.mean(0)) ** 2) + (a * a).sum() / na + (b * b).sum() / nb - 2.0 * cross)


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


KID_DEGREE = 3
PR_NEIGHBOURS = 3  # k of the k-NN manifolds: small, because a test fold holds ~30 sequences (2-19 per class)


def _poly_kernel(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Binkowski et al.'s kernel k(x, y) = (x·y / d + 1)^3, d the feature width."""
    return (x @ y.T / x.shape[1] + 1.0) ** KID_DEGREE


def _mmd2_unbiased(kxx: np.ndarray, kyy: np.ndarray, kxy: np.ndarray, same: np.ndarray | None = None,
                   paired: bool = True) -> float:
    """Unbiased MMD² from kernel matrices. Within a set, a pair counts unless `same` marks it as one sequence with itself
    (the diagonal, and in a bootstrap resample also a sequence drawn twice). `paired` (equal sets, row i of each from
    the same sequence): the cross term leaves out each sequence's own pair too, Gretton et al. 2012's U-statistic,
    unbiased although a sequence's real and generated followers share a leader; else every cross pair counts."""
    same_x = np.eye(len(kxx), dtype=bool) if same is None else same
    same_y = np.eye(len(kyy), dtype=bool) if same is None else same
    if (~same_x).sum() == 0 or (~same_y).sum() == 0:
        return float("nan")
    cross = kxy[~same_x].mean() if paired else kxy.mean()
    return float(kxx[~same_x].mean() + kyy[~same_y].mean() - 2.0 * cross)


def kid(real: np.ndarray, generated: np.ndarray, paired: bool = True) -> float:
    """Kernel inception distance (Binkowski et al. 2018): the unbiased MMD² between the two feature sets under the cubic
    polynomial kernel, in one block (a fold has far fewer sequences than the paper's 1000-sample subsets). `paired`:
    row i of each set comes from one test sequence (one leader), as in the evaluation; then identical sets score
    exactly 0. Unbiased, so two samples of one distribution score ~0, possibly slightly negative; nan with < 2 of either."""
    if len(real) < 2 or len(generated) < 2:
        return float("nan")
    if paired and len(real) != len(generated):
        raise ValueError(f"paired features expected, got {len(real)} real and {len(generated)} generated")
    real, generated = np.asarray(real, np.float64), np.asarray(generated, np.float64)
    return _mmd2_unbiased(_poly_kernel(real, real), _poly_kernel(generated, generated), _poly_kernel(real, generated),
                          paired=paired)


def _kth_radius(features: np.ndarray, k: int) -> np.ndarray:
    """Each point's distance to its k-th nearest other point of the set."""
    from scipy.spatial.distance import cdist

    d = cdist(features, features)
    np.fill_diagonal(d, np.inf)
    return np.partition(d, k - 1, axis=1)[:, k - 1]


def manifold_membership(real: np.ndarray, generated: np.ndarray, k: int = PR_NEIGHBOURS) -> tuple[np.ndarray, np.ndarray]:
    """(is each generated point inside the real manifold (M,), is each real point inside the generated one (N,)): a
    set's manifold is the union of balls around its points, each with the radius to its k-th nearest neighbour in the
    set (Kynkäänniemi et al. 2019). Empty arrays with k or fewer points in either set."""
    from scipy.spatial.distance import cdist

    real, generated = np.asarray(real, np.float64), np.asarray(generated, np.float64)
    if len(real) <= k or len(generated) <= k:
        return np.zeros(0, bool), np.zeros(0, bool)
    d = cdist(generated, real)  # (M, N)
    in_real = (d <= _kth_radius(real, k)[None, :]).any(axis=1)
    in_generated = (d <= _kth_radius(generated, k)[:, None]).any(axis=0)
    return in_real, in_generated


def precision_recall(real: np.ndarray, generated: np.ndarray, k: int = PR_NEIGHBOURS) -> tuple[float, float]:
    """Improved precision (share of generated points inside the real manifold: fidelity) and recall (share of real
    points inside the generated manifold: coverage), Kynkäänniemi et al. 2019; nan with k or fewer points."""
    in_real, in_generated = manifold_membership(real, generated, k)
    if not len(in_real):
        return float("nan"), float("nan")
    return float(in_real.mean()), float(in_generated.mean())


def distribution_intervals(real: np.ndarray, generated: np.ndarray, k: int = PR_NEIGHBOURS) -> dict[str, tuple[float, float]]:
    """95 % bootstrap intervals (evaluation/intervals.py) of FID, KID, precision and recall over the sequences: real and
    generated features are paired by sequence (the same leader), so one index draw resamples both. Kernel matrices and
    manifold memberships are computed once; a resample reads them at its indices (KID leaves out every pair of a
    sequence drawn twice with itself, as it leaves out the diagonal). Precision and recall keep the full sample's
    manifolds and resample which sequences are scored."""
    real, generated = np.asarray(real, np.float64), np.asarray(generated, np.float64)
    n = len(real)
    if len(generated) != n:
        raise ValueError(f"paired features expected, got {n} real and {len(generated)} generated")
    kxx, kyy, kxy = _poly_kernel(real, real), _poly_kernel(generated, generated), _poly_kernel(real, generated)

    def kid_at(idx: np.ndarray) -> float:
        return _mmd2_unbiased(kxx[np.ix_(idx, idx)], kyy[np.ix_(idx, idx)], kxy[np.ix_(idx, idx)], idx[:, None] == idx[None, :])

    in_real, in_generated = manifold_membership(real, generated, k)
    out = {"fid": intervals.bootstrap_interval(lambda idx: _fid_by_factors(real[idx], generated[idx]), n),
           "kid": intervals.bootstrap_interval(kid_at, n)}
    if len(in_real):
        out["precision"] = intervals.mean_interval(in_real)
        out["recall"] = intervals.mean_interval(in_generated)
    else:
        out["precision"] = out["recall"] = intervals.NONE
    return out
