"""Skeleton description as data: joints, bones, body parts and the vertical axis.

The model and the canonical frame only ever read a `Skeleton`; nothing else hard-codes joint
indices, so a second skeleton (e.g. a BVH rig) plugs in by describing itself here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from imm_model.typed_config import Interval, ListOf, Name, checked_kwargs, param, validate

MAX_JOINTS = 1000
JOINT = Interval(int, 0, MAX_JOINTS - 1)


@dataclass(frozen=True)
class Joints(ListOf):
    """A ListOf described with both of its length bounds (a skeleton's are part of what it must be)."""

    def __str__(self) -> str:
        size = str(self.min_length) if self.min_length == self.max_length else f"{self.min_length} to {self.max_length}"
        return f"a list of {size} {'distinct ' if self.unique else ''}items, each {self.item}"


@dataclass(frozen=True)
class NamedJointLists:
    """A JSON object of names, each a non-empty list of joint indices (a skeleton's body parts)."""

    def accepts(self, value: Any) -> bool:
        return isinstance(value, Mapping) and len(value) <= MAX_JOINTS and all(
            Name().accepts(k) and ListOf(JOINT, min_length=1, max_length=MAX_JOINTS).accepts(v) for k, v in value.items())

    def __str__(self) -> str:
        return "an object of part names, each a non-empty list of joint indices"


def _is_tree(skeleton: Skeleton) -> bool:
    """Following parents, every joint reaches the root: no cycle (each joint is walked once)."""
    reaches_root: set[int] = set()
    for j in range(skeleton.num_joints):
        path: set[int] = set()
        while j not in reaches_root and skeleton.parents[j] >= 0:
            if j in path:
                return False
            path.add(j)
            j = skeleton.parents[j]
        reaches_root |= path | {j}
    return True


def _within(joints, skeleton: Skeleton) -> bool:
    return all(j < skeleton.num_joints for j in joints)


@dataclass(frozen=True)
class Skeleton:
    """Checked as a whole when built (ValueError naming the field): whatever reads a skeleton indexes with it and walks
    its tree, so an index out of range would fail far from here and a cycle would never return."""

    name: str = param(check=Name())
    joint_names: tuple[str, ...] = param(check=Joints(Name(), min_length=1, max_length=MAX_JOINTS, unique=True))
    # parent joint index per joint, -1 for the root
    parents: tuple[int, ...] = param(check=Joints(Interval(int, -1, MAX_JOINTS - 1), min_length=1, max_length=MAX_JOINTS))
    # The model's hierarchical streams: five body parts (whole body is implicit = all joints).
    body_parts: dict[str, tuple[int, ...]] = param(check=NamedJointLists(), factory=dict)
    vertical_axis: int = param(1, Interval(int, 0, 2))  # index of the "up" coordinate (Y for Kinect)
    # Joints used to derive facing: (left_hip, right_hip, left_shoulder, right_shoulder).
    facing_joints: tuple[int, int, int, int] = param((0, 0, 0, 0), Joints(JOINT, min_length=4, max_length=4))

    RULES: ClassVar = (
        ("parents", lambda s: len(s.parents) == s.num_joints, "one per joint"),
        ("parents", lambda s: _within(s.parents, s) and s.parents.count(-1) == 1,
         "joint indices below the joint count, with -1 for exactly one root"),
        ("parents", _is_tree, "a tree: every joint reaches the root (these form a cycle)"),
        ("body_parts", lambda s: all(_within(js, s) for js in s.body_parts.values()), "joint indices below the joint count"),
        ("facing_joints", lambda s: _within(s.facing_joints, s), "joint indices below the joint count"),
    )

    def __post_init__(self) -> None:
        validate(self, "skeleton")

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
    def leg_joints(self) -> list[int]:
        """The joints of the body parts named "...leg" (Kinect: hips, knees, feet), sorted."""
        return sorted({j for name, joints in self.body_parts.items() if name.endswith("leg") for j in joints})

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
        """A skeleton from its JSON form (a checkpoint's sidecar, a bundle's metadata): every field required and
        checked (ValueError naming the first problem)."""
        d = checked_kwargs(cls, d, "skeleton")
        missing = [f.name for f in fields(cls) if f.name not in d]
        if missing:
            raise ValueError(f"skeleton lacks {', '.join(missing)}")
        return cls(
            name=d["name"],
            joint_names=tuple(d["joint_names"]),
            parents=tuple(d["parents"]),
            body_parts={k: tuple(v) for k, v in d["body_parts"].items()},
            vertical_axis=d["vertical_axis"],
            facing_joints=tuple(d["facing_joints"]),
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
