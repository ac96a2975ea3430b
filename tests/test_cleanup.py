"""The inference clean-up (imm_model/cleanup.py): rigid bones, planted feet.

Unit tests run on real SBU poses from the bundled sample, moved about by hand (the moves are synthetic and say
so); the last tests go through the bundled checkpoint.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from imm_model.checkpoint import load_checkpoint, save_checkpoint
from imm_model.cleanup import clean_follower, follower_bone_lengths, plant_feet, rigid_bones
from imm_model.contact import CONTACT_M
from imm_model.errors import CheckpointError
from imm_model.evaluation.plausibility import foot_skate_mps
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_GAN


def _feet(skeleton):
    return [skeleton.joint_names.index(n) for n in ("left_foot", "right_foot")]


def test_rigid_bones_sets_every_bone_and_keeps_its_direction(sample_data):
    sk = sample_data.skeleton
    follower = sample_data.canonical(3)[1].astype(np.float64)
    wobbly = follower * (1 + 0.1 * np.sin(np.arange(len(follower)))[:, None, None])  # synthetic: bones breathe 10 %
    lengths = np.linspace(0.1, 0.4, len(sk.bones))
    out = rigid_bones(wobbly, sk, lengths)
    np.testing.assert_allclose(sk.bone_lengths(out), np.broadcast_to(lengths, (len(out), len(lengths))), atol=1e-9)
    np.testing.assert_allclose(out[:, sk.root], wobbly[:, sk.root])
    for parent, child in sk.bones:
        before, after = wobbly[:, child] - wobbly[:, parent], out[:, child] - out[:, parent]
        cosine = (before * after).sum(-1) / np.linalg.norm(before, axis=-1) / np.linalg.norm(after, axis=-1)
        assert cosine.min() > 1 - 1e-9
    own = rigid_bones(wobbly, sk)  # no lengths given: each bone at its own median
    assert np.ptp(sk.bone_lengths(own), axis=0).max() < 1e-9


def test_plant_feet_holds_a_foot_on_the_floor_and_keeps_the_leg(sample_data):
    sk = sample_data.skeleton
    follower = sample_data.canonical(20)[1].astype(np.float64)
    t = np.arange(len(follower))
    sliding = follower + np.stack([0.02 * t, 0 * t, 0 * t], -1)[:, None]  # synthetic: 0.3 m/s drift of the whole body
    out = plant_feet(sliding, sk)
    assert foot_skate_mps(out, sk, 15.0) < 0.5 * foot_skate_mps(sliding, sk, 15.0)
    for foot in _feet(sk):
        knee, hip = sk.parents[foot], sk.parents[sk.parents[foot]]
        for a, b in ((hip, knee), (knee, foot)):
            length = np.linalg.norm(out[:, a] - out[:, b], axis=-1)
            assert np.abs(length - np.median(np.linalg.norm(sliding[:, a] - sliding[:, b], axis=-1))).max() < 1e-6
    legs = {j for f in _feet(sk) for j in (f, sk.parents[f])}
    untouched = [j for j in range(sk.num_joints) if j not in legs]
    np.testing.assert_array_equal(out[:, untouched], sliding[:, untouched])
    floor = sliding[:, _feet(sk), sk.vertical_axis].min()
    airborne = sliding[:, _feet(sk), sk.vertical_axis] > floor + CONTACT_M + 0.05  # well off the floor
    for k, foot in enumerate(_feet(sk)):
        far = airborne[:, k] & np.convolve(airborne[:, k], np.ones(5), "same").astype(bool)
        np.testing.assert_allclose(out[far, foot], sliding[far, foot], atol=0.05)


def test_clean_follower_on_the_bundled_model(sample_data):
    """On the network's hug for a kicking leader: rigid bones at the given lengths, feet slide less, and the
    motion is cleaned up, not replaced."""
    model = ReactionModel.load(SAMPLE_GAN)
    model.raw = True
    sk = sample_data.skeleton
    lengths = np.asarray(follower_bone_lengths([sample_data.canonical(i)[1] for i in range(40)], sk))
    for i in (60, 100, 150):
        raw = model.synthesize_canonical(sample_data.canonical(i)[0], np.eye(6, dtype=np.float32)[3]).astype(np.float64)
        clean = clean_follower(raw, sk, lengths)
        assert np.abs(sk.bone_lengths(clean) - lengths).max() < 1e-6
        assert foot_skate_mps(clean, sk, 15.0) <= foot_skate_mps(raw, sk, 15.0)
        assert np.linalg.norm(clean - raw, axis=-1).mean() < 0.1  # metres: a clean-up, not a new motion


def test_the_model_cleans_up_unless_raw_and_reads_its_bone_lengths(sample_data, tmp_path):
    tensors, meta = load_checkpoint(SAMPLE_GAN)
    lengths = np.linspace(0.1, 0.4, len(sample_data.skeleton.bones))
    path = tmp_path / "with_lengths.safetensors"
    save_checkpoint(path, tensors, meta | {"follower_bone_lengths": lengths.tolist()})
    model = ReactionModel.load(path)
    leader, label = sample_data.canonical(5)[0], np.eye(6, dtype=np.float32)[1]
    out = model.synthesize_canonical(leader, label)
    np.testing.assert_allclose(model.skeleton.bone_lengths(out), np.broadcast_to(lengths, (len(out), len(lengths))), atol=1e-5)
    np.testing.assert_allclose(model.synthesize_batch_canonical([leader], label[None])[0], out, atol=1e-4)
    model.raw = True
    assert np.abs(model.skeleton.bone_lengths(model.synthesize_canonical(leader, label)) - lengths).max() > 0.01
    for bad in ([0.3] * 3, [float("nan")] * len(lengths), [-0.1] * len(lengths), "long"):
        side = json.loads(path.with_suffix(".json").read_text()) | {"follower_bone_lengths": bad}
        path.with_suffix(".json").write_text(json.dumps(side))
        with pytest.raises(CheckpointError, match=r"follower_bone_lengths must be 14 lengths in \(0, 5\] m"):
            ReactionModel.load(path)


def test_evaluation_cleans_up_every_model_alike(sample_data, tmp_path):
    """`imm evaluate` scores cleaned followers (or raw ones with --raw); a checkpoint from before the clean-up gets
    the bone lengths its training would have stored: the fold's training followers'."""
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation.loso import EvalOptions, prepare_model

    tensors, meta = load_checkpoint(SAMPLE_GAN)
    old = tmp_path / "old.safetensors"
    save_checkpoint(old, tensors, {k: v for k, v in meta.items() if k != "follower_bone_lengths"})
    model = ReactionModel.load(old)
    assert model.bone_lengths is None
    prepare_model(model, sample_data, "s04", EvalOptions())
    train = loso_fold(sample_data.subject_pairs, "s04").train
    expected = follower_bone_lengths([sample_data.canonical(int(i))[1] for i in train], sample_data.skeleton)
    np.testing.assert_allclose(model.bone_lengths, expected)
    np.testing.assert_allclose(model.bone_lengths, ReactionModel.load(SAMPLE_GAN).bone_lengths)  # the bundle's own
    assert not model.raw
    prepare_model(model, sample_data, "s04", EvalOptions(raw=True, average_placement=True))
    assert model.raw and model.average_placement
