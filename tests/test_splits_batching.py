"""Splits (LOSO, 5-fold, validation) and padded, length-bucketed batches."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from imm_model.data.batching import LengthBucketSampler, pad_sequences
from imm_model.data.splits import five_folds, loso_fold, loso_folds, subjects_of, validation_split


def test_loso_folds_are_disjoint_by_subject_and_cover_everything(sample_data):
    pairs = sample_data.subject_pairs
    folds = loso_folds(pairs)
    assert [f.name for f in folds] == [f"loso-s0{k}" for k in range(1, 8)]
    covered = np.concatenate([f.test for f in folds])
    assert set(covered.tolist()) == set(range(len(sample_data)))
    for fold in folds:
        subject = fold.name.split("-")[1]
        assert all(subject not in subjects_of(pairs[i]) for i in fold.train)
        assert all(subject in subjects_of(pairs[i]) for i in fold.test)
        assert len(fold.train) + len(fold.test) == len(sample_data)
    # Deterministic
    assert all(np.array_equal(a.test, b.test) for a, b in zip(folds, loso_folds(pairs), strict=True))


def test_five_fold_split_partitions_the_pairs(sample_data):
    folds = five_folds(sample_data.subject_pairs)
    tests = np.concatenate([f.test for f in folds])
    assert sorted(tests.tolist()) == list(range(len(sample_data)))


def test_validation_split_comes_from_training_only(sample_data):
    fold = loso_fold(sample_data.subject_pairs, "s03")
    train, val = validation_split(fold.train, sample_data.actions, fraction=0.15, seed=0)
    assert np.intersect1d(val, fold.test).size == 0 and np.intersect1d(train, val).size == 0
    assert sorted(np.concatenate([train, val]).tolist()) == sorted(fold.train.tolist())
    assert set(sample_data.actions[val].tolist()) == set(range(6))  # stratified: every class
    again, _ = validation_split(fold.train, sample_data.actions, fraction=0.15, seed=0)
    assert np.array_equal(train, again)
    with pytest.raises(ValueError, match="unknown subject"):
        loso_fold(sample_data.subject_pairs, "s09")


def test_batch_padding_and_masks(sample_data):
    idx = [0, 5, 17]
    leader, mask = pad_sequences([sample_data.canonical(i)[0].reshape(int(sample_data.lengths[i]), -1) for i in idx])
    t_max = int(sample_data.lengths[idx].max())
    assert leader.shape == (3, t_max, 45) and mask.shape == (3, t_max)
    for b, i in enumerate(idx):
        n = int(sample_data.lengths[i])
        assert mask[b].sum() == n and torch.all(leader[b, n:] == 0)
        np.testing.assert_array_equal(leader[b, :n].numpy(), sample_data.canonical(i)[0].reshape(n, -1))


def test_length_buckets_cut_padding_and_cover_each_index_once(sample_data):
    idx = np.arange(len(sample_data))
    sampler = LengthBucketSampler(sample_data.lengths, idx, batch_size=16, seed=1)
    batches = list(sampler)
    flat = sorted(i for b in batches for i in b)
    assert flat == idx.tolist()
    padded_frames = sum(len(b) * sample_data.lengths[b].max() for b in batches)
    assert padded_frames < 1.1 * sample_data.lengths.sum()  # vs ~1.8x when padding to 46
    assert padded_frames < 0.6 * len(idx) * 46
    sampler.set_epoch(1)
    assert [b for b in sampler] != batches  # a new order every epoch
    sampler.set_epoch(0)
    assert list(sampler) == batches  # ... and reproducible
