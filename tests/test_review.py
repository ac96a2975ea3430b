"""The review across sequences (imm_model/evaluation/review.py) on the bundled data, models and judge."""

from __future__ import annotations

import numpy as np
import pytest

from imm_model.data.splits import loso_fold
from imm_model.evaluation import review
from imm_model.inference import ReactionModel
from imm_model.model import classifier as classifiers
from imm_model.model import classifier_config as classifier_configs
from imm_model.paths import SAMPLE_DIFFUSION, SAMPLE_GAN, SAMPLE_JUDGE
from imm_model.reads_as import ReadsAs


@pytest.fixture(scope="module")
def gan():
    return ReactionModel.load(SAMPLE_GAN)


@pytest.fixture(scope="module")
def judge():
    return ReadsAs.load(SAMPLE_JUDGE)


@pytest.fixture(scope="module")
def features(sample_data):
    """A small interaction classifier (seconds to train) standing in for the fold's cached one."""
    fold = loso_fold(sample_data.subject_pairs, "s04")
    pairs = [sample_data.canonical(int(i)) for i in fold.train]
    cfg = classifier_configs.ClassifierConfig(inputs="interaction", epochs=2, hidden=16, features=8)
    model = classifiers.train_classifier(cfg, classifiers.motion_inputs(*map(list, zip(*pairs, strict=True)), "interaction"),
                                         sample_data.actions[fold.train], len(sample_data.class_names))
    return review.InteractionFeatures(model)


@pytest.fixture(scope="module")
def rows(gan, sample_data, judge, features):
    return review.review_table(gan, sample_data, judge=judge, features=features)


@pytest.mark.slow
def test_rows_cover_the_held_out_split(rows, gan, sample_data):
    test = loso_fold(sample_data.subject_pairs, gan.held_out_subject).test
    assert sorted(r.index for r in rows) == sorted(int(i) for i in test)
    assert all(np.isfinite(r.afd) and r.afd > 0 and np.isfinite(r.feature_distance) for r in rows)
    assert all(r.reads_as in sample_data.class_names and 0 < r.reads_as_p <= 1 for r in rows)
    # own-class label: the asked probability is that of the sequence's class, at most the top class's
    assert all(0 <= r.asked_p <= r.reads_as_p + 1e-12 for r in rows)


def test_the_review_afd_is_the_evaluations(rows, gan, sample_data):
    from imm_model.evaluation.baselines import sequence_afds
    from imm_model.evaluation.loso import model_predictions

    idx = np.array([r.index for r in rows[:5]])
    expected = sequence_afds(sample_data, model_predictions(gan, sample_data, idx))
    for r in rows[:5]:
        assert r.afd == pytest.approx(expected[r.index], rel=1e-5)


def test_feature_distance_of_the_real_follower_is_zero(sample_data, features):
    idx = np.flatnonzero(sample_data.held_out)[:6]
    leaders, reals = zip(*(sample_data.canonical(int(i)) for i in idx), strict=True)
    d = review.feature_distances(features, list(leaders), list(reals), list(reals), sample_data.actions[idx])
    np.testing.assert_allclose(d, 0.0, atol=1e-9)


def test_sorting_is_monotone_and_next_worst_walks_the_order(rows):
    for key in review.SORT_KEYS:
        ordered = review.sort_rows(rows, key)
        values = np.array([float(getattr(r, key)) for r in ordered])
        finite = values[~np.isnan(values)]
        steps = np.diff(finite)
        assert (steps >= 0).all() if key in review.LOWER_IS_WORSE else (steps <= 0).all()
    ordered = review.sort_rows(rows, "afd")
    walked, current = [], None
    while (row := review.next_worst(rows, current, "afd")) is not None:
        walked.append(row.index)
        current = row.index
        assert len(walked) <= len(rows)
    assert walked == [r.index for r in ordered]
    assert review.next_worst(rows, ordered[-1].index, "afd") is None
    assert review.next_worst([], None) is None
    with pytest.raises(ValueError, match="unknown sort key 'speed'"):
        review.sort_rows(rows, "speed")


def test_flags_are_booleans_consistent_with_their_thresholds(rows, sample_data):
    threshold = review.real_foot_threshold(sample_data)
    for r in rows:
        assert type(r.contact_flag) is bool and type(r.foot_flag) is bool
        assert r.foot_flag == (r.foot_skate_mps > threshold)
        assert r.contact_flag == (r.contact_reason != "")
        if r.contact_reason == "interpenetrates":
            assert r.interpenetration > r.real_interpenetration + review.PENETRATION_EXCESS
        elif r.contact_reason == "never reaches":
            assert r.real_closest_m < review.PENETRATION_M and r.closest_m > review.REACH_M
        else:
            assert r.interpenetration <= r.real_interpenetration + review.PENETRATION_EXCESS
        assert r.flags == int(r.contact_flag) + int(r.foot_flag)


def test_a_strict_threshold_flags_every_foot(gan, sample_data):
    idx = np.flatnonzero(sample_data.held_out)[:4]
    rows = review.review_table(gan, sample_data, idx, thresholds=review.ReviewThresholds(foot_skate_mps=-1.0))
    assert all(r.foot_flag for r in rows) and all(r.reads_as == "" and np.isnan(r.feature_distance) for r in rows)


def test_a_given_label_is_every_rows_and_a_wrong_length_is_one_line(gan, sample_data, judge):
    idx = np.flatnonzero(sample_data.held_out)[:4]
    hug = np.eye(6)[sample_data.class_names.index("hugging")]
    rows = review.review_table(gan, sample_data, idx, judge=judge, label=hug)
    direct = judge.probabilities(gan.synthesize_canonical(sample_data.canonical(int(idx[0]))[0], hug))
    assert rows[0].asked_p == pytest.approx(float(direct[sample_data.class_names.index("hugging")]), abs=1e-4)
    for bad in ([1.0, 0.0], np.zeros((2, 6)), "hugging", [np.nan] * 6):
        with pytest.raises(ValueError) as err:
            review.review_table(gan, sample_data, idx, label=bad)
        assert "\n" not in str(err.value)


def test_diffusion_rows_are_deterministic_given_a_seed(sample_data, judge, features):
    model = ReactionModel.load(SAMPLE_DIFFUSION)
    idx = np.flatnonzero(sample_data.held_out)[:3]
    first, again = (review.review_table(model, sample_data, idx, judge=judge, features=features, seed=3)
                     for _ in range(2))
    other = review.review_table(model, sample_data, idx, judge=judge, seed=4)
    assert [r.to_dict() for r in first] == [r.to_dict() for r in again]
    assert [r.afd for r in first] != [r.afd for r in other]
