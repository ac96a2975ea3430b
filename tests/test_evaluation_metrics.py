"""Evaluation building blocks: classifiers, cache, baselines, FID/diversity, label control, plausibility."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model import cache
from imm_model.contact import segment_distances
from imm_model.data.splits import loso_fold
from imm_model.evaluation import control, distribution, intervals, plausibility
from imm_model.evaluation.baselines import knn_dtw_follower, template_follower
from imm_model.model import classifier as classifiers
from imm_model.model import classifier_config as classifier_configs

QUICK = dict(epochs=2, hidden=16, features=8)


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("IMM_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_classifier_result_does_not_depend_on_its_batch(sample_data):
    """Packed GRU / masked conv: a sequence classified alone or padded in a batch gives the same numbers."""
    fold = loso_fold(sample_data.subject_pairs, "s04")
    followers = [sample_data.canonical(int(i))[1] for i in fold.train]
    seqs = classifiers.motion_inputs([], followers, "follower")
    short = int(np.argmin(sample_data.lengths[fold.train]))
    for arch in classifier_configs.ARCHITECTURES:
        cfg = classifier_configs.ClassifierConfig(inputs="follower", arch=arch, **QUICK)
        model = classifiers.train_classifier(cfg, seqs, sample_data.actions[fold.train], 6)
        alone_p, alone_f = classifiers.classify(model, [seqs[short]])
        batch_p, batch_f = classifiers.classify(model, seqs)
        np.testing.assert_allclose(batch_p[short], alone_p[0], atol=1e-5)
        np.testing.assert_allclose(batch_f[short], alone_f[0], atol=1e-5)
        assert batch_p.shape == (len(seqs), 6) and batch_f.shape == (len(seqs), 8)
        np.testing.assert_allclose(batch_p.sum(1), 1.0, atol=1e-6)


def test_a_start_centred_classifier_reads_motion_not_where_the_body_starts(sample_data):
    """start_centred: a follower shifted sideways or forwards reads the same; raised off the floor, it does not."""
    from imm_model.model.classifier import MotionClassifier

    torch.manual_seed(0)
    x = torch.as_tensor(sample_data.canonical(0)[1].reshape(1, -1, 45))
    lengths = torch.tensor([x.shape[1]])
    shifted = lambda d: (x.unflatten(-1, (-1, 3)) + torch.tensor(d)).flatten(-2)  # noqa: E731
    for centred in (True, False):
        model = MotionClassifier(classifier_configs.ClassifierConfig(inputs="follower", start_centred=centred), 45, 6).eval()
        same = torch.allclose(model(x, lengths), model(shifted([0.4, 0.0, -0.3]), lengths), atol=1e-5)
        assert same == centred
        assert not torch.allclose(model(x, lengths), model(shifted([0.0, 0.3, 0.0]), lengths), atol=1e-5)
    assert "start_centred" not in classifier_configs.ClassifierConfig().to_dict()  # off: older cache keys hold


def test_classifier_config_errors_name_the_field():
    with pytest.raises(ValueError, match="classifier config: arch must be one of"):
        classifier_configs.ClassifierConfig(arch="transformer")
    with pytest.raises(ValueError, match="unknown classifier config keys"):
        classifier_configs.ClassifierConfig.from_dict({"layers": 3})
    with pytest.raises(ValueError, match="start_centred must be false for interaction inputs"):
        classifier_configs.ClassifierConfig(inputs="interaction", start_centred=True)


def test_cache_reuses_and_rebuilds_a_corrupt_entry(sample_data, cache_dir, capsys):
    cfg = classifier_configs.ClassifierConfig(inputs="follower", arch="conv", **QUICK)
    first = cache.fold_classifier(cfg, sample_data, "s04", progress=False)
    assert "trained the follower-only conv classifier for fold s04" in capsys.readouterr().err
    files = list((cache_dir / "classifiers").glob("*.safetensors"))
    assert len(files) == 1
    again = cache.fold_classifier(cfg, sample_data, "s04", progress=False)
    assert capsys.readouterr().err == ""  # reused, not retrained
    for k, v in first.state_dict().items():
        assert np.array_equal(v.numpy(), again.state_dict()[k].numpy())
    files[0].write_bytes(b"\0garbage" * 10)
    rebuilt = cache.fold_classifier(cfg, sample_data, "s04", progress=False)
    err = capsys.readouterr().err
    assert "not a readable safetensors checkpoint" in err and "rebuilding" in err
    assert np.array_equal(rebuilt.head.weight.detach().numpy(), first.head.weight.detach().numpy())  # deterministic
    other = cache.fold_classifier(replace(cfg, seed=3), sample_data, "s04", progress=False)  # another key
    assert len(list((cache_dir / "classifiers").glob("*.safetensors"))) == 2
    assert not np.array_equal(other.head.weight.detach().numpy(), first.head.weight.detach().numpy())


def test_dtw_baseline_retrieves_an_identical_leader_and_places_it(sample_data):
    """A training copy of the test leader is its DTW nearest neighbour; its follower comes back unchanged."""
    others = [j for j in range(len(sample_data)) if sample_data.actions[j] == sample_data.actions[5] and j != 5][:4]
    data = sample_data.subset([5, 5, *others])  # index 1 is a copy of index 0
    pred = knn_dtw_follower(data, np.arange(1, len(data)), 0, k=1)
    np.testing.assert_allclose(pred, data.canonical(1)[1], atol=1e-5)
    avg = knn_dtw_follower(data, np.arange(1, len(data)), 0, k=3)
    assert avg.shape == data.canonical(0)[1].shape and np.isfinite(avg).all()


def test_template_baseline_ignores_the_leader(sample_data):
    fold = loso_fold(sample_data.subject_pairs, "s04")
    same = [int(i) for i in fold.test if sample_data.actions[i] == 0]
    a, b = same[0], next(j for j in same[1:] if sample_data.lengths[j] == sample_data.lengths[same[0]]) if any(
        sample_data.lengths[j] == sample_data.lengths[same[0]] for j in same[1:]) else (same[0], same[0])
    np.testing.assert_array_equal(template_follower(sample_data, fold.train, a), template_follower(sample_data, fold.train, b))


def test_fid_and_diversity():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(200, 4))
    assert abs(distribution.fid(x, x)) < 1e-8
    shift = np.array([3.0, 0, 0, 0])
    assert distribution.fid(x, x + shift) == pytest.approx(9.0, rel=1e-6)
    assert distribution.fid(x, x * 2) > 1.0
    assert np.isnan(distribution.fid(x[:1], x))
    assert distribution.diversity(x) == pytest.approx(np.sqrt(2 * 4), rel=0.15)  # E|x - y| for unit Gaussians
    assert distribution.diversity(np.zeros((5, 3))) == 0.0


def test_label_control_with_known_judges():
    leader_classes = np.array([0, 1, 2, 2, 3])
    obeys = lambda labels: np.eye(4)[np.argmax(labels, -1)]  # noqa: E731  reads the label exactly
    ignores = lambda labels: np.eye(4)[leader_classes]  # noqa: E731  reacts to the leader only
    matrix, per_target = control.adherence_matrix(obeys, leader_classes, 4)
    assert control.off_diagonal_mean(matrix) == 1.0 and per_target.tolist() == [1, 1, 1, 1]
    matrix, per_target = control.adherence_matrix(ignores, leader_classes, 4)
    assert control.off_diagonal_mean(matrix) == 0.0 and np.allclose(np.diag(matrix), 1.0)
    blend = lambda labels: np.maximum(labels, 0) / np.maximum(labels, 0).sum(-1, keepdims=True).clip(1e-9) * 0.8 + 0.05  # noqa: E731
    rows = control.mix_table(blend, 5, ("a", "b", "c", "d"))
    assert len(rows) == 6 and all(r["mass"] == pytest.approx(0.9) and r["both_top2"] == 1.0 for r in rows)
    assert all(r["both_read"] == 1.0 for r in rows)  # 0.45 on each member for every leader
    one_side = lambda labels: np.eye(4)[np.argmax(labels, -1) + np.arange(len(labels)) % 2]  # noqa: E731  one member per leader
    ab = control.mix_table(one_side, 4, ("a", "b", "c", "d"))[0]
    assert ab["first"] == ab["second"] == 0.5 and ab["both_read"] == 0.0  # the means pass, no leader's reaction reads as both
    avoid = control.avoid_effect(lambda labels: np.full((len(labels), 4), 0.25) - labels * 0.2, leader_classes, 4)
    assert avoid["change"] == pytest.approx(0.2)  # this judge raises the avoided class: "avoid" failed, and it shows


def test_part_tables_with_known_judges():
    """Synthetic judges: one reads each part's label exactly, one reads the upper label on both parts."""
    c, names = 3, ("a", "b", "c")
    leader_classes = np.array([0, 1, 2, 2])
    upper_reads = lambda labels: np.eye(c)[np.argmax(labels[:, :c], -1)]  # noqa: E731
    lower_reads = lambda labels: np.eye(c)[np.argmax(labels[:, -c:], -1)]  # noqa: E731  (the lower part, or the whole body)
    half_real = lambda a, b: np.arange(4) % 2 == 0  # noqa: E731  real composites read so for half the leaders
    rows = control.part_pair_table(upper_reads, lower_reads, half_real, 4, names)
    assert len(rows) == 6 and {(r["upper"], r["lower"]) for r in rows} == {(x, y) for x in names for y in names if x != y}
    assert all(r["read"] == 1.0 and r["real"] == 0.5 for r in rows)
    rows = control.part_pair_table(upper_reads, upper_reads, half_real, 4, names)  # the legs follow the arms: never a pair
    assert all(r["read"] == 0.0 for r in rows)
    held_out = np.full((c, c), 0.25)  # composites of held-out followers: the reference, beside the nearest training ones
    rows = control.part_pair_table(upper_reads, lower_reads, half_real, 4, names, held_out)
    assert all(r["real"] == 0.25 and r["real_nearest_training"] == 0.5 for r in rows)
    real_upper = np.eye(c)[leader_classes]  # the real followers read as their own class on both parts ...
    real_lower = np.eye(c)[[1, 0, 2, 2]]  # ... but for the lower judge, the first two swapped
    realism = control.part_realism(upper_reads, lower_reads, leader_classes, real_upper, real_lower, names)
    assert len(realism) == 2 * c and all(r["own"] == 1.0 and r["all"] == 1.0 for r in realism)
    by = {(r["class"], r["part"]): r["real"] for r in realism}
    assert by[("a", "upper")] == 1.0 and by[("a", "lower")] == 0.0 and by[("c", "lower")] == 1.0
    lowering = lambda labels: np.full((len(labels), c), 0.5) + 0.2 * labels[:, c:]  # noqa: E731  reads the lower label
    avoid = control.part_avoid_effect({"upper": lowering, "lower": lowering}, leader_classes, c)
    assert avoid["lower"]["share_lowered"] == 1.0 and avoid["lower"]["change"] == pytest.approx(-0.2)
    assert avoid["upper"]["share_lowered"] == 0.0  # -1 on the upper part: this judge does not move


def test_segment_distance_matches_brute_force():
    rng = np.random.default_rng(1)
    s = np.linspace(0, 1, 301)[:, None]
    for _ in range(100):
        p0, p1, q0, q1 = rng.normal(size=(4, 3))
        brute = np.linalg.norm((p0 + s * (p1 - p0))[:, None] - (q0 + s * (q1 - q0))[None], axis=-1).min()
        assert segment_distances(p0, p1, q0, q1) == pytest.approx(brute, abs=2e-2)


def test_plausibility_of_real_motion_and_of_a_frozen_pose(sample_data):
    sk = sample_data.skeleton
    leaders, reals = zip(*(sample_data.canonical(i) for i in range(10)), strict=True)
    real = plausibility.plausibility(list(leaders), list(reals), list(reals), sk, 15.0)
    assert real["bone_error_cm"] == real["real_bone_error_cm"]
    assert 0.9 < real["speed_ratio"] < 1.5  # unsmoothed real vs smoothed real
    frozen = [np.repeat(r[:1], len(r), 0) for r in reals]
    still = plausibility.plausibility(list(leaders), frozen, list(reals), sk, 15.0)
    assert still["speed_ratio"] == 0.0 and still["foot_skate_mps"] == 0.0
    inside = [a.copy() for a in leaders]  # B standing inside A
    assert plausibility.plausibility(list(leaders), inside, list(reals), sk, 15.0)["interpenetration"] == 1.0
    far = [r + np.array([5.0, 0, 0]) for r in reals]
    assert plausibility.plausibility(list(leaders), far, list(reals), sk, 15.0)["interpenetration"] == 0.0


def test_foot_skate_counts_a_foot_sliding_on_the_floor_not_one_stepping_off_it(sample_data):
    """Synthetic feet on a real follower's frame: a foot that slides along the floor skates; one that lifts off while
    it moves forward does not (the lift-off step has the foot on the floor at one end only)."""
    sk = sample_data.skeleton
    up, feet = sk.vertical_axis, [sk.joint_names.index(n) for n in ("left_foot", "right_foot")]
    body = np.repeat(sample_data.canonical(0)[1][:1].astype(np.float64), 10, 0)
    body[:, feet, up] = 0.0
    sliding, stepping = body.copy(), body.copy()
    forward = [a for a in range(3) if a != up][0]
    sliding[:, feet[0], forward] += 0.02 * np.arange(10)  # 0.3 m/s along the floor, every step
    stepping[5:, feet[0], up] = 0.2  # lifted on frame 5, having moved forward on the same step
    stepping[5:, feet[0], forward] += 0.1
    assert plausibility.foot_skate_mps(sliding, sk, 15.0) == pytest.approx(0.15)  # one foot of two slides
    assert plausibility.foot_skate_mps(stepping, sk, 15.0) == 0.0


def test_a_swaying_root_counts_as_limb_motion_from_the_root_only(sample_data):
    """A frozen pose whose root joint alone swings back and forth inside the body: every joint moves relative to the
    root (limb_speed_ratio > 0), none relative to the centre of the root's neighbours (body_limb_speed_ratio is the
    root's own share alone), and root_sway_mps is the swing's speed."""
    sk = sample_data.skeleton
    assert [sk.joint_names[j] for j in sk.root_neighbours] == ["neck", "left_hip", "right_hip"]
    leaders, reals = zip(*(sample_data.canonical(i) for i in range(10)), strict=True)
    swaying = []
    for r in reals:
        still = np.repeat(r[:1].astype(np.float64), len(r), 0)
        still[:, sk.root, 0] += 0.05 * np.sin(np.arange(len(r)) * 0.5)  # synthetic: 5 cm swing at 15 fps
        swaying.append(still)
    p = plausibility.plausibility(list(leaders), swaying, list(reals), sk, 15.0)
    assert p["limb_speed_ratio"] > 0.5  # the swing moves 14 of 15 joints relative to the root
    assert p["body_limb_speed_ratio"] < p["limb_speed_ratio"] / 10  # only the root itself moves in the body frame
    # 5 cm x 0.5 rad/frame x 15 fps x mean |cos| (2 / pi), against the real followers' own (smoothed) sway
    assert p["root_sway_mps"] == pytest.approx(0.05 * 0.5 * 15 * 2 / np.pi, rel=0.05)
    assert p["root_sway_mps"] > 3 * p["real_root_sway_mps"]


def test_interior_limb_speed_leaves_out_motion_in_the_first_and_last_frames(sample_data):
    """A follower that moves like the real one only in its first and last three frames and stands still in between:
    its limb speed over all frames is a good part of the real one's, over the interior frames nothing."""
    sk = sample_data.skeleton
    leaders, reals = zip(*(sample_data.canonical(i) for i in range(10)), strict=True)
    edges_only = []
    for r in reals:
        x = np.asarray(r, np.float64).copy()
        x[3:-3] = x[3]  # synthetic: the interior frozen
        x[-3:] += x[3] - x[-4]  # the last frames continue from the frozen pose, with their own real motion
        edges_only.append(x)
    p = plausibility.plausibility(list(leaders), edges_only, list(reals), sk, 15.0)
    assert p["body_limb_speed_ratio"] > 0.1 and p["interior_limb_speed_ratio"] == 0.0
    real = plausibility.plausibility(list(leaders), list(reals), list(reals), sk, 15.0)
    assert 0.8 < real["interior_limb_speed_ratio"] < 1.6  # unsmoothed real against smoothed real
    assert np.isnan(plausibility.mean_speed(reals[0][:5], 15.0, edge=3))  # no interior frames at all


def test_afd_parts_split_where_the_follower_stands_from_how_its_limbs_move(sample_data):
    from imm_model.evaluation.metrics import afd_parts

    real = sample_data.canonical(0)[1]
    root = sample_data.skeleton.root
    assert afd_parts(real, real, root) == {"start_root_m": 0.0, "root_m": 0.0, "limb_m": 0.0}
    stepped_aside = afd_parts(real + np.array([0.3, 0.0, 0.4]), real, root)  # the same motion, 0.5 m away
    assert stepped_aside["start_root_m"] == pytest.approx(0.5) and stepped_aside["root_m"] == pytest.approx(0.5)
    assert stepped_aside["limb_m"] == pytest.approx(0.0, abs=1e-9)
    frozen = afd_parts(np.repeat(real[:1], len(real), 0), real, root)  # right start, then no motion at all
    assert frozen["start_root_m"] == 0.0 and frozen["limb_m"] > 0.0
    with pytest.raises(ValueError, match="shape"):
        afd_parts(real[:-1], real, root)


PLAUSIBLE = {"limb_speed_ratio": 0.5, "smooth_limb_speed_ratio": 0.4, "bone_error_cm": 1.0, "interpenetration": 0.0, "foot_skate_mps": 0.1,
             "real_bone_error_cm": 0.5, "real_interpenetration": 0.0, "real_foot_skate_mps": 0.2}


def _fake_scores(x: float) -> dict:
    classes = {c: {"afd": x, "afd_squared": x * x, "fid": 10 * x, "accuracy": 0.5} for c in ("a", "b")}
    return {"classes": classes, "fid": 10 * x, "accuracy": 0.5, "diversity": 1.0, "plausibility": PLAUSIBLE | {"speed_ratio": x},
            "afd_parts": {"start_root_m": x / 2, "root_m": x / 2, "limb_m": x / 4}}


def _fake_fold_result(subject: str, group: str, seed: int, afd: float) -> dict:
    """A synthetic fold result with the shape evaluate_fold returns (made-up numbers, for the report's arithmetic)."""
    return {"subject": subject, "group": group, "seed": seed, "real_diversity": 1.0,
            "classifier": {"real_accuracy": {"interaction": 0.9, "follower": 0.7, "follower_judge": 0.7}},
            "model": _fake_scores(afd), "baselines": {"nn1": _fake_scores(2.0), "knn_dtw": _fake_scores(1.0)},
            "adherence": {"a": 0.4, "b": 0.4}, "adherence_judge": {"a": 0.3, "b": 0.3},
            "adherence_matrix": [[1, 0], [0, 1]], "adherence_matrix_judge": [[1, 0], [0, 1]],
            "adherence_off_diagonal": 0.0, "adherence_off_diagonal_judge": 0.0,
            "mix": [{"pair": ["a", "b"], "mass": 1.0, "first": 0.5, "second": 0.5, "both_top2": 1.0}],
            "mix_judge": [{"pair": ["a", "b"], "mass": 1.0, "first": 0.8, "second": 0.2, "both_top2": 1.0}],
            "avoid": {"p_zero": 0.5, "p_avoid": 0.2, "change": -0.3},
            "avoid_judge": {"p_zero": 0.5, "p_avoid": 0.3, "change": -0.2}}


def test_report_groups_folds_and_seeds():
    from imm_model.evaluation.report import summarize
    from imm_model.evaluation.tables import markdown_report

    results = [_fake_fold_result("s01", "dev", 0, 0.6), _fake_fold_result("s02", "test", 0, 0.8),
               _fake_fold_result("s01", "dev", 1, 0.8), _fake_fold_result("s02", "test", 1, 1.0)]
    s = summarize(results, ("a", "b"))
    assert s["folds"] == ["s01", "s02"] and s["seeds"] == [0, 1] and set(s["groups"]) == {"all", "dev", "test"}
    assert s["classes"]["a"]["afd"] == pytest.approx(0.8) and s["classes"]["a"]["afd_std"] == pytest.approx(np.std([0.6, 0.8, 0.8, 1.0]))
    assert s["groups"]["dev"]["classes"]["a"]["afd"] == pytest.approx(0.7)
    assert s["groups"]["test"]["classes"]["b"]["strongest_baseline"] == "knn_dtw"
    assert s["groups"]["test"]["classes"]["b"]["ratio_strongest"] == pytest.approx(0.9)
    assert s["classes"]["a"]["ratio_nn1"] == pytest.approx(0.4)
    assert s["per_fold"] == results  # every fold's result as it is: nothing in it is kept out of the JSON
    assert s["mix_pairs_ok"] == 1 and s["mix_pairs_ok_judge"] == 0  # 0.2 < 0.25 on the second member
    assert s["model_overall"]["afd_parts"]["limb_m"] == pytest.approx(0.2)
    text = markdown_report(s)
    lo, hi = intervals.t_interval([0.6, 0.8, 0.8, 1.0])  # the class's 95 % interval over the four results
    assert "## dev folds" in text and "## test folds" in text and f"| a | 0.800 [{lo:.2f}, {hi:.2f}] |" in text
    assert "| model | 0.400 | 0.400 | 0.200 |" in text  # where the AFD comes from, all folds and seeds


def tilted_back(motion: np.ndarray, degrees: float) -> np.ndarray:
    """The whole body turned back about its own left-right axis through the body centre, frame by frame: turned the
    way that moves the head further behind the body centre along the body's facing (across x up)."""
    from scipy.spatial.transform import Rotation

    from imm_model.skeleton import KINECT15

    centre = motion[:, KINECT15.root_neighbours].mean(1, keepdims=True)
    across = motion[:, 9] - motion[:, 12] + motion[:, 3] - motion[:, 6]
    axis = across.mean(0) * np.array([1, 0, 1])
    forward = np.cross(axis, np.eye(3)[KINECT15.vertical_axis])
    head_forward = lambda m: float((m[:, 0] - m[:, KINECT15.root_neighbours].mean(1)).mean(0) @ forward)  # noqa: E731
    rot = Rotation.from_rotvec(np.radians(degrees) * axis / np.linalg.norm(axis))
    out = rot.apply((motion - centre).reshape(-1, 3)).reshape(motion.shape) + centre
    if head_forward(out) > head_forward(motion):
        out = rot.inv().apply((motion - centre).reshape(-1, 3)).reshape(motion.shape) + centre  # the other way is back
    return out


def test_lean_error_counts_a_follower_thrown_further_back_than_the_real_one(sample_data):
    """The real followers tilted back by 15 degrees about their own left-right axis (hand-made): their lean error is
    about 15 degrees, the real followers' own is 0, and a yaw turn of the whole scene changes neither."""
    from scipy.spatial.transform import Rotation

    idx = [int(i) for i in np.flatnonzero(sample_data.held_out)[:6]]
    leaders, reals = zip(*(sample_data.canonical(i) for i in idx), strict=True)
    tilted = [tilted_back(r.astype(np.float64), 15.0) for r in reals]
    p = plausibility.plausibility(list(leaders), tilted, list(reals), sample_data.skeleton, 15.0)
    assert 12.0 < p["lean_error_deg"] < 16.0
    assert plausibility.plausibility(list(leaders), list(reals), list(reals), sample_data.skeleton, 15.0)["lean_error_deg"] == 0.0
    yaw = Rotation.from_euler("y", 50, degrees=True)
    turned = [yaw.apply(t.reshape(-1, 3)).reshape(t.shape) for t in tilted]
    lean = plausibility.torso_lean_deg
    assert lean(turned[0], sample_data.skeleton) == pytest.approx(lean(tilted[0], sample_data.skeleton), abs=1e-6)
    assert lean(tilted[0], sample_data.skeleton) < lean(reals[0], sample_data.skeleton) - 12.0
