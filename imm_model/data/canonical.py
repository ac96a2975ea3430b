"""The canonical frame: the paper's standardization, on which every metric depends.

Both characters are expressed relative to the leader A: A's root joint is moved to the origin and
A's rotation about the vertical axis is removed, so that A faces one fixed direction (the axis after
the vertical one: +Z for Kinect's Y-up frame).

Facing is derived from the hips and shoulders: the "across" vector (left hip - right hip) +
(left shoulder - right shoulder) is projected onto the horizontal plane and forward =
across x up. On SBU this forward points at the partner in the great majority of sequences
(checked in tests), i.e. the Kinect left/right labels are not mirrored.

Two modes:
- ``first_frame`` (default): one rigid transform per sequence: origin = A's root at the first
  frame, facing = A's mean facing over the first `FACING_WINDOW` frames. A's motion during the
  sequence (stepping in to push, leaning back) is kept, which the follower's reaction depends on.
  Why a window: Kinect's hip/shoulder estimates are noisy frame to frame. On the 197 SBU sequences
  the spread (std) of B's mean sideways position in A's frame is 0.55 m with frame 0's facing alone
  and 0.45 m with the mean over the first 10 frames (SBU's shortest sequence), i.e. A's facing is
  estimated better and less of B's placement looks random to the model.
- ``per_frame``: translation and yaw of A removed at every frame.

Either way the transform is a rotation about the vertical axis plus a translation per frame, so
bone lengths are unchanged, and `to_world` inverts `to_canonical` exactly (to float precision).
"""

from __future__ import annotations

import typing
from dataclasses import dataclass
from typing import Literal

import numpy as np

from imm_model.skeleton import Skeleton

CanonicalMode = Literal["first_frame", "per_frame"]
CANONICAL_MODES: tuple[str, ...] = typing.get_args(CanonicalMode)
FACING_WINDOW = 10  # frames (0.67 s at 15 fps) averaged for A's facing in first_frame mode


def facing_direction(positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """positions (T, J, 3) -> unit horizontal forward vectors (T, 3) (zero where undefined)."""
    lhip, rhip, lsh, rsh = skeleton.facing_joints
    across = (positions[:, lhip] - positions[:, rhip]) + (positions[:, lsh] - positions[:, rsh])
    up = np.zeros(3)
    up[skeleton.vertical_axis] = 1.0
    forward = np.cross(across, up)
    forward[:, skeleton.vertical_axis] = 0.0
    norm = np.linalg.norm(forward, axis=-1, keepdims=True)
    return np.where(norm > 1e-9, forward / np.maximum(norm, 1e-12), 0.0)


def _axes(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (up, fixed forward, up x forward) of the canonical frame."""
    up = np.zeros(3)
    up[skeleton.vertical_axis] = 1.0
    fwd = np.zeros(3)
    fwd[(skeleton.vertical_axis + 1) % 3] = 1.0
    return up, fwd, np.cross(up, fwd)


def yaw_rotation(yaw: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """yaw (T,) radians -> rotation matrices (T, 3, 3) about the vertical axis (Rodrigues)."""
    up, _, _ = _axes(skeleton)
    k = np.array([[0, -up[2], up[1]], [up[2], 0, -up[0]], [-up[1], up[0], 0]])
    s, c = np.sin(yaw)[:, None, None], np.cos(yaw)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


@dataclass(frozen=True)
class CanonicalFrame:
    """Per-frame transform world -> canonical: p_c = R(-yaw_t) (p - origin_t)."""

    yaw: np.ndarray  # (T,) radians: A's facing measured from the fixed forward axis
    origin: np.ndarray  # (T, 3) metres: A's root position
    mode: str

    @classmethod
    def from_leader(
        cls, leader: np.ndarray, skeleton: Skeleton, mode: CanonicalMode = "first_frame"
    ) -> CanonicalFrame:
        """leader (T, J, 3) world positions of A -> the frame that standardizes them."""
        if mode not in CANONICAL_MODES:
            raise ValueError(f"unknown canonical mode {mode!r} ({' or '.join(CANONICAL_MODES)})")
        _, fwd, side = _axes(skeleton)
        facing = facing_direction(leader, skeleton)
        yaw = np.arctan2(facing @ side, facing @ fwd)  # 0 where facing is undefined
        origin = leader[:, skeleton.root].astype(np.float64)
        if mode == "first_frame":
            mean_facing = facing[:FACING_WINDOW].mean(axis=0)
            yaw = np.full(len(leader), np.arctan2(mean_facing @ side, mean_facing @ fwd))
            origin = np.repeat(origin[:1], len(leader), axis=0)
        return cls(yaw=yaw.astype(np.float64), origin=origin, mode=mode)

    def to_canonical(self, positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
        """(T, J, 3) world -> (T, J, 3) canonical, float64."""
        rot_inv = yaw_rotation(-self.yaw, skeleton)  # (T, 3, 3)
        return np.einsum("tij,tkj->tki", rot_inv, positions - self.origin[:, None, :])

    def to_world(self, positions: np.ndarray, skeleton: Skeleton) -> np.ndarray:
        """(T, J, 3) canonical -> (T, J, 3) world, float64. Exact inverse of `to_canonical`."""
        rot = yaw_rotation(self.yaw, skeleton)
        return np.einsum("tij,tkj->tki", rot, positions) + self.origin[:, None, :]


def joined(clips: list[tuple[np.ndarray, ...]], skeleton: Skeleton) -> tuple[tuple[np.ndarray, ...], list[int]]:
    """Clips as (leader, motions moved with it...) (T_i, J, 3) -> one continuous take of each, every clip moved rigidly
    (turned about the vertical, shifted) so that its leader starts where and as the leader before it ended (its first
    root above the last one's last, its first frames' facing the last ones'), and the frame each clip starts at. A long
    take made of short recorded ones, in which the leader walks on and never jumps back."""
    out, starts = [list(clips[0])], [0]
    for clip in clips[1:]:
        prev = out[-1][0]
        tail = CanonicalFrame.from_leader(prev[::-1], skeleton)  # the facing over the last frames
        own = CanonicalFrame.from_leader(clip[0], skeleton)
        n, up = len(clip[0]), skeleton.vertical_axis
        start = prev[-1, skeleton.root].copy()
        start[up] = clip[0][0, skeleton.root, up]  # its own height: the floor stays the floor
        there = CanonicalFrame(np.full(n, tail.yaw[0]), np.repeat(start[None], n, 0), "first_frame")
        starts.append(starts[-1] + len(prev))
        out.append([there.to_world(own.to_canonical(m, skeleton), skeleton) for m in clip])
    return tuple(np.concatenate(parts) for parts in zip(*out, strict=True)), starts
