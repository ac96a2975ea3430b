"""Skeleton description as data: joints, bones, body parts and the vertical axis.

The model and the canonical frame only ever read a `Skeleton`; nothing else hard-codes joint
indices, so a second skeleton (e.g. a BVH rig) plugs in by describing itself here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Skeleton:
    name: str
    joint_names: tuple[str, ...]
    parents: tuple[int, ...]  # parent joint index per joint, -1 for the root
    # The model's hierarchical streams: five body parts (whole body is implicit = all joints).
    body_parts: dict[str, tuple[int, ...]] = field(default_factory=dict)
    vertical_axis: int = 1  # index of the "up" coordinate (Y for Kinect)
    # Joints used to derive facing: (left_hip, right_hip, left_shoulder, right_shoulder).
    facing_joints: tuple[int, int, int, int] = (0, 0, 0, 0)

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if len(self.parents) != n:
            raise ValueError(f"skeleton {self.name}: {len(self.parents)} parents for {n} joints")
        if sum(p < 0 for p in self.parents) != 1:
            raise ValueError(f"skeleton {self.name}: exactly one root joint (parent -1) is required")
        for part, joints in self.body_parts.items():
            if any(not 0 <= j < n for j in joints):
                raise ValueError(f"skeleton {self.name}: body part {part} names a joint outside 0..{n - 1}")

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def root(self) -> int:
        return self.parents.index(-1)

    @property
    def root_neighbours(self) -> list[int]:
        """The joints attached to the root (Kinect: neck and hips): their centre is a body frame that the root joint's
        own sway does not move."""
        return [j for j, p in enumerate(self.parents) if p == self.root]

    @property
    def bones(self) -> list[tuple[int, int]]:
        """(parent, child) pairs, one per non-root joint."""
        return [(p, j) for j, p in enumerate(self.parents) if p >= 0]

    @property
    def bones_from_root(self) -> list[tuple[int, int, int]]:
        """(parent, child, index into `bones`) with every parent placed before its children: the order in which a
        skeleton is rebuilt from its root outwards."""
        children: dict[int, list[tuple[int, int]]] = {}
        for k, (parent, child) in enumerate(self.bones):
            children.setdefault(parent, []).append((child, k))
        order, stack = [], [self.root]
        while stack:
            parent = stack.pop()
            for child, k in children.get(parent, []):
                order.append((parent, child, k))
                stack.append(child)
        return order

    @property
    def lateral_axis(self) -> int:
        """The horizontal axis across a body facing +forward: up x forward (X for Y-up, +Z forward)."""
        return (self.vertical_axis + 2) % 3

    @property
    def mirror_permutation(self) -> list[int]:
        """Joint permutation that swaps left_* and right_* joints (identity for the others)."""
        names = list(self.joint_names)
        perm = []
        for n in names:
            other = n.replace("left_", "\0").replace("right_", "left_").replace("\0", "right_")
            perm.append(names.index(other) if other in names else names.index(n))
        return perm

    def mirrored(self, positions: np.ndarray) -> np.ndarray:
        """positions (..., J, 3) -> their mirror image across the lateral axis, left and right joints swapped."""
        out = positions[..., self.mirror_permutation, :].copy()
        out[..., self.lateral_axis] *= -1
        return out

    def bone_lengths(self, positions: np.ndarray) -> np.ndarray:
        """positions (..., J, 3) -> bone lengths (..., J-1) in the positions' units."""
        parents = np.array([p for p, _ in self.bones])
        children = np.array([c for _, c in self.bones])
        return np.linalg.norm(positions[..., children, :] - positions[..., parents, :], axis=-1)

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "joint_names": list(self.joint_names),
            "parents": list(self.parents),
            "body_parts": {k: list(v) for k, v in self.body_parts.items()},
            "vertical_axis": self.vertical_axis,
            "facing_joints": list(self.facing_joints),
        }

    @classmethod
    def from_dict(cls, d: dict) -> Skeleton:
        return cls(
            name=str(d["name"]),
            joint_names=tuple(d["joint_names"]),
            parents=tuple(int(p) for p in d["parents"]),
            body_parts={k: tuple(int(j) for j in v) for k, v in d["body_parts"].items()},
            vertical_axis=int(d["vertical_axis"]),
            facing_joints=tuple(int(j) for j in d["facing_joints"]),  # type: ignore[arg-type]
        )


# SBU Kinect Interaction joint order (dataset README, 1-based there, 0-based here).
KINECT15 = Skeleton(
    name="kinect15",
    joint_names=(
        "head", "neck", "torso",
        "left_shoulder", "left_elbow", "left_hand",
        "right_shoulder", "right_elbow", "right_hand",
        "left_hip", "left_knee", "left_foot",
        "right_hip", "right_knee", "right_foot",
    ),
    parents=(1, 2, -1, 1, 3, 4, 1, 6, 7, 2, 9, 10, 2, 12, 13),
    body_parts={
        "left_arm": (3, 4, 5),
        "right_arm": (6, 7, 8),
        "left_leg": (9, 10, 11),
        "right_leg": (12, 13, 14),
        "trunk": (0, 1, 2),
    },
    vertical_axis=1,
    facing_joints=(9, 12, 3, 6),
)
