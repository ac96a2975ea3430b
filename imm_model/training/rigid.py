"""The clean-up's rigid bones (cleanup.py) as a differentiable step, so that training scores what inference ships.

Without it the generator is free to stretch and shrink bones, and a label critic can be satisfied by body
proportions that the clean-up then takes away. Tried and not adopted: the limbs nearly stopped (docs/training.md,
"Session 12: three more training variants").
"""

from __future__ import annotations

import torch

from imm_model.skeleton import Skeleton


class RigidBones:
    """Rebuild a skeleton from its root outwards, each bone at a fixed length along the network's bone direction."""

    def __init__(self, skeleton: Skeleton, lengths, device: torch.device | str = "cpu"):
        self.order = skeleton.bones_from_root
        self.root, self.num_joints = skeleton.root, skeleton.num_joints
        self.lengths = torch.as_tensor(lengths, dtype=torch.float32, device=device)

    def __call__(self, motion: torch.Tensor) -> torch.Tensor:
        """(B, T, 3J) -> (B, T, 3J) with every bone at its length (padding frames collapse onto the root)."""
        x = motion.unflatten(-1, (self.num_joints, 3))
        joints: list[torch.Tensor | None] = [None] * self.num_joints
        joints[self.root] = x[..., self.root, :]
        for parent, child, k in self.order:
            bone = x[..., child, :] - x[..., parent, :]
            joints[child] = joints[parent] + self.lengths[k] * bone / bone.norm(dim=-1, keepdim=True).clamp_min(1e-6)
        return torch.stack(joints, dim=-2).flatten(-2)
