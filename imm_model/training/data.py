"""Training tensors: the whole dataset padded once, batches sliced from it, augmentation in torch.

Cheaper than building batches from numpy every step: an epoch is ~10 index/slice operations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from imm_model.data.dataset import InteractionDataset
from imm_model.skeleton import Skeleton


@dataclass
class PaddedData:
    leader: torch.Tensor  # (N, T_max, 3J) canonical metres, zero-padded
    follower: torch.Tensor  # (N, T_max, 3J)
    swapped_leader: torch.Tensor  # (N, T_max, 3J): B as leader, re-canonicalized on B
    swapped_follower: torch.Tensor
    lengths: torch.Tensor  # (N,)
    actions: torch.Tensor  # (N,)

    @classmethod
    def from_dataset(cls, data: InteractionDataset) -> PaddedData:
        """Every sequence padded, and its role-swapped copy (B leading, re-canonicalized on B) from the one
        implementation of the swap, InteractionDataset.role_swapped."""
        swapped = data.role_swapped()
        n, t_max, d = len(data), int(data.lengths.max()), 3 * data.skeleton.num_joints
        arrays = np.zeros((4, n, t_max, d), dtype=np.float32)
        for i in range(n):
            t = int(data.lengths[i])
            for k, motion in enumerate((*data.canonical(i), *swapped.canonical(i))):
                arrays[k, i, :t] = motion.reshape(t, -1)
        t = torch.from_numpy(arrays)
        return cls(t[0], t[1], t[2], t[3], torch.as_tensor(data.lengths), torch.as_tensor(data.actions))

    @classmethod
    def joined(cls, first: PaddedData, second: PaddedData) -> PaddedData:
        """The rows of both, padded to the longer: `second`'s row i is row len(first) + i."""
        t = max(first.leader.shape[1], second.leader.shape[1])
        pad = lambda x: torch.nn.functional.pad(x, (0, 0, 0, t - x.shape[1]))  # noqa: E731
        tensors = [torch.cat([pad(getattr(first, f)), pad(getattr(second, f))])
                   for f in ("leader", "follower", "swapped_leader", "swapped_follower")]
        return cls(*tensors, torch.cat([first.lengths, second.lengths]), torch.cat([first.actions, second.actions]))

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """idx (B,) -> leader, follower (B, T, 3J) trimmed to the longest, lengths, actions."""
        lengths = self.lengths[idx]
        t = int(lengths.max())
        return self.leader[idx, :t], self.follower[idx, :t], lengths, self.actions[idx]


class Augmenter:
    """Random mirror / yaw / role swap of a batch (both characters transformed alike)."""

    def __init__(self, skeleton: Skeleton, mirror_prob: float, rotate_deg: float, role_swap_prob: float,
                 swap_class_mask: torch.Tensor, time_warp: float = 0.0, scale_jitter: float = 0.0,
                 mirror_class_mask: torch.Tensor | None = None):
        self.perm = torch.tensor(skeleton.mirror_permutation)
        self.vertical = skeleton.vertical_axis
        self.lateral = skeleton.lateral_axis
        self.forward = (skeleton.vertical_axis + 1) % 3
        self.mirror_prob, self.rotate_deg, self.role_swap_prob = mirror_prob, rotate_deg, role_swap_prob
        self.swap_class_mask = swap_class_mask  # (C,) bool
        self.time_warp = time_warp
        self.scale_jitter = scale_jitter
        self.mirror_class_mask = mirror_class_mask  # (C,) bool: classes that may be mirrored (None = all)

    def __call__(self, data: PaddedData, idx: torch.Tensor, gen: torch.Generator):
        leader, follower, lengths, actions = data.batch(idx)
        B, T, _ = leader.shape
        if self.role_swap_prob > 0:
            swap = (torch.rand(B, generator=gen) < self.role_swap_prob) & self.swap_class_mask[actions]
            s = swap[:, None, None]
            leader = torch.where(s, data.swapped_leader[idx, :T], leader)
            follower = torch.where(s, data.swapped_follower[idx, :T], follower)
        poses = torch.stack([leader, follower]).unflatten(-1, (-1, 3))  # (2, B, T, J, 3)
        if self.mirror_prob > 0:
            flip = torch.rand(B, generator=gen) < self.mirror_prob
            if self.mirror_class_mask is not None:
                flip &= self.mirror_class_mask[actions]
            flip = flip[None, :, None, None, None]
            mirrored = poses[:, :, :, self.perm].clone()
            mirrored[..., self.lateral] *= -1
            poses = torch.where(flip, mirrored, poses)
        if self.rotate_deg > 0:
            ang = (torch.rand(B, generator=gen) * 2 - 1) * np.deg2rad(self.rotate_deg)
            c, s = torch.cos(ang)[None, :, None, None], torch.sin(ang)[None, :, None, None]
            f, lat = poses[..., self.forward], poses[..., self.lateral]
            poses = poses.clone()
            poses[..., self.forward] = c * f - s * lat
            poses[..., self.lateral] = s * f + c * lat
        if self.scale_jitter > 0:
            scale = 1 + (torch.rand(B, generator=gen) * 2 - 1) * self.scale_jitter
            poses = poses * scale[None, :, None, None, None]
        poses = poses.flatten(-2)
        if self.time_warp > 0:
            poses, lengths = self._warp(poses, lengths, gen)
        return poses[0], poses[1], lengths, actions

    def _warp(self, poses: torch.Tensor, lengths: torch.Tensor, gen: torch.Generator):
        """poses (2, B, T, D): each sequence resampled to round(L * U(1-w, 1+w)) frames (at least 2)."""
        factor = 1 + (torch.rand(len(lengths), generator=gen) * 2 - 1) * self.time_warp
        new = torch.clamp((lengths * factor).round().long(), min=2)
        t_new = int(new.max())
        t = torch.arange(t_new)[None].float()  # (1, T')
        src = t * (lengths - 1)[:, None] / (new - 1)[:, None].float()  # (B, T') source positions
        src = torch.minimum(src, (lengths - 1)[:, None].float())
        lo = src.floor().long()
        hi = torch.minimum(lo + 1, (lengths - 1)[:, None])
        w = (src - lo)[None, :, :, None]
        idx = lambda i: i[None, :, :, None].expand(2, -1, -1, poses.shape[-1])  # noqa: E731
        out = (1 - w) * poses.gather(2, idx(lo)) + w * poses.gather(2, idx(hi))
        valid = (t < new[:, None])[None, :, :, None]
        return torch.where(valid, out, torch.zeros(())), new


def late_starts(data: InteractionDataset, indices: np.ndarray, min_frames: int) -> InteractionDataset:
    """Every pair of `indices` from each of its later frames on (frames a..T-1 for a = 1.., at least `min_frames` long),
    each standardized from its own first frame: a take's windows begin mid-interaction, and these are what a
    network sees there."""
    from imm_model.data.sequence import Interaction

    crops = []
    for i in indices:
        leader, follower = data.world(i)
        frames = data.frame_numbers[data.frames(i)]
        for a in range(1, len(leader) - min_frames + 1):
            crops.append(Interaction(f"{data.sequence_ids[i]}@{a}", data.dataset, data.class_names[data.actions[i]],
                                     data.subject_pairs[i], leader[a:], follower[a:], data.leader_sources[i],
                                     data.leader_rules[i], frames[a:]))
    return InteractionDataset.from_interactions(crops, data.class_names, data.skeleton, data.canonical_mode)


def data_meta(data: InteractionDataset, subject: str | None, train_idx: np.ndarray) -> dict:
    """What a checkpoint records of the data it was trained on (both trainers' sidecars): what inference needs to read
    a leader as the training did, and which subject it never saw."""
    return {
        "skeleton": data.skeleton.to_dict(),
        "class_names": list(data.class_names),
        "canonical_mode": data.canonical_mode,
        "dataset": data.dataset,
        "held_out_subject": subject,
        "max_train_length": int(data.lengths[train_idx].max()),
    }


def derive_seed(*parts: int) -> int:
    """One seed from several (a run's seed, a step, ...): every trainer's random stream at a step, so that a resumed run
    draws what an uninterrupted one would."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0])
