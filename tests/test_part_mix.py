"""Two-class training composites by body parts (training/part_mix.py) and the sampler's pair terms that read them.
Followers are the bundled SBU data's; the sampler's network is a synthetic stand-in (its numbers are not results)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.families.diffusion.recipes import IMM_DIFFUSION, DiffusionTrainConfig
from imm_model.families.diffusion.sampler import Guidance, sample
from imm_model.model.body_parts import compose_parts as compose
from imm_model.model.classifier import body_part_view
from imm_model.training.part_mix import mixed_rows, part_indices, resample_rows, upper_shares


def batch(sample_data, rows):
    from imm_model.training.data import PaddedData

    padded = PaddedData.from_dataset(sample_data)
    leader, follower, lengths, actions = padded.batch(torch.as_tensor(rows))
    return follower, lengths, actions


def test_a_composite_reads_as_its_sources_part_by_part(sample_data):
    follower, lengths, _ = batch(sample_data, [0, 60])
    n = int(min(lengths))
    a, b = (follower[i:i + 1, :n].unflatten(-1, (-1, 3)) for i in (0, 1))
    upper, legs, centre = part_indices(sample_data.skeleton)
    mixed = compose(a, b, upper, centre)
    view = lambda x, part: body_part_view(x[0].numpy(), part, sample_data.skeleton)  # noqa: E731
    assert np.allclose(view(mixed, "upper"), view(a, "upper"), atol=1e-5)  # trunk and arms as a's, around the centre
    assert np.allclose(mixed[0, :, legs].numpy(), b[0, :, legs].numpy())  # legs and placement as b's
    assert sorted(upper + legs) == list(range(sample_data.skeleton.num_joints))


def test_resampling_keeps_the_ends(sample_data):
    follower, lengths, _ = batch(sample_data, [0, 1])
    out = resample_rows(follower, lengths, torch.tensor([10, int(lengths[1])]))
    n = int(lengths[0])
    assert torch.allclose(out[0, 0], follower[0, 0]) and torch.allclose(out[0, 9], follower[0, n - 1])
    assert (out[0, 10:] == 0).all() and torch.allclose(out[1, : lengths[1]], follower[1, : lengths[1]], atol=1e-6)


def test_mixed_rows_compose_only_rows_with_another_class(sample_data):
    rows = list(range(0, 197, 7))
    follower, lengths, actions = batch(sample_data, rows)
    shares = upper_shares([sample_data.follower[sample_data.frames(i)] for i in range(len(sample_data))], sample_data.actions,
                          6, sample_data.skeleton)
    assert shares.shape == (6,) and ((shares > 0) & (shares < 1)).all()
    untouched, one_hot = mixed_rows(follower, lengths, actions, shares, 0.0, sample_data.skeleton, torch.Generator().manual_seed(0))
    assert torch.equal(untouched, follower) and torch.equal(one_hot, torch.nn.functional.one_hot(actions, 6).float())
    mixed, labels = mixed_rows(follower, lengths, actions, shares, 1.0, sample_data.skeleton, torch.Generator().manual_seed(0))
    two_hot = labels.sum(1) == 2
    assert two_hot.any() and set(labels.sum(1).tolist()) <= {1.0, 2.0} and labels.max() == 1
    assert (labels[torch.arange(len(rows)), actions] == 1).all()  # a row keeps its own class
    changed = (mixed != follower).flatten(1).any(1)
    assert torch.equal(changed, two_hot)  # exactly the composed rows differ
    mask = torch.arange(follower.shape[1])[None] >= lengths[:, None]
    assert (mixed[mask] == 0).all()  # padding stays zero
    upper, legs, centre = part_indices(sample_data.skeleton)
    for i in torch.nonzero(two_hot).flatten().tolist():  # the class with the larger upper-body share gives the trunk and arms
        n, own = int(lengths[i]), mixed[i, : lengths[i]].unflatten(-1, (-1, 3))
        mine = follower[i, :n].unflatten(-1, (-1, 3))
        keeps_legs = torch.allclose(own[:, legs], mine[:, legs])
        other = int(torch.nonzero(labels[i] * (torch.arange(6) != actions[i])).item())
        assert keeps_legs == bool(shares[other] > shares[actions[i]])


def test_mixing_needs_the_network_that_reads_two_hot_labels():
    with pytest.raises(ValueError, match="mix_prob.*pair_terms"):
        replace(IMM_DIFFUSION, mix_prob=0.3)
    DiffusionTrainConfig.from_dict(IMM_DIFFUSION.to_dict() | {"mix_prob": 0.3, "model": IMM_DIFFUSION.model | {"pair_terms": True}})


def test_pair_terms_move_from_the_sum_rule_to_the_joint_condition():
    """A stand-in network: each class moves x0 by its own offset, a two-hot label by a different one (not their sum).
    With pair terms, one class is the sum rule, two classes at 1 are guidance on the joint condition, and a second
    class entering at a small value moves the result by little."""
    offsets = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], np.float32)

    def denoise(x, step, leader_on, label, label_on):
        joint = np.where(label.sum(1) == 2, 1.0, 0.0)  # the two-hot label's own effect
        out = (label * offsets).sum(1) * label_on + joint * label_on
        return np.broadcast_to(out[:, None, None], x.shape).astype(np.float32).copy()

    leaders, mask = np.zeros((1, 4, 45), np.float32), np.ones((1, 4), bool)
    noise = np.zeros((1, 4, 45), np.float32)
    g = Guidance(label_scale=2.0, sample_steps=1)
    run = lambda w, pairs=True: sample(denoise, leaders, mask, np.array([w], np.float32), noise, g, 100, pair_terms=pairs)[0, 0, 0]  # noqa: E731
    assert np.isclose(run([0, 1, 0, 0, 0, 0]), 2.0 * 0.2)  # one class: the sum rule
    assert np.isclose(run([0, 1, 0, 1, 0, 0], pairs=False), 2.0 * (0.2 + 0.4))  # two, without pair terms: the sum
    assert np.isclose(run([0, 1, 0, 1, 0, 0]), 2.0 * (0.2 + 0.4 + 1.0))  # with: s * (x0(A, e_1 + e_3) - x0(A, -))
    assert abs(run([0, 1, 0, 0.01, 0, 0]) - run([0, 1, 0, 0, 0, 0])) < 0.05  # a class entering at 0.01 moves little
    assert np.isclose(run([0, 1, 0, -1, 0, 0]), 2.0 * (0.2 - 0.4))  # avoid: no pair term
