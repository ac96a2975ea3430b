"""Motion-energy matching (families/gan/energy.py) and device selection. Synthetic motions: unit tests only."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.device import resolve_device
from imm_model.evaluation.plausibility import mean_speed, smooth
from imm_model.families.gan.energy import class_profiles, energy_loss, limb_speeds, mixed_profile

ROOT = 0


def moving_pose(T: int = 30, J: int = 4, speed: float = 0.02, drift: float = 0.05) -> torch.Tensor:
    """(1, T, 3J): joint 1 moves along x at `speed` m/frame relative to the root; everything drifts along z."""
    t = torch.arange(T, dtype=torch.float32)
    p = torch.zeros(T, J, 3)
    p[:, 1, 0] = speed * t
    p[:, :, 2] += drift * t[:, None]  # a root translation shared by all joints: no limb motion
    return p.reshape(1, T, 3 * J)


def test_limb_speed_is_relative_to_the_root_and_ignores_padding():
    pose = moving_pose()
    s = limb_speeds(pose, torch.tensor([30]), ROOT)
    assert s.shape == (1, 4)
    assert s[0, 1].item() == pytest.approx(0.02, rel=1e-4) and s[0, [0, 2, 3]].abs().max() < 1e-6
    padded = torch.cat([pose, torch.full((1, 10, 12), 99.0)], dim=1)  # garbage after the end
    assert torch.allclose(limb_speeds(padded, torch.tensor([30]), ROOT), s, atol=1e-6)


def test_limb_speed_from_the_body_centre_ignores_a_swaying_root():
    """energy_reference "body": speeds relative to the centre of several joints, so the reference joint swinging
    alone moves only itself there, where from the root it moves every other joint."""
    t = torch.arange(30, dtype=torch.float32)
    p = torch.zeros(30, 4, 3)
    p[:, ROOT, 0] = 0.05 * torch.sin(0.5 * t)  # the root swings; joints 1-3 stand still
    pose = p.reshape(1, 30, 12)
    from_root = limb_speeds(pose, torch.tensor([30]), ROOT)
    from_body = limb_speeds(pose, torch.tensor([30]), [1, 2])
    assert from_root[0, 1:].min() > 0.01 and from_body[0, 1:].abs().max() < 1e-6 and from_body[0, ROOT] > 0.01


def test_limb_speed_matches_the_evaluation_on_smoothed_motion():
    """The training target is what the evaluation measures: mean speed of the Savitzky-Golay smoothed motion."""
    rng = np.random.default_rng(0)
    motion = np.cumsum(rng.normal(0, 0.01, (40, 4, 3)), axis=0)  # a random walk per joint
    ours = limb_speeds(torch.tensor(motion, dtype=torch.float32).reshape(1, 40, 12), torch.tensor([40]), ROOT)
    theirs = mean_speed(smooth(motion), 1.0, ROOT)  # the evaluation also counts the edge frames
    assert ours[0].mean().item() == pytest.approx(theirs, rel=0.15)


def test_jitter_earns_little_energy():
    """Frame-to-frame jitter of +-2 cm moves a joint 4 cm per frame raw, under a quarter of that once smoothed
    (the window-7, order-2 filter passes 0.24 of the highest frequency)."""
    pose = torch.zeros(1, 30, 12)
    pose[0, :, 3] = 0.02 * torch.tensor([(-1.0) ** k for k in range(30)])
    assert limb_speeds(pose, torch.tensor([30]), ROOT)[0, 1] < 0.25 * 0.04


def test_energy_loss_pushes_a_still_pose_to_move():
    still = torch.zeros(1, 30, 12, requires_grad=True)
    target = limb_speeds(moving_pose(), torch.tensor([30]), ROOT)
    loss = energy_loss(still + 1e-3 * torch.randn(1, 30, 12), target, torch.tensor([30]), ROOT)
    loss.backward()
    assert loss.item() > 0.004 and still.grad.abs().sum() > 0
    short = energy_loss(torch.zeros(1, 5, 12), target, torch.tensor([5]), ROOT)  # too short to measure: no term
    assert short.item() == 0.0


def test_class_profiles_and_their_mix():
    moving = moving_pose()[0].reshape(30, 4, 3).numpy()
    profiles = class_profiles([moving, np.zeros_like(moving)], np.array([0, 1]), 3, ROOT)
    assert profiles[0, 1].item() == pytest.approx(0.02, rel=1e-4) and profiles[1].abs().max() == 0 and profiles[2].abs().max() == 0
    mix = mixed_profile(torch.tensor([[1.0, 1.0, 0.0], [1.0, 0.0, -1.0]]), profiles)
    assert mix[0, 1].item() == pytest.approx(0.01, rel=1e-4)  # half of each member
    assert mix[1, 1].item() == pytest.approx(0.02, rel=1e-4)  # an avoided class adds nothing


def test_trainer_logs_the_energy_term(sample_data, tmp_path):
    from imm_model.families.gan.trainer import Trainer
    from tests.test_training import TINY

    trainer = Trainer(replace(TINY, lambda_energy=1.0, adv_warmup_epochs=0, adv_ramp_epochs=0), sample_data, "s04", tmp_path)
    assert trainer.profiles.shape == (6, 15)
    assert trainer.train_epoch(0)["energy"] > 0
    with pytest.raises(ValueError, match="lambda_energy must be"):
        replace(TINY, lambda_energy=-1.0)
    body = Trainer(replace(TINY, lambda_energy=1.0, energy_reference="body", adv_warmup_epochs=0, adv_ramp_epochs=0),
                   sample_data, "s04", tmp_path)
    assert body.train_epoch(0)["energy"] > 0
    assert body.energy_reference == sample_data.skeleton.root_neighbours
    assert not torch.allclose(body.profiles, trainer.profiles)  # the real followers' speeds from another frame
    with pytest.raises(ValueError, match="energy_reference must be one of 'root', 'body'"):
        replace(TINY, energy_reference="pelvis")


def test_device_choice():
    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(ValueError, match="expected one of auto, cpu, cuda"):
        resolve_device("gpu")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="sees no CUDA device"):
            resolve_device("cuda")
