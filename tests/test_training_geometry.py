"""The diffusion model's geometric training terms (training/geometry.py): a planted foot's drag and the torso's
direction, on a real SBU follower moved by hand, and that the trainer adds them only when weighted."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.families.diffusion.trainer import DiffusionTrainer
from imm_model.skeleton import KINECT15
from imm_model.training.geometry import GeometricTerms
from tests.test_diffusion import TINY

LEFT_FOOT, NECK, LEFT_HIP, RIGHT_HIP = 11, 1, 9, 12


@pytest.fixture(scope="module")
def real(sample_data):
    """(1, T, 15, 3) one real follower, (1, T) mask."""
    follower = sample_data.canonical(0)[1]
    return torch.as_tensor(follower[None], dtype=torch.float32), torch.ones(1, len(follower), dtype=torch.bool)


def test_a_perfect_prediction_costs_nothing(real):
    follower, mask = real
    terms = GeometricTerms(KINECT15)(follower, follower, mask)
    assert terms["torso"].item() < 1e-10
    # the real follower's own planted feet drag (Kinect jitter): the term is that drag, not zero, and finite
    assert 0 < terms["foot_contact"].item() < 0.01


def test_a_planted_foot_that_slides_is_charged_and_a_lifted_one_is_not(real):
    follower, mask = real
    geometry = GeometricTerms(KINECT15)
    still = follower.clone()
    still[0, :, :, [0, 2]] = follower[0, :1, :, [0, 2]]  # every joint held horizontally where it starts
    assert geometry.foot_contact(still, follower, mask).item() == pytest.approx(0.0, abs=1e-12)
    sliding = still.clone()
    sliding[0, :, LEFT_FOOT, 0] += 0.01 * torch.arange(len(follower[0]))  # 1 cm a frame along x
    height = follower[0, :, [11, 14], 1]
    on_floor = (height < height.min() + 0.05)
    planted_left = (on_floor[1:, 0] & on_floor[:-1, 0]).sum().item()
    planted = (on_floor[1:] & on_floor[:-1]).sum().item()
    assert planted_left > 0
    expected = 1e-4 * planted_left / planted
    assert geometry.foot_contact(sliding, follower, mask).item() == pytest.approx(expected, rel=1e-4)
    # the same slide where the real foot is lifted (a real follower whose feet stand 1 m higher but for one frame)
    lifted = follower.clone()
    lifted[0, 1:, LEFT_FOOT, 1] += 1.0
    lifted[0, 1:, 14, 1] += 1.0
    assert geometry.foot_contact(sliding, lifted, mask).item() == pytest.approx(0.0, abs=1e-12)


def test_a_tilted_torso_costs_two_minus_twice_its_cosine(real):
    follower, mask = real
    torso = follower.clone()
    # the neck turned 20 degrees about the hips' centre, towards a direction at right angles to the torso
    centre = follower[0, :, [LEFT_HIP, RIGHT_HIP]].mean(1)
    v = follower[0, :, NECK] - centre
    u = v / v.norm(dim=-1, keepdim=True)
    side = torch.linalg.cross(u, torch.tensor([0.0, 0.0, 1.0]).expand_as(u))
    side = side / side.norm(dim=-1, keepdim=True)
    a = math.radians(20)
    torso[0, :, NECK] = centre + v.norm(dim=-1, keepdim=True) * (math.cos(a) * u + math.sin(a) * side)
    cost = GeometricTerms(KINECT15).torso(torso, follower, mask).item()
    assert cost == pytest.approx(2 - 2 * math.cos(a), rel=1e-3)
    # padded frames do not count: the same tilt on frames beyond the mask changes nothing
    half = mask.clone()
    half[0, len(mask[0]) // 2:] = False
    padded = follower.clone()
    padded[0, len(mask[0]) // 2:] = torso[0, len(mask[0]) // 2:]
    assert GeometricTerms(KINECT15).torso(padded, follower, half).item() < 1e-10


def test_the_trainer_adds_the_terms_only_when_weighted(sample_data, tmp_path):
    unweighted = replace(TINY, steps=1, lambda_foot_contact=0.0, lambda_torso=0.0)
    plain = DiffusionTrainer(unweighted, sample_data, "s04", tmp_path / "plain").train_step()
    assert plain["foot_contact"] == 0 and plain["torso"] == 0
    assert plain["loss"] == pytest.approx(plain["x0"] + plain["velocity"], rel=1e-6)
    cfg = replace(TINY, steps=1, lambda_foot_contact=20.0, lambda_torso=1.0)
    weighted = DiffusionTrainer(cfg, sample_data, "s04", tmp_path / "weighted").train_step()
    assert weighted["foot_contact"] > 0 and weighted["torso"] > 0
    expected = weighted["x0"] + weighted["velocity"] + 20.0 * weighted["foot_contact"] + weighted["torso"]
    assert weighted["loss"] == pytest.approx(expected, rel=1e-5)
    assert np.isfinite(list(weighted.values())).all()
