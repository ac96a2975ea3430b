"""The generator's label critic: drawn labels, what the critic scores, and that it stays frozen."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

from imm_model.families.gan.trainer import Trainer
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
    from imm_model.families.gan.critic import drawn_labels

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
    frozen = trainer.critic.classifier
    before = [p.clone() for p in frozen.parameters()]
    row = trainer.train_epoch(0)
    assert row["critic"] > 0  # the critic is scored, never trained
    assert all(torch.equal(p, b) and not p.requires_grad for p, b in zip(frozen.parameters(), before, strict=True))
    with pytest.raises(ValueError, match=r"critic_mix_prob must be a finite number in \[0, 1\]"):
        replace(TINY, critic_mix_prob=2.0)


def test_the_critic_is_the_folds_follower_gru_scoring_both_labels(sample_data, tmp_path, monkeypatch):
    """The critic is the cached follower GRU (FOLLOWER) of the fold, asked for once; every batch it scores the
    true-label follower and the drawn-label one."""
    from imm_model import cache
    from imm_model.model.classifier_config import FOLLOWER
    from imm_model.training.label_critic import LabelCritic

    quick = quick_follower_classifier(sample_data)
    asked, scored = [], []
    monkeypatch.setattr(cache, "fold_classifier", lambda cfg, data, subject, **k: asked.append((cfg, subject)) or quick)
    real_loss = LabelCritic.loss
    monkeypatch.setattr(LabelCritic, "loss", lambda self, x, lengths, target: scored.append(target) or real_loss(self, x, lengths, target))
    trainer = Trainer(replace(TINY, lambda_critic=0.1, adv_warmup_epochs=0, adv_ramp_epochs=0), sample_data, "s04", tmp_path)
    trainer.train_epoch(0)
    assert asked == [(FOLLOWER, "s04")]
    batches = -(-len(trainer.train_idx) // TINY.batch_size)
    assert len(scored) == 2 * batches
    true_targets = scored[0::2]
    assert all(set(t.sum(1).tolist()) == {1.0} and set(t.flatten().tolist()) <= {0.0, 1.0} for t in true_targets)


def test_label_critic_loss_is_the_soft_cross_entropy_and_reaches_the_follower(sample_data):
    """The critic's loss is the mean soft cross-entropy of its frozen classifier; its gradient reaches the generated
    follower, never the classifier."""
    from imm_model.model.classifier import MotionClassifier
    from imm_model.model.classifier_config import ClassifierConfig
    from imm_model.training.label_critic import LabelCritic

    torch.manual_seed(0)
    clf = MotionClassifier(ClassifierConfig(inputs="follower", hidden=8, features=8), 45, 6)
    x = torch.as_tensor(sample_data.canonical(0)[1].reshape(1, -1, 45)).repeat(2, 1, 1).requires_grad_(True)
    lengths, target = torch.tensor([x.shape[1]] * 2), torch.tensor([[1.0, 0, 0, 0, 0, 0], [0, 0.5, 0, 0.5, 0, 0]])
    critic = LabelCritic(clf)
    loss = critic.loss(x, lengths, target)
    expected = -(clf.eval()(x, lengths).log_softmax(-1) * target).sum(-1).mean()  # the classifier without dropout
    torch.testing.assert_close(loss, expected, rtol=0, atol=0)
    loss.backward()
    assert x.grad is not None and x.grad.abs().sum() > 0
    assert all(p.grad is None for p in critic.classifier.parameters())
