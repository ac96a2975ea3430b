"""95 % intervals for every reported figure: one rule for `imm evaluate` and the reproduce tables.

- Within one run (one model on one fold): a percentile bootstrap over the evaluated sequences. The sequences are
  resampled with replacement RESAMPLES times with a fixed generator seed, the figure is recomputed on each resample
  (features and per-sequence values are computed once; only the statistic is recomputed), and the interval is the
  2.5th and 97.5th percentile of the resampled figures.
- Across runs (several seeds of one recipe, or per-fold figures pooled): mean ± t_{0.975, n-1} · sd / √n over the
  runs' figures (sd with n - 1), the spread over seeds and folds. One run has no such interval; its bootstrap stands in.

Intervals are (low, high) pairs of floats, (nan, nan) where there is none.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence

import numpy as np

LEVEL = 0.95
RESAMPLES = 1000
SEED = 0  # every bootstrap draws the same resamples: reruns and methods on the same sequences get the same draws
NONE = (float("nan"), float("nan"))


def bootstrap_indices(n: int, resamples: int = RESAMPLES, seed: int = SEED) -> np.ndarray:
    """(resamples, n) sequence indices drawn with replacement."""
    return np.random.default_rng(seed).integers(0, n, size=(resamples, n))


def bootstrap_interval(statistic: Callable[[np.ndarray], float], n: int, resamples: int = RESAMPLES, seed: int = SEED,
                       level: float = LEVEL) -> tuple[float, float]:
    """Percentile interval of `statistic(indices)` over resampled sequence indices; NONE with fewer than 2 sequences
    or when no resample gives a finite figure (a resample may lack a class, or have too few sequences for a FID)."""
    if n < 2:
        return NONE
    values = np.array([statistic(idx) for idx in bootstrap_indices(n, resamples, seed)], dtype=np.float64)
    return percentile_interval(values, level)


def percentile_interval(values: np.ndarray, level: float = LEVEL) -> tuple[float, float]:
    values = values[np.isfinite(values)]
    if not len(values):
        return NONE
    tail = 100 * (1 - level) / 2
    lo, hi = np.percentile(values, [tail, 100 - tail])
    return float(lo), float(hi)


def mean_interval(values: Sequence[float], resamples: int = RESAMPLES, seed: int = SEED, level: float = LEVEL) -> tuple[float, float]:
    """Bootstrap interval of the mean of per-sequence values (vectorized: one draw matrix, no Python loop)."""
    v = np.asarray(values, dtype=np.float64)
    if len(v) < 2:
        return NONE
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # as ratio_interval
        return percentile_interval(np.nanmean(v[bootstrap_indices(len(v), resamples, seed)], axis=1), level)


def ratio_interval(numerator: Sequence[float], denominator: Sequence[float], resamples: int = RESAMPLES, seed: int = SEED,
                   level: float = LEVEL) -> tuple[float, float]:
    """Bootstrap interval of mean(numerator) / mean(denominator), both per sequence and resampled together (nan
    entries left out of their mean, as plausibility's means leave out sequences too short to score)."""
    a, b = np.asarray(numerator, np.float64), np.asarray(denominator, np.float64)
    if len(a) < 2:
        return NONE
    idx = bootstrap_indices(len(a), resamples, seed)
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a resample of nothing but too-short sequences: nan, left out
        return percentile_interval(np.nanmean(a[idx], 1) / np.nanmean(b[idx], 1), level)


def group_mean_interval(values: Sequence[float], groups: Sequence[int], resamples: int = RESAMPLES, seed: int = SEED,
                        level: float = LEVEL) -> tuple[float, float]:
    """Bootstrap interval of the mean over groups of each group's mean (the tables' AFD: the mean over classes of the
    per-class means); a group missing from a resample is left out of that resample's mean."""
    v, g = np.asarray(values, np.float64), np.asarray(groups)
    if len(v) < 2:
        return NONE
    idx = bootstrap_indices(len(v), resamples, seed)
    onehot = (g[:, None] == np.unique(g)[None, :]).astype(np.float64)  # (n, G)
    counts = onehot[idx].sum(1)  # (R, G)
    sums = (v[idx][..., None] * onehot[idx]).sum(1)
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        means = np.nanmean(np.where(counts > 0, sums / counts, np.nan), axis=1)
    return percentile_interval(means, level)


def t_interval(values: Sequence[float], level: float = LEVEL) -> tuple[float, float]:
    """mean ± t_{(1+level)/2, n-1} · sd / √n over runs' figures (non-finite ones left out); NONE with fewer than 2."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=np.float64)
    if len(v) < 2:
        return NONE
    from scipy import stats  # here: scipy.stats costs ~1 s to import, and most callers never pool runs

    half = stats.t.ppf((1 + level) / 2, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v))
    return float(v.mean() - half), float(v.mean() + half)


def pooled(values: Sequence[float], single: Sequence[float] | None = None) -> tuple[float, tuple[float, float]]:
    """(mean, interval) of one figure over runs: the t-interval over runs with two or more, else the one run's own
    bootstrap interval (`single`, or NONE when the run has none)."""
    v = [x for x in values if x is not None and np.isfinite(x)]
    if not v:
        return float("nan"), NONE
    if len(v) >= 2:
        return float(np.mean(v)), t_interval(v)
    return float(v[0]), as_interval(single)


def as_interval(value) -> tuple[float, float]:
    """A stored interval (a 2-list in JSON, or None / missing in results recorded before intervals) as a pair."""
    if value is None or len(value) != 2:
        return NONE
    return float(value[0]), float(value[1])


def with_interval(mean: float | None, interval=None, digits: int = 3) -> str:
    """`0.806 [0.77, 0.84]`: the figure, then its 95 % interval one digit shorter; the figure alone without one."""
    if mean is None or not np.isfinite(mean):
        return "-"
    lo, hi = as_interval(interval)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{mean:.{digits}f}"
    d = max(digits - 1, 1)
    return f"{mean:.{digits}f} [{lo:.{d}f}, {hi:.{d}f}]"
