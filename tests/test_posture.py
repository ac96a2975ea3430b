"""Posture profiles (training/posture.py): how a follower holds its body, the target of a drawn label. Real SBU
followers, moved, turned, mirrored and tilted here by hand."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from imm_model.skeleton import KINECT15
from imm_model.training.posture import PostureTarget, class_postures, posture_loss, postures

HEAD, FORWARD, UP = 0, 0, 1  # joint 0; the two columns of a joint's posture


def as_batch(motion: np.ndarray, pad: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """(T, J, 3) -> (1, T + pad, 3J) with `pad` frames of garbage after the sequence, and its length."""
    x = torch.as_tensor(motion, dtype=torch.float32).flatten(1)
    x = torch.cat([x, torch.full((pad, x.shape[1]), 7.0)])
    return x[None], torch.tensor([len(motion)])


def tilted_back(motion: np.ndarray, degrees: float) -> np.ndarray:
    """The whole body turned back about its own left-right axis through the body centre, frame by frame."""
    centre = motion[:, KINECT15.root_neighbours].mean(1, keepdims=True)
    across = motion[:, 9] - motion[:, 12] + motion[:, 3] - motion[:, 6]
    axis = across.mean(0) * np.array([1, 0, 1])
    rot = Rotation.from_rotvec(np.radians(degrees) * axis / np.linalg.norm(axis))
    forward_before = postures(*as_batch(motion), KINECT15)[0].view(-1, 2)[HEAD, FORWARD]
    out = rot.apply((motion - centre).reshape(-1, 3)).reshape(motion.shape) + centre
    if postures(*as_batch(out), KINECT15)[0].view(-1, 2)[HEAD, FORWARD] > forward_before:
        out = rot.inv().apply((motion - centre).reshape(-1, 3)).reshape(motion.shape) + centre  # the other way is back
    return out


def test_posture_ignores_where_the_follower_stands_which_way_it_faces_mirroring_and_padding(sample_data):
    follower = sample_data.canonical(0)[1].astype(np.float64)
    base = postures(*as_batch(follower), KINECT15)[0]
    assert base.shape == (2 * KINECT15.num_joints,)
    assert base.view(-1, 2)[HEAD, UP] > 0.3  # the head is well above the body centre
    turned = Rotation.from_euler("y", 70, degrees=True).apply(follower.reshape(-1, 3)).reshape(follower.shape)
    moved = turned + np.array([0.8, 0.0, -1.5])
    mirrored = KINECT15.mirrored(follower)
    for other in (moved, mirrored):
        assert torch.allclose(postures(*as_batch(other), KINECT15)[0], base, atol=1e-4)
    assert torch.allclose(postures(*as_batch(follower, pad=9), KINECT15)[0], base, atol=1e-5)


def test_a_follower_that_leans_back_has_its_head_behind_the_body_centre(sample_data):
    follower = sample_data.canonical(0)[1].astype(np.float64)
    head = [postures(*as_batch(tilted_back(follower, deg)), KINECT15)[0].view(-1, 2)[HEAD] for deg in (0, 10, 20)]
    assert head[0][FORWARD] > head[1][FORWARD] + 0.05 > head[2][FORWARD] + 0.1  # ~0.5 m above: ~9 cm per 10 degrees
    assert head[2][UP] < head[0][UP]


def test_the_loss_pulls_towards_the_classes_posture(sample_data):
    upright = sample_data.canonical(0)[1]
    leaning = tilted_back(upright.astype(np.float64), 20).astype(np.float32)
    profiles, spreads = class_postures([upright, leaning], np.array([0, 1]), 2, KINECT15)
    assert profiles.shape == spreads.shape == (2, 2 * KINECT15.num_joints) and spreads.abs().max() == 0  # one each
    x, lengths = as_batch(leaning)
    assert posture_loss(x, profiles[1:], lengths, KINECT15) < 1e-5
    x.requires_grad_(True)
    loss = posture_loss(x, profiles[:1], lengths, KINECT15)
    loss.backward()
    assert loss > 0.01
    # moving the leaning head back to where it was upright lowers the loss
    towards_upright = torch.as_tensor(upright[:, HEAD] - leaning[:, HEAD]).mean(0)
    head_grad = x.grad.view(len(upright), -1, 3)[:, HEAD]
    assert float((head_grad * towards_upright).sum()) < 0


def test_trainer_logs_the_posture_term(sample_data, tmp_path):
    from imm_model.training.trainer import Trainer
    from tests.test_training import TINY

    cfg = replace(TINY, lambda_critic=0.05, lambda_posture=1.0, adv_warmup_epochs=0, adv_ramp_epochs=0)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path)
    assert trainer.posture.means.shape == trainer.posture.spreads.shape == (6, 2 * KINECT15.num_joints)
    assert trainer.train_epoch(0)["posture"] > 0
    one_class = Trainer(replace(cfg, posture_on_mixes=False, critic_mix_prob=1.0), sample_data, "s04", tmp_path / "mixes")
    assert one_class.train_epoch(0)["posture"] == 0  # every drawn label a mix: no posture target
    with pytest.raises(ValueError, match="lambda_posture must be"):
        replace(TINY, lambda_posture=1.0)  # without the critic there are no drawn labels to shape


def test_the_loss_can_leave_out_rows(sample_data):
    """Rows left out (a two-class mix with posture_on_mixes off) cost nothing, and leaving out every row gives 0, not
    a division by zero."""
    upright = sample_data.canonical(0)[1]
    leaning = tilted_back(upright.astype(np.float64), 20).astype(np.float32)
    target = class_postures([upright], np.array([0]), 1, KINECT15)[0].expand(2, -1)
    x = torch.cat([as_batch(upright)[0], as_batch(leaning)[0]])
    lengths = torch.tensor([len(upright)] * 2)
    assert posture_loss(x, target, lengths, KINECT15, torch.tensor([True, False])) < 1e-5
    assert posture_loss(x, target, lengths, KINECT15, torch.tensor([False, True])) > 0.01
    assert posture_loss(x, target, lengths, KINECT15, torch.tensor([False, False])) == 0


def test_a_tolerance_frees_postures_within_the_classes_spread(sample_data):
    """A class of an upright and a 20-degree-leaning follower: its mean leans 10 degrees. Held to the mean, the
    upright follower costs; with a tolerance of one spread it does not, and a 40-degree lean still does."""
    upright = sample_data.canonical(0)[1].astype(np.float64)
    leaning, far = (tilted_back(upright, deg).astype(np.float32) for deg in (20, 40))
    means, spreads = class_postures([upright.astype(np.float32), leaning], np.array([0, 0]), 1, KINECT15)
    label, lengths = torch.tensor([[1.0]]), torch.tensor([len(upright)])
    strict, loose = PostureTarget(means, spreads, KINECT15), PostureTarget(means, spreads, KINECT15, tolerance=1.0)
    assert strict.loss(as_batch(upright.astype(np.float32))[0], label, lengths) > 0.005
    assert loose.loss(as_batch(upright.astype(np.float32))[0], label, lengths) < 1e-4
    assert loose.loss(as_batch(far)[0], label, lengths) > 0.005
