"""Deterministic train/test splits over subject pairs.

Leave-one-subject-out (the paper's protocol): 7 folds, fold k tests on every subject-pair set that
contains subject k and trains on all others, so subject k is never seen in training.
The dataset README's 5-fold split is given by its fixed lists of subject pairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# From the SBU README (5-fold cross validation).
SBU_FIVE_FOLDS: tuple[tuple[str, ...], ...] = (
    ("s01s02", "s03s04", "s05s02", "s06s04"),
    ("s02s03", "s02s07", "s03s05", "s05s03"),
    ("s01s03", "s01s07", "s07s01", "s07s03"),
    ("s02s01", "s02s06", "s03s02", "s03s06"),
    ("s04s02", "s04s03", "s04s06", "s06s02", "s06s03"),
)


@dataclass(frozen=True)
class Fold:
    name: str  # "loso-s03" or "5fold-2"
    train: np.ndarray  # sequence indices, sorted
    test: np.ndarray

    def __post_init__(self) -> None:
        if np.intersect1d(self.train, self.test).size:
            raise ValueError(f"fold {self.name}: train and test overlap")


def normalize_fold(fold: str | None) -> str | None:
    """A fold as the user may name it -> the held-out subject: 's04', 'loso-s04', '4' -> 's04'; 'all' and None
    unchanged."""
    if fold is None or fold == "all":
        return fold
    fold = fold.removeprefix("loso-")
    if fold.isdigit():
        fold = f"s{int(fold):02d}"
    return fold


def subjects_of(pair: str) -> tuple[str, str]:
    """'s01s02' -> ('s01', 's02')."""
    if len(pair) != 6:
        raise ValueError(f"subject pair {pair!r} is not of the form sXXsYY")
    return pair[:3], pair[3:]


def all_subjects(subject_pairs: Sequence[str]) -> list[str]:
    return sorted({s for p in subject_pairs for s in subjects_of(p)})


def loso_fold(subject_pairs: Sequence[str], subject: str) -> Fold:
    """Test on every sequence whose pair contains `subject`; train on the rest."""
    if subject not in all_subjects(subject_pairs):
        raise ValueError(f"unknown subject {subject!r}; known: {all_subjects(subject_pairs)}")
    has = np.array([subject in subjects_of(p) for p in subject_pairs])
    return Fold(name=f"loso-{subject}", train=np.flatnonzero(~has), test=np.flatnonzero(has))


def loso_folds(subject_pairs: Sequence[str]) -> list[Fold]:
    """The 7 leave-one-subject-out folds of SBU (one per subject, in subject order)."""
    return [loso_fold(subject_pairs, s) for s in all_subjects(subject_pairs)]


def five_folds(subject_pairs: Sequence[str]) -> list[Fold]:
    """The SBU README's 5-fold split."""
    pairs = np.array(subject_pairs)
    folds = []
    for k, test_pairs in enumerate(SBU_FIVE_FOLDS, start=1):
        test = np.isin(pairs, test_pairs)
        folds.append(Fold(name=f"5fold-{k}", train=np.flatnonzero(~test), test=np.flatnonzero(test)))
    return folds


def half_split(actions: np.ndarray, seed: int = 0) -> Fold:
    """The recognition protocol's half/half split (Yun et al. 2012, as the IMM paper uses it): per class, a
    seeded shuffle, the first half (rounded up) trains and the rest tests."""
    rng = np.random.default_rng(seed)
    train = []
    for c in np.unique(actions):
        members = rng.permutation(np.flatnonzero(actions == c))
        train.extend(members[: (len(members) + 1) // 2].tolist())
    train_arr = np.sort(np.array(train, dtype=np.int64))
    return Fold(name=f"half-{seed}", train=train_arr, test=np.setdiff1d(np.arange(len(actions)), train_arr))


def validation_split(train: np.ndarray, actions: np.ndarray, fraction: float = 0.15, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Carve a class-stratified validation set out of a fold's training indices (never its test set).

    Returns (train, validation), both sorted. Deterministic for a given seed.
    """
    rng = np.random.default_rng(seed)
    val = []
    for c in np.unique(actions[train]):
        members = train[actions[train] == c]
        k = max(1, int(round(fraction * len(members)))) if len(members) > 1 else 0
        val.extend(rng.choice(members, size=k, replace=False).tolist())
    val_arr = np.sort(np.array(val, dtype=np.int64))
    return np.setdiff1d(train, val_arr), val_arr
