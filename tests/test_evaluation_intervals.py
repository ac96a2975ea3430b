"""95 % intervals (evaluation/intervals.py), KID, precision/recall and jitter, and how the summary and the reproduce
models table show them. Every feature set and motion here is synthetic (random numbers from a seeded generator), made
to have a known answer."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from imm_model.evaluation import distribution, intervals
from imm_model.evaluation.plausibility import acceleration_mps2


def _features(n: int = 60, d: int = 8, seed: int = 0) -> np.ndarray:
    """Synthetic features: unit Gaussians."""
    return np.random.default_rng(seed).normal(size=(n, d))


def test_kid_is_about_zero_for_one_distribution_and_grows_with_a_shift():
    x, y = _features(seed=0), _features(seed=1)  # two synthetic samples of the same Gaussian
    assert distribution.kid(x, x) == pytest.approx(0.0, abs=1e-9)  # identical paired sets: every term cancels
    same = distribution.kid(x, y)
    shifted = [distribution.kid(x, y + s) for s in (0.5, 1.0, 2.0)]
    assert abs(same) < 0.1 * shifted[0]
    assert shifted[0] < shifted[1] < shifted[2]
    assert np.isnan(distribution.kid(x[:1], y[:1]))
    assert distribution.kid(x, y[:40], paired=False) < 0.1 * distribution.kid(x, y[:40] + 0.5, paired=False)


def test_kid_matches_the_unbiased_mmd_written_out():
    x, y = _features(20, 4, seed=2), _features(25, 4, seed=3) + 0.3  # synthetic
    k = lambda a, b: (a @ b.T / a.shape[1] + 1) ** 3  # noqa: E731
    kxx, kyy, kxy = k(x, x), k(y, y), k(x, y)
    m, n = len(x), len(y)
    expected = ((kxx.sum() - np.trace(kxx)) / (m * (m - 1)) + (kyy.sum() - np.trace(kyy)) / (n * (n - 1))
                - 2 * kxy.mean())
    assert distribution.kid(x, y, paired=False) == pytest.approx(expected, rel=1e-10)
    y = y[:m]  # paired rows: the cross term leaves out each row's own pair too (Gretton et al.'s U-statistic)
    kyy, kxy = k(y, y), k(x, y)
    paired = ((kxx.sum() - np.trace(kxx)) + (kyy.sum() - np.trace(kyy)) - 2 * (kxy.sum() - np.trace(kxy))) / (m * (m - 1))
    assert distribution.kid(x, y) == pytest.approx(paired, rel=1e-10)


def test_precision_and_recall_are_one_for_identical_sets_and_precision_drops_when_points_move_away():
    x = _features(seed=4)
    assert distribution.precision_recall(x, x) == (1.0, 1.0)
    moved = x.copy()
    moved[:30] += 10.0  # half the synthetic generated points moved far outside the real manifold
    precision, recall = distribution.precision_recall(x, moved)
    assert precision == pytest.approx(0.5)
    assert recall < 1.0  # the real points those left behind are no longer covered
    collapsed = np.repeat(x[:1], len(x), axis=0) + 1e-3 * _features(seed=5)  # every generated point at one real one
    precision, recall = distribution.precision_recall(x, collapsed)
    assert precision == 1.0 and recall < 0.2  # faithful but no coverage: what recall is for
    assert np.isnan(distribution.precision_recall(x[:3], x[:3])[0])  # k = 3 needs more than 3 points


@pytest.mark.parametrize("n, d", [(30, 64), (200, 4)])  # fewer sequences than features (a fold), and more
def test_the_bootstraps_fid_without_a_square_root_equals_fid(n, d):
    real = np.maximum(_features(n, d, seed=10), 0)  # synthetic, ReLU-like as the classifier's features
    generated = np.maximum(_features(n, d, seed=11) + 0.3, 0)
    assert distribution._fid_by_factors(real, generated) == pytest.approx(distribution.fid(real, generated), rel=1e-6)
    assert distribution._fid_by_factors(real, real) == pytest.approx(0.0, abs=1e-9)


def test_a_bootstrap_interval_holds_the_estimate_and_narrows_with_more_sequences():
    rng = np.random.default_rng(6)
    widths = []
    for n in (10, 40, 160):
        values = rng.normal(1.0, 0.3, n)  # synthetic per-sequence figures
        lo, hi = intervals.mean_interval(values)
        assert lo < values.mean() < hi
        widths.append(hi - lo)
    assert widths[0] > widths[1] > widths[2]
    assert widths[0] / widths[2] == pytest.approx(4.0, rel=0.35)  # ~1/sqrt(n)
    values = rng.normal(size=30)
    generic = intervals.bootstrap_interval(lambda idx: values[idx].mean(), len(values))
    assert generic == pytest.approx(intervals.mean_interval(values))  # the same draws: the same interval
    assert intervals.mean_interval(values[:1]) == intervals.NONE


def test_the_distribution_intervals_hold_their_point_estimates():
    real = _features(30, 6, seed=7)
    generated = real + 0.5 + 0.5 * _features(30, 6, seed=8)  # synthetic: a shifted, noisier copy, paired by row
    ci = distribution.distribution_intervals(real, generated)
    precision, recall = distribution.precision_recall(real, generated)
    for key, value in (("fid", distribution.fid(real, generated)), ("kid", distribution.kid(real, generated)),
                       ("precision", precision), ("recall", recall)):
        lo, hi = ci[key]
        assert lo <= value <= hi, key
    assert ci["kid"][0] > 0  # a shift this large: the whole interval is above zero


def test_group_mean_interval_averages_the_groups_means():
    values = np.r_[np.full(20, 1.0), np.full(5, 3.0)]  # synthetic: two groups of constant values
    groups = np.r_[np.zeros(20, int), np.ones(5, int)]
    lo, hi = intervals.group_mean_interval(values, groups)
    assert lo <= 2.0 <= hi and hi <= 3.0  # 2 when both groups are drawn; 1 or 3 only when one is missing
    assert intervals.percentile_interval(np.array([np.nan, np.nan])) == intervals.NONE


def test_the_t_interval_over_seeds_matches_a_hand_computation():
    seeds = [0.80, 0.86, 0.78, 0.83]  # made-up per-seed figures
    mean, sd, n = np.mean(seeds), np.std(seeds, ddof=1), len(seeds)
    half = 3.182446305284263 * sd / np.sqrt(n)  # t_{0.975, 3} from a t table
    assert intervals.t_interval(seeds) == pytest.approx((mean - half, mean + half), rel=1e-9)
    assert stats.t.ppf(0.975, 3) == pytest.approx(3.182446305284263)
    assert intervals.t_interval([0.8]) == intervals.NONE
    assert intervals.pooled([0.8], (0.7, 0.9)) == (0.8, (0.7, 0.9))  # one run: its own bootstrap
    assert intervals.pooled([0.8, np.nan, 0.9], (0.0, 1.0))[1] == pytest.approx(intervals.t_interval([0.8, 0.9]))


def test_intervals_print_beside_the_figure():
    assert intervals.with_interval(0.8061, (0.771, 0.842)) == "0.806 [0.77, 0.84]"
    assert intervals.with_interval(12.345, (10.0, 15.0), 2) == "12.35 [10.0, 15.0]"
    assert intervals.with_interval(0.806, None) == "0.806" and intervals.with_interval(float("nan"), (0, 1)) == "-"


def test_jitter_ratio_is_one_for_real_motion_and_above_one_with_noise(sample_data):
    from imm_model.evaluation.plausibility import frame_rate, plausibility

    idx = range(8)
    leaders = [sample_data.canonical(i)[0] for i in idx]
    reals = [sample_data.canonical(i)[1] for i in idx]
    fps = frame_rate(sample_data.dataset)
    same = plausibility(leaders, reals, reals, sample_data.skeleton, fps)
    assert same["jitter_ratio"] == pytest.approx(1.0) and same["real_jitter_mps2"] > 0
    rng = np.random.default_rng(9)
    noisy = [r + rng.normal(0, 0.01, r.shape) for r in reals]  # synthetic 1 cm jitter on the real followers
    p = plausibility(leaders, noisy, reals, sample_data.skeleton, fps)
    assert p["jitter_ratio"] > 1.5 and p["jitter_mps2"] > same["jitter_mps2"]
    lo, hi = intervals.ratio_interval([acceleration_mps2(m, fps) for m in noisy], [acceleration_mps2(m, fps) for m in reals])
    assert lo <= p["jitter_ratio"] <= hi and lo > 1


def test_acceleration_is_the_second_difference_at_the_frame_rate():
    t = np.arange(10, dtype=np.float64)
    motion = np.zeros((10, 2, 3))
    motion[:, :, 0] = 0.5 * 2.0 * (t[:, None] / 15.0) ** 2  # synthetic: constant 2 m/s² along x at 15 fps
    assert acceleration_mps2(motion, 15.0) == pytest.approx(2.0)
    assert np.isnan(acceleration_mps2(motion[:2], 15.0))


def _fold_result(subject: str, group: str, seed: int, kid: float, intervals_: bool = True) -> dict:
    """A synthetic fold result (the shape evaluate_fold returns, made-up numbers) with the new figures."""
    from tests.test_evaluation_metrics import _fake_fold_result

    r = _fake_fold_result(subject, group, seed, 0.8)
    for scores in (r["model"], *r["baselines"].values()):
        scores |= {"kid": kid, "precision": 0.7, "recall": 0.6}
        scores["plausibility"] = scores["plausibility"] | {"jitter_mps2": 3.0, "real_jitter_mps2": 2.0, "jitter_ratio": 1.5}
        if intervals_:
            scores["intervals"] = {"afd": [0.7, 0.9], "fid": [6.0, 10.0], "kid": [kid - 0.01, kid + 0.01],
                                   "precision": [0.6, 0.8], "recall": [0.5, 0.7], "jitter_ratio": [1.3, 1.7]}
            for c in scores["classes"].values():
                c["afd_ci"] = [0.7, 0.9]
    r |= {"mix_parts": [{"pair": ["a", "b"], "whole": 0.5, "parts": 0.2, "mixed": 0.6}], "adherence_off_diagonal_judge": 0.3}
    r["avoid_judge"]["share_lowered"] = 0.5
    r["model"]["plausibility"] |= {"interior_limb_speed_ratio": 0.9, "lean_error_deg": 3.0}
    return r


def test_the_summary_shows_one_runs_bootstrap_and_several_runs_t_interval():
    from imm_model.evaluation.report import summarize
    from imm_model.evaluation.tables import markdown_report, metric_table, printed_distribution

    one = summarize([_fold_result("s01", "dev", 0, 0.05)], ("a", "b"))
    assert one["model_overall"]["ci"]["kid"] == pytest.approx([0.04, 0.06]) and one["classes"]["a"]["afd_ci"] == [0.7, 0.9]
    assert "| a | 0.800 [0.70, 0.90] |" in metric_table(one, "afd")
    assert "bootstrap over sequences" in printed_distribution(one) and "| model | 0.800 [0.70, 0.90] |" in printed_distribution(one)
    kids = [0.05, 0.07, 0.06]
    many = summarize([_fold_result(s, "test", k, kid) for k, (s, kid) in enumerate(zip(("s02", "s05", "s06"), kids, strict=True))],
                     ("a", "b"))
    assert many["model_overall"]["ci"]["kid"] == pytest.approx(list(intervals.t_interval(kids)))
    assert many["model_overall"]["ci"]["jitter_ratio"] == [1.5, 1.5]  # no spread over runs: a zero-width t-interval
    text = markdown_report(many)
    assert "t over results" in text and "| real followers | | | | | | 2.0 [2.0, 2.0] | 1 |" in text
    old = summarize([_fold_result("s01", "dev", 0, float("nan"), intervals_=False)], ("a", "b"))  # saved before KID
    assert "| a | 0.800 |" in metric_table(old, "afd") and printed_distribution(old) == ""


def test_the_models_table_gives_every_figure_an_interval_dev_and_test_apart():
    from imm_model.reproduce.jobs import TrainJob
    from imm_model.reproduce.report import models_section
    from imm_model.reproduce.tasks import EvalJob

    kids = {"s01": 0.05, "s03": 0.07, "s04": 0.06, "s02": 0.10}
    results = {EvalJob(TrainJob("imm-steer", s, 0), "final", baselines=("nn1",)): _fold_result(s, "dev" if s != "s02" else "test", 0, k)
               for s, k in kids.items()}
    table = models_section(results, ["a", "b"])
    assert "imm-steer, dev folds (3 runs)" in table and "imm-steer, test folds (1 runs)" in table
    row = lambda title: next(line for line in table.splitlines() if line.startswith(f"| {title} |")).split("|")  # noqa: E731
    lo, hi = intervals.t_interval([0.05, 0.07, 0.06])
    assert row("KID")[2].strip() == f"0.060 [{lo:.2f}, {hi:.2f}]"  # dev: t over the three folds
    assert row("KID")[3].strip() == "0.100 [0.09, 0.11]"  # test: one run, its own bootstrap
    assert row("... generated / real")[3].strip() == "1.50 [1.3, 1.7]"
    assert row("precision (k = 3)")[2].strip() == "0.70 [0.7, 0.7]"
