"""The inference API the studio depends on, against the bundled checkpoint, and `imm generate`."""

from __future__ import annotations

import numpy as np
import pytest

import imm_model
from imm_model.checkpoint import load_checkpoint, save_checkpoint
from imm_model.cli import main
from imm_model.data.canonical import yaw_rotation
from imm_model.data.splits import loso_fold
from imm_model.errors import DataFormatError, LabelError
from imm_model.evaluation.metrics import afd
from imm_model.inference import Label, ReactionModel
from imm_model.paths import SAMPLE_DIFFUSION, SAMPLE_GAN, SAMPLE_MODELS, SAMPLE_STUDENT


@pytest.fixture(scope="module")
def model():
    return ReactionModel.load(SAMPLE_GAN)


def test_bundled_checkpoint_describes_itself(model, sample_data):
    assert model.class_names == sample_data.class_names
    assert model.skeleton == sample_data.skeleton
    assert model.held_out_subject == sample_data.info["held_out_subject"] == "s04"
    assert model.config.latent_dim > 0 and model.info["code_version"]
    assert SAMPLE_GAN.with_suffix(".json").exists()


def test_label_vector(model):
    v = model.label_vector({"kicking": 1, "hugging": 0.5}, scale=2)
    assert v.dtype == np.float32 and v.tolist() == [2, 0, 0, 1, 0, 0]
    assert model.label_vector([0, -1, 0, 0, 0, 0.25]).tolist() == [0, -1, 0, 0, 0, 0.25]
    for bad, match in [({"kick": 1}, "unknown class"), ([1, 0], "expected 6"), ({"kicking": float("nan")}, "finite"),
                       ([np.inf] * 6, "finite"), ({"kicking": "a lot"}, "not a number"), ("kicking", "not a string")]:
        with pytest.raises(LabelError, match=match):
            model.label_vector(bad)
    with pytest.raises(LabelError, match="finite"):
        model.label_vector({"kicking": 1}, scale=float("inf"))
    assert Label.parse("kicking=1, hugging=0.5", model.class_names).keys() == {"kicking": 1.0, "hugging": 0.5}
    assert Label.parse("1,0,0,0,0,0", model.class_names).keys() == {"kicking": 1.0}
    assert Label.parse("hugging", model.class_names).keys() == {"hugging": 1.0}


def test_leader_validation(model, sample_data):
    leader = sample_data.world(0)[0]
    bad = [(leader[:, :14], "14 joints"), (leader[:0], "empty"), (leader[:1], "1 frame"),
           (np.where(np.arange(len(leader))[:, None, None] == 3, np.nan, leader), "NaN"),
           (np.zeros((model.max_length + 1, 15, 3)), "at most"), (leader[..., :2], "shape")]
    for arr, match in bad:
        with pytest.raises(DataFormatError, match=match):
            model.synthesize(arr, {"kicking": 1})
    assert model.synthesize(leader.reshape(len(leader), 45), {"kicking": 1}).shape == leader.shape


def test_world_synthesis_follows_the_leader(model, sample_data):
    """Rotating and moving the leader in the world moves the follower the same way."""
    leader = sample_data.world(5)[0]
    out = model.synthesize(leader, {"pushing": 1})
    assert out.shape == leader.shape and out.dtype == np.float32 and np.isfinite(out).all()
    rot = yaw_rotation(np.array([0.7]), sample_data.skeleton)[0]
    shift = np.array([0.5, 0.0, -1.0])
    moved = model.synthesize(leader @ rot.T + shift, {"pushing": 1})
    np.testing.assert_allclose(moved, out @ rot.T + shift, atol=1e-3)


def test_batch_equals_single_and_latent(model, sample_data):
    leaders = [sample_data.canonical(i)[0] for i in (0, 7, 30)]
    labels = np.eye(6, dtype=np.float32)[[0, 3, 5]]
    batch = model.synthesize_batch_canonical(leaders, labels)
    for a, lab, b in zip(leaders, labels, batch, strict=True):
        assert b.shape == a.shape
        np.testing.assert_allclose(b, model.synthesize_canonical(a, lab), atol=1e-4)
    z = model.latent_canonical_batch(leaders, labels)
    assert z.shape == (3, model.config.latent_dim)
    world = sample_data.world(7)[0]
    np.testing.assert_allclose(model.latent(world, {"hugging": 1}), z[1], atol=1e-4)
    np.testing.assert_allclose(imm_model.latent(world, {"hugging": 1}, checkpoint=SAMPLE_GAN), z[1], atol=1e-4)
    assert imm_model.synthesize(world, [0, 0, 0, 1, 0, 0], checkpoint=SAMPLE_GAN).shape == world.shape
    assert not np.allclose(model.latent(world, {"kicking": 1}), z[1])  # the label enters the encoding


def test_average_placement_moves_the_follower_and_keeps_its_motion(sample_data):
    """Averaged placement shifts the whole follower by one offset (its motion is the network's own), makes the
    placement mirror-consistent, and leaves a handed label (handshakes are never mirrored in training) alone."""
    model, skeleton = ReactionModel.load(SAMPLE_GAN), sample_data.skeleton
    leaders = [sample_data.canonical(i)[0] for i in (0, 7)]
    labels = np.eye(6, dtype=np.float32)[[0, 2]]  # kicking; shaking hands (handed)
    model.raw = True
    single = model.synthesize_batch_canonical(leaders, labels)
    model.average_placement = True
    placed = model.synthesize_batch_canonical(leaders, labels)
    shift = placed[0] - single[0]
    np.testing.assert_allclose(shift, np.broadcast_to(shift[0, 0], shift.shape), atol=1e-5)
    assert np.linalg.norm(shift[0, 0]) > 1e-3  # the network's two answers disagree on where the follower stands
    np.testing.assert_array_equal(placed[1], single[1])
    twin = model.synthesize_canonical(skeleton.mirrored(leaders[0]), labels[0])
    centre = [f[:, skeleton.root_neighbours].mean((0, 1)) for f in (placed[0], skeleton.mirrored(twin))]
    np.testing.assert_allclose(centre[0], centre[1], atol=1e-5)
    np.testing.assert_allclose(skeleton.mirrored(skeleton.mirrored(twin)), twin)


def test_average_placement_leaves_a_model_trained_without_mirroring_alone(tmp_path, sample_data):
    tensors, meta = load_checkpoint(SAMPLE_GAN)
    unmirrored = tmp_path / "unmirrored.safetensors"
    save_checkpoint(unmirrored, tensors, meta | {"train_config": meta["train_config"] | {"mirror_prob": 0.0}})
    model = ReactionModel.load(unmirrored)
    leader, label = sample_data.canonical(0)[0], np.eye(6, dtype=np.float32)[0]
    single = model.synthesize_canonical(leader, label)
    model.average_placement = True
    np.testing.assert_array_equal(model.synthesize_canonical(leader, label), single)


def test_bundled_model_beats_a_trivial_baseline_on_its_held_out_subject(model, sample_data):
    """Plausible reactions: lower AFD than the training set's mean follower pose per class, bones kept."""
    fold = loso_fold(sample_data.subject_pairs, model.held_out_subject)
    ours, trivial, bone_err = [], [], []
    for i in fold.test:
        leader, gt = sample_data.canonical(int(i))
        pred = model.synthesize_canonical(leader, np.eye(6, dtype=np.float32)[sample_data.actions[i]])
        same = [j for j in fold.train if sample_data.actions[j] == sample_data.actions[i]]
        mean_pose = np.mean([sample_data.canonical(int(j))[1].mean(0) for j in same], axis=0)
        frame, sk = sample_data.frame_of(int(i)), sample_data.skeleton
        ours.append(afd(pred, gt, frame, sk))
        trivial.append(afd(np.repeat(mean_pose[None], len(gt), 0), gt, frame, sk))
        bone_err.append(np.abs(sk.bone_lengths(pred) - sk.bone_lengths(gt)).mean())
    assert np.mean(ours) < 0.9 * np.mean(trivial)
    assert np.mean(bone_err) < 0.05  # metres


def test_the_default_model_is_the_bundled_diffusion_model(model, sample_data, tmp_path):
    """ReactionModel.load(), the one-call helpers, `imm generate` and the studio's switch default to the diffusion
    model's 2-step student, its teacher making its long takes (docs/experiments/default-model.md, default-student.md);
    the GAN stays bundled and loads by its path."""
    default = ReactionModel.load()
    assert default.family == "diffusion" and default.settings.seed and default.path == SAMPLE_STUDENT
    assert default.guidance.sample_steps == 2 and default.takes.path == SAMPLE_DIFFUSION
    assert model.family == "gan" and not model.settings.seed
    assert list(SAMPLE_MODELS) == ["diffusion", "gan", "retrieval"] and SAMPLE_MODELS["gan"] == SAMPLE_GAN
    world = sample_data.world(7)[0]
    ours = imm_model.synthesize(world, {"hugging": 1})
    np.testing.assert_allclose(ours, default.synthesize(world, {"hugging": 1}), atol=1e-5)
    assert not np.allclose(ours, model.synthesize(world, {"hugging": 1}), atol=1e-2)  # not the GAN's follower
    out = tmp_path / "d.npz"
    assert main(["generate", "--sequence", sample_data.sequence_ids[7], "--label", "hugging", "--out", str(out)]) == 0
    with np.load(out) as z:
        assert str(z["checkpoint"]) == SAMPLE_STUDENT.name and int(z["seed"]) == 0
        np.testing.assert_allclose(z["follower"], ours, atol=1e-4)
    assert main(["generate", "--sequence", sample_data.sequence_ids[7], "--label", "hugging", "--out", str(out), "--force",
                 "--checkpoint", str(SAMPLE_GAN)]) == 0
    with np.load(out) as z:
        assert str(z["checkpoint"]) == SAMPLE_GAN.name and "seed" not in z.files


def test_generate_cli(tmp_path, sample_data, capsys):
    out = tmp_path / "o.npz"
    assert main(["generate", "--sequence", sample_data.sequence_ids[3], "--label", "kicking=1,hugging=0.5", "--out", str(out)]) == 0
    with np.load(out) as z:
        assert z["follower"].shape == z["leader"].shape == (sample_data.lengths[3], 15, 3)
        assert z["label"].tolist() == [1, 0, 0, 0.5, 0, 0]
    leader_file = tmp_path / "leader.npz"
    np.savez(leader_file, leader=sample_data.world(3)[0])
    assert main(["generate", "--leader", str(leader_file), "--label", "kicking", "--scale", "2", "--out", str(out), "--force"]) == 0
    assert main(["generate", "--leader", str(leader_file), "--label", "kick=1", "--out", str(out), "--force"]) == 2
    err = capsys.readouterr().err
    assert "unknown class 'kick'" in err and len(err.strip().splitlines()) == 1
    np.savez(leader_file, other=np.zeros(3))
    assert main(["generate", "--leader", str(leader_file), "--label", "kicking", "--out", str(out), "--force"]) == 2
    assert "no 'leader' array" in capsys.readouterr().err
