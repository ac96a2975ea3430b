"""Skeleton description as data: joints, bones, body parts and the vertical axis.

The model and the canonical frame only ever read a `Skeleton`; nothing else hard-codes joint
indices, so a second skeleton (e.g. a BVH rig) plugs in by describing itself here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from imm_model.typed_config import checked_kwargs

MAX_JOINTS = 1000


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
        """The description checked as a whole (ValueError naming the field): whatever reads a skeleton indexes with it
        and walks its tree, so an index out of range or a cycle would fail far from here, or never return."""
        n, where = len(self.joint_names), f"skeleton {str(self.name)[:40]}"
        if not 1 <= n <= MAX_JOINTS:
            raise ValueError(f"{where}: {n} joints; 1 to {MAX_JOINTS} are accepted")
        if not all(isinstance(j, str) and j for j in self.joint_names):
            raise ValueError(f"{where}: joint_names must be non-empty strings")
        if len(set(self.joint_names)) != n:
            raise ValueError(f"{where}: joint name {_first_repeat(self.joint_names)!r} is used twice")
        if len(self.parents) != n:
            raise ValueError(f"{where}: {len(self.parents)} parents for {n} joints")
        _check_indices(self.parents, n, f"{where}: parents", allow_root=True)
        if sum(p < 0 for p in self.parents) != 1:
            raise ValueError(f"{where}: exactly one root joint (parent -1) is required")
        _check_tree(self.parents, where)
        for part, joints in self.body_parts.items():
            if not isinstance(part, str) or not joints:
                raise ValueError(f"{where}: body part {part!r} must be named and list at least one joint")
            _check_indices(joints, n, f"{where}: body part {part}")
        if isinstance(self.vertical_axis, bool) or self.vertical_axis not in (0, 1, 2):
            raise ValueError(f"{where}: vertical_axis must be 0, 1 or 2 (x, y, z), not {self.vertical_axis!r}")
        if len(self.facing_joints) != 4:
            raise ValueError(f"{where}: facing_joints must be 4 joints (left hip, right hip, left shoulder, right shoulder)")
        _check_indices(self.facing_joints, n, f"{where}: facing_joints")

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
        """A skeleton from its JSON form (a checkpoint's sidecar, a bundle's metadata): every field required and
        checked (ValueError naming the first problem)."""
        d = checked_kwargs(cls, d, "skeleton")
        missing = [f.name for f in fields(cls) if f.name not in d]
        if missing:
            raise ValueError(f"skeleton lacks {', '.join(missing)}")
        parts = d["body_parts"]
        if not all(isinstance(v, list) and all(isinstance(j, int) and not isinstance(j, bool) for j in v) for v in parts.values()):
            raise ValueError("skeleton: body_parts must map each part's name to a list of joint indices")
        return cls(
            name=d["name"],
            joint_names=tuple(d["joint_names"]),
            parents=tuple(d["parents"]),
            body_parts={k: tuple(v) for k, v in parts.items()},
            vertical_axis=d["vertical_axis"],
            facing_joints=tuple(d["facing_joints"]),
        )


def _check_indices(joints: tuple[int, ...], n: int, what: str, allow_root: bool = False) -> None:
    low = -1 if allow_root else 0
    bad = next((j for j in joints if isinstance(j, bool) or not isinstance(j, int | np.integer) or not low <= j < n), None)
    if bad is not None:
        raise ValueError(f"{what} names joint {bad!r}; the indices are {low}..{n - 1}")


def _check_tree(parents: tuple[int, ...], where: str) -> None:
    """Every joint reaches the root by following parents (no cycle); each joint is walked once."""
    reaches: set[int] = set()
    for j in range(len(parents)):
        path = []
        while j not in reaches and parents[j] >= 0:
            if j in path:
                raise ValueError(f"{where}: parents form a cycle through joint {j}")
            path.append(j)
            j = parents[j]
        reaches.update(path)
        reaches.add(j)


def _first_repeat(names: tuple[str, ...]) -> str:
    seen: set[str] = set()
    for n in names:
        if n in seen:
            return n
        seen.add(n)
    return ""


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
