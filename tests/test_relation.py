"""Relation curves (training/relation.py): the follower's whole-body motion relative to the leader, the target of a
drawn label. Synthetic motions: unit tests only."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.training.relation import RELATION_BINS, class_relations, relation_curves, relation_loss

ROOT, UP = 0, 1


def pair(T: int = 24, step_back: float = 0.8, crouch: float = 0.0) -> tuple[torch.Tensor, torch.Tensor]:
    """(1, T, 6) leader and follower of 2 joints: the leader stands still at the origin; the follower starts 1 m
    away along z and steps back by `step_back` m and down by `crouch` m at a constant pace."""
    t = torch.linspace(0, 1, T)
    leader = torch.zeros(T, 2, 3)
    follower = torch.zeros(T, 2, 3)
    follower[:, :, 2] = 1.0 + step_back * t[:, None]
    follower[:, :, UP] = -crouch * t[:, None]
    return leader.reshape(1, T, 6), follower.reshape(1, T, 6)


def test_curves_measure_the_change_in_distance_and_height_and_ignore_padding():
    leader, follower = pair(crouch=0.2)
    curve = relation_curves(leader, follower, torch.tensor([24]), ROOT, UP)[0]
    assert curve.shape == (RELATION_BINS, 2)
    assert (curve[1:, 0] > curve[:-1, 0]).all() and 0.6 < curve[-1, 0] < 0.8  # moving away, by ~0.8 m at the end
    assert (curve[1:, 1] < curve[:-1, 1]).all() and -0.2 < curve[-1, 1] < -0.15
    padded = [torch.cat([x, torch.full((1, 10, 6), 9.0)], 1) for x in (leader, follower)]
    assert torch.allclose(relation_curves(*padded, torch.tensor([24]), ROOT, UP)[0], curve)
    sideways = follower.clone().view(1, 24, 2, 3)
    sideways[..., 0] += 0.3  # further off to the side from the start: stepping back widens the distance less
    assert relation_curves(leader, sideways.flatten(2), torch.tensor([24]), ROOT, UP)[0, -1, 0] < curve[-1, 0]


def test_the_loss_pulls_towards_the_classes_curve():
    leader, follower = pair(step_back=0.8)
    _, still = pair(step_back=0.0)
    joints = [x[0].view(24, 2, 3).numpy() for x in (leader, follower, still)]
    profiles = class_relations([joints[0]] * 2, joints[1:], np.array([0, 1]), 2, ROOT, UP)
    assert profiles.shape == (2, 2 * RELATION_BINS) and profiles[1].abs().max() < 1e-6
    lengths = torch.tensor([24])
    assert relation_loss(leader, follower, profiles[:1], lengths, ROOT, UP) < 1e-6
    moved = still.clone().requires_grad_(True)
    loss = relation_loss(leader, moved, profiles[:1], lengths, ROOT, UP)
    loss.backward()
    assert loss > 0.1 and moved.grad.view(24, 2, 3)[-1, 0, 2] < 0  # a step away from the leader lowers it


def test_trainer_logs_the_relation_term(sample_data, tmp_path):
    from imm_model.training.trainer import Trainer
    from tests.test_training import TINY

    cfg = replace(TINY, lambda_critic=0.05, lambda_relation=1.0, adv_warmup_epochs=0, adv_ramp_epochs=0)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path)
    assert trainer.relations.shape == (6, 2 * RELATION_BINS)
    assert trainer.train_epoch(0)["relation"] > 0
    with pytest.raises(ValueError, match="lambda_relation must be"):
        replace(TINY, lambda_relation=1.0)  # without the critic there are no drawn labels to shape
