"""The generator's extra training terms: the label critic (true and drawn labels, ensembles, its options), rigid
output and interpenetration."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.training.trainer import Trainer
from tests.test_training import TINY


def quick_follower_classifier(sample_data, **overrides):
    """A follower classifier trained for one epoch on 40 sequences: a critic for tests, in seconds."""
    from imm_model.model.classifier import train_classifier
    from imm_model.model.classifier_config import ClassifierConfig

    followers = [sample_data.canonical(i)[1].reshape(-1, 45) for i in range(40)]
    cfg = ClassifierConfig(inputs="follower", epochs=1, hidden=8, features=8, **overrides)
    return train_classifier(cfg, followers, sample_data.actions[:40], 6)


def test_label_critic_scores_the_true_and_a_drawn_label(sample_data, tmp_path, monkeypatch):
    """lambda_critic > 0: a frozen follower classifier scores G's output for the true and a drawn other label."""
    from imm_model import cache
    from imm_model.training.critic import drawn_labels

    gen = torch.Generator().manual_seed(0)
    actions = torch.arange(6).repeat(50)
    labels, target = drawn_labels(actions, 6, 0.5, gen)
    own = labels[torch.arange(300), actions]
    one_hot = labels.sum(1) == 1
    assert (own[one_hot] == 0).all()  # a one-hot label is never the leader's own class ...
    assert (own[~one_hot] == 1).any() and (own[~one_hot] == 0).any()  # ... a mix may include it
    assert set(labels.sum(1).tolist()) == {1.0, 2.0} and torch.allclose(target.sum(1), torch.ones(300))
    assert labels.max() == 1.0  # two different members

    quick = quick_follower_classifier(sample_data)
    monkeypatch.setattr(cache, "fold_classifier", lambda *a, **k: quick)
    trainer = Trainer(replace(TINY, lambda_critic=0.1, critic_mix_prob=0.5, adv_warmup_epochs=0, adv_ramp_epochs=0),
                      sample_data, "s04", tmp_path)
    before = quick.head.weight.clone()
    row = trainer.train_epoch(0)
    assert row["critic"] > 0 and torch.equal(quick.head.weight, before)  # the critic is scored, never trained
    with pytest.raises(ValueError, match="critic_mix_prob must be in"):
        replace(TINY, critic_mix_prob=2.0)


def test_critic_options_and_rigid_output(sample_data, tmp_path, monkeypatch):
    """critic_true_label False: only the drawn label meets the critic (critic_true_confidence: the true label's
    alone); critic_mixup / critic_start_centred: the critic
    is a mixup-trained / start-centred classifier; rigid_output: every follower a loss reads has the training followers' bone lengths."""
    from imm_model import cache
    from imm_model.training.critic import LabelCritic

    quick = quick_follower_classifier(sample_data, mixup=True)
    asked, scored = [], []
    monkeypatch.setattr(cache, "fold_classifier", lambda cfg, *a, **k: asked.append(cfg) or quick)
    real_loss = LabelCritic.loss
    monkeypatch.setattr(LabelCritic, "loss", lambda self, x, *a: scored.append(a[3]) or real_loss(self, x, *a))
    base = replace(TINY, lambda_critic=0.1, adv_warmup_epochs=0, adv_ramp_epochs=0)
    for true_label, mixup, calls in ((True, False, 2), (False, True, 1)):
        asked.clear(), scored.clear()
        trainer = Trainer(replace(base, critic_true_label=true_label, critic_mixup=mixup, critic_start_centred=mixup,
                                  critic_true_confidence=0.6), sample_data, "s04", tmp_path)
        trainer.train_epoch(0)
        assert [(c.mixup, c.start_centred) for c in asked] == [(mixup, mixup)]
        assert len(scored) == calls * -(-len(trainer.train_idx) // TINY.batch_size)  # per batch
        assert scored[:calls] == [0.6, 1.0][2 - calls:]  # the floor is the true label's alone
    trainer = Trainer(replace(TINY, rigid_output=True), sample_data, "s04", tmp_path)
    leader, _, lengths, actions = trainer.padded.batch(torch.as_tensor(trainer.train_idx[:4]))
    labels = torch.nn.functional.one_hot(actions, 6).float()
    fake = trainer.generate(trainer.G, leader, labels, lengths).detach().numpy()
    for row, n in zip(fake, lengths.tolist(), strict=True):
        bones = sample_data.skeleton.bone_lengths(row[:n].reshape(n, -1, 3))
        np.testing.assert_allclose(bones, np.broadcast_to(trainer.bone_lengths, bones.shape), atol=1e-5)
    assert np.isfinite(trainer.train_epoch(0)["l1"])


def test_penetration_loss_measures_overlap_like_the_evaluation(sample_data):
    """training/penetration.py: the measure's segment geometry in torch; zero for bodies apart, and its gradient
    moves an overlapping follower out of the leader."""
    from imm_model.contact import bone_pair_distances
    from imm_model.training.penetration import penetration_loss, segment_distances

    sk = sample_data.skeleton
    leader, follower = (x.astype(np.float64) for x in sample_data.canonical(10))
    into = follower + (leader[:, sk.root] - follower[:, sk.root])[:, None] * np.array([0.8, 0, 0.8])  # synthetic overlap
    bones = np.array(sk.bones)
    a, b = torch.tensor(leader), torch.tensor(into)
    pairs = segment_distances(a[:, bones[:, 0], None], a[:, bones[:, 1], None], b[:, None, bones[:, 0]], b[:, None, bones[:, 1]])
    np.testing.assert_allclose(pairs.numpy(), bone_pair_distances(leader, into, sk), atol=1e-6)
    flat = lambda x: torch.tensor(x.reshape(1, len(x), -1), dtype=torch.float32)  # noqa: E731
    mask, idx = torch.ones(1, len(leader)), torch.tensor(bones)
    assert float(penetration_loss(flat(leader), flat(follower + [3.0, 0, 0]), mask, idx)) == 0.0
    moving = flat(into).requires_grad_(True)
    loss = penetration_loss(flat(leader), moving, mask, idx)
    loss.backward()
    assert float(loss.detach()) > 0
    stepped = (moving - 0.05 * moving.grad / moving.grad.abs().max()).detach()
    assert float(penetration_loss(flat(leader), stepped, mask, idx)) < float(loss.detach())


def test_label_critic_ensemble_and_augmentation(sample_data):
    """Several critics average their losses; with augment each scores a turned/scaled/jittered copy, and the
    gradient still reaches the generated follower."""
    from imm_model.model.classifier import MotionClassifier
    from imm_model.model.classifier_config import ClassifierConfig
    from imm_model.training.critic import LabelCritic

    torch.manual_seed(0)
    a, b = (MotionClassifier(ClassifierConfig(inputs="follower", hidden=8, features=8, seed=s), 45, 6) for s in (0, 1))
    x = torch.as_tensor(sample_data.canonical(0)[1].reshape(1, -1, 45)).repeat(2, 1, 1).requires_grad_(True)
    lengths, target = torch.tensor([x.shape[1]] * 2), torch.eye(6)[:2]
    gen = lambda: torch.Generator().manual_seed(0)  # noqa: E731
    la, lb = (LabelCritic([c]).loss(x, lengths, target, gen()) for c in (a, b))
    torch.testing.assert_close(LabelCritic([a, b]).loss(x, lengths, target, gen()), (la + lb) / 2)
    augmented = LabelCritic([a], augment=True).loss(x, lengths, target, gen())
    assert not torch.isclose(augmented, la)
    augmented.backward()
    assert x.grad is not None and x.grad.abs().sum() > 0
    with pytest.raises(ValueError, match="critic_seeds must be"):
        replace(TINY, critic_seeds=())


def test_true_label_confidence_stops_the_pull_on_a_readable_follower(sample_data):
    """critic_true_confidence < 1: a follower the critic reads as its class with at least that probability adds no
    loss and no gradient; one read below it keeps the plain cross-entropy, less the floor."""
    from imm_model.model.classifier import MotionClassifier
    from imm_model.model.classifier_config import ClassifierConfig
    from imm_model.training.critic import LabelCritic

    torch.manual_seed(0)
    clf = MotionClassifier(ClassifierConfig(inputs="follower", hidden=8, features=8), 45, 6)
    x = torch.as_tensor(sample_data.canonical(0)[1].reshape(1, -1, 45)).repeat(2, 1, 1).requires_grad_(True)
    lengths, gen = torch.tensor([x.shape[1]] * 2), torch.Generator().manual_seed(0)
    probs = clf(x, lengths).softmax(-1).detach()
    likely, unlikely = int(probs[0].argmax()), int(probs[0].argmin())
    critic = LabelCritic([clf])
    read = float(probs[0, likely])
    above = critic.loss(x[:1], lengths[:1], torch.eye(6)[[likely]], gen, confidence=read * 0.99)
    above.backward()
    assert float(above.detach()) == 0.0 and x.grad.abs().sum() == 0
    plain = critic.loss(x[1:], lengths[1:], torch.eye(6)[[unlikely]], gen)
    floored = critic.loss(x[1:], lengths[1:], torch.eye(6)[[unlikely]], gen, confidence=0.9)
    torch.testing.assert_close(floored, plain + np.log(0.9), rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="critic_true_confidence must be in"):
        replace(TINY, critic_true_confidence=0.0)


def test_root_term_is_the_root_joints_own_l1(sample_data, tmp_path):
    """lambda_root > 0: the log's "root" is the root joint's L1 alone, below the whole pose's when the follower is
    placed well, and it adds to the generator's loss; a negative weight is refused by name."""
    trainer = Trainer(replace(TINY, lambda_root=1.0), sample_data, "s04", tmp_path)
    leader, follower, lengths, actions = trainer.padded.batch(torch.as_tensor(trainer.train_idx[:4]))
    mask = torch.arange(follower.shape[1])[None] < lengths[:, None]
    root = sample_data.skeleton.root
    fake = follower.clone()
    fake[..., 3 * root:3 * root + 3] += 0.5  # only the root joint misplaced
    with_root, terms = trainer._generator_loss(0, leader, follower, fake, lengths, actions, mask, torch.Generator())
    assert terms["root"] == pytest.approx(0.5, rel=1e-5) and terms["l1"] == pytest.approx(0.5 / 15, rel=1e-5)
    trainer.cfg = replace(trainer.cfg, lambda_root=0.0)
    without_root, terms = trainer._generator_loss(0, leader, follower, fake, lengths, actions, mask, torch.Generator())
    assert "root" not in terms and float(with_root - without_root) == pytest.approx(0.5, rel=1e-4)
    with pytest.raises(ValueError, match="lambda_root must be >= 0"):
        replace(TINY, lambda_root=-1.0)


def test_start_term_ties_the_drawn_labels_first_frame_root_to_the_true_ones(sample_data, tmp_path, monkeypatch):
    """lambda_start > 0: the drawn label's follower is pulled to where the true label's starts on the first frame, and
    the true one is not pulled back (it is held fixed); without the critic the option is refused by name."""
    from imm_model import cache

    monkeypatch.setattr(cache, "fold_classifier", lambda *a, **k: quick_follower_classifier(sample_data))
    cfg = replace(TINY, lambda_critic=0.1, critic_true_label=False, lambda_start=1.0, adv_warmup_epochs=0,
                  adv_ramp_epochs=0)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path)
    leader, _, lengths, actions = trainer.padded.batch(torch.as_tensor(trainer.train_idx[:4]))
    mask = torch.arange(leader.shape[1])[None] < lengths[:, None]
    fake = trainer.generate(trainer.G, leader, torch.nn.functional.one_hot(actions, 6).float(), lengths).detach()
    fake = (fake + 0.3).requires_grad_(True)  # the true-label follower stands elsewhere
    loss, terms = trainer._critic_loss(0, leader, fake, lengths, actions, mask, torch.Generator().manual_seed(0), 0.0)
    assert terms["start"] > 0.25  # mostly the 0.3 m moved; the drawn label's own offset is small for an untrained G
    loss.backward()
    assert fake.grad is None or fake.grad.abs().sum() == 0
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in trainer.G.parameters())
    with pytest.raises(ValueError, match="lambda_start must be"):
        replace(TINY, lambda_start=1.0)
