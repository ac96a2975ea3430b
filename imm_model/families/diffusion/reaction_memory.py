"""The diffusion sampler's reaction memory: real reactions of the training set as the sampler's starting point.

SBU records one reaction per leader, so a denoiser trained on it returns a hedge between the reactions it has seen:
limbs that move less than real ones, and variations smaller than the differences between real followers. Started
part-way down the noise schedule from a real follower's reaction to a similar leader (SDEdit, Meng et al. 2022; the
retrieval of ReMoDiffuse, Zhang et al. 2023), the sampler keeps that reaction's coarse timing and posture and fits the
rest to this leader and label. numpy only, like the sampler.

For each class the memory holds the training pairs of that class; a leader's `NEIGHBOURS` nearest training leaders of
a class (per-joint distance, both resampled to `RESAMPLED_FRAMES`) are that class's candidates, and a sampler seed
picks one per class. The starting reaction is a mixture of the picked followers whose weights are continuous in the
signed label, so a moved slider moves the start, it does not jump:

    rho_c = max(w_c, 0) / max(1, P) + max(0, 1 - P) * pi_c,    P = sum_c max(w_c, 0)

where pi (the label-free share, summing to 1) favours the class whose picked leader is nearest (a softmax over
distances at temperature `TEMPERATURE_M`) and fades a class out as its value goes from 0 to -1 (avoided classes
never start the reaction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imm_model.data.sequence import resample as resample_time

RESAMPLED_FRAMES = 24  # leaders are compared at this many frames, whatever their lengths
NEIGHBOURS = 3  # nearest training leaders per class a seed picks among
TEMPERATURE_M = 0.05  # metres per joint: how sharply the label-free share favours the nearest class
MEMORY_STREAM = 3  # a seed's picks are drawn from (seed, this), apart from the sampler's noise streams


def resample(motion: np.ndarray, frames: int) -> np.ndarray:
    """(T, ...) -> (frames, ...) float32, linearly in time."""
    return resample_time(np.asarray(motion, np.float32), frames)


@dataclass(frozen=True)
class ReactionMemory:
    """Training pairs in the canonical frame: leaders resampled for retrieval, followers as recorded."""

    leaders: np.ndarray  # (N, RESAMPLED_FRAMES, J * 3) float32: the training leaders, resampled
    followers: tuple[np.ndarray, ...]  # N followers (T_i, J, 3) float32
    classes: np.ndarray  # (N,) int: each pair's class
    num_classes: int

    def __post_init__(self) -> None:
        missing = sorted(set(range(self.num_classes)) - set(self.classes.tolist()))
        if missing:
            raise ValueError(f"a reaction memory needs every class; class {missing[0]} has no training pair")

    @classmethod
    def from_pairs(cls, leaders, followers, classes, num_classes: int) -> ReactionMemory:
        """Canonical (T_i, J, 3) leaders and followers with their classes -> the memory over them."""
        resampled = np.stack([resample(a, RESAMPLED_FRAMES).reshape(RESAMPLED_FRAMES, -1) for a in leaders])
        return cls(resampled, tuple(np.asarray(b, np.float32) for b in followers), np.asarray(classes, int), int(num_classes))

    @classmethod
    def from_dataset(cls, data, indices) -> ReactionMemory:
        """The memory over `data`'s pairs `indices` (a fold's training pairs: never its held-out subject)."""
        pairs = [data.canonical(int(i)) for i in indices]
        return cls.from_pairs([a for a, _ in pairs], [b for _, b in pairs], data.actions[np.asarray(indices, int)],
                              len(data.class_names))

    def picks(self, leader: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """The pair each class contributes for this leader and seed -> (C,) memory indices, (C,) their leaders'
        distances (metres per joint). Depends on the leader and the seed only, never on the label."""
        query = resample(leader, RESAMPLED_FRAMES).reshape(1, RESAMPLED_FRAMES, -1, 3)
        dist = np.linalg.norm(self.leaders.reshape(len(self.leaders), RESAMPLED_FRAMES, -1, 3) - query, axis=-1).mean((1, 2))
        draws = np.random.default_rng((int(seed), MEMORY_STREAM)).random(self.num_classes)
        index, distance = np.zeros(self.num_classes, int), np.zeros(self.num_classes)
        for c in range(self.num_classes):
            members = np.flatnonzero(self.classes == c)
            nearest = members[np.argsort(dist[members], kind="stable")[:NEIGHBOURS]]
            index[c] = nearest[int(draws[c] * len(nearest))]
            distance[c] = dist[index[c]]
        return index, distance

    def mixture_weights(self, label: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """Signed label (C,) (times the scale) and the picks' distances (C,) -> rho (C,), summing to 1."""
        label = np.asarray(label, np.float64)
        positive = np.maximum(label, 0)
        total = positive.sum()
        kept = np.clip(1 + label, 0, 1)  # a class fades out of the label-free share as its value goes to -1
        if not kept.any():  # every class avoided: the nearest still starts the reaction; guidance does the avoiding
            kept = np.ones_like(kept)
        prior = np.exp(-(distance - distance.min()) / TEMPERATURE_M) * kept
        return positive / max(1.0, total) + max(0.0, 1.0 - total) * prior / prior.sum()

    def start(self, leader: np.ndarray, label: np.ndarray, seed: int) -> np.ndarray:
        """The reaction the sampler starts from for this leader (T, J, 3), label and seed -> (T, J, 3) canonical."""
        index, distance = self.picks(leader, seed)
        rho = self.mixture_weights(label, distance)
        frames = len(leader)
        return sum(float(r) * resample(self.followers[i], frames) for r, i in zip(rho, index, strict=True) if r > 0)
