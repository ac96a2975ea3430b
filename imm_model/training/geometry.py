"""Geometric training terms on a predicted follower in metres, beside the diffusion model's x0 error (as MDM's foot
contact loss, Tevet et al. 2023): the coordinate error weighs a foot's few centimetres of drag and the torso's tilt
like any other coordinate, so neither is learnt unless asked for.

- foot_contact: squared horizontal displacement per frame of each predicted foot over the steps on which the real
  follower's foot is on the floor (within CONTACT_M of the sequence's lowest foot height at both ends, the
  evaluation's skating rule), in m^2.
- torso: squared distance between the predicted and the real torso's unit direction (hips' centre to the neck), per
  frame; 2 - 2 cos of the angle between them.
"""

from __future__ import annotations

import torch

from imm_model.contact import CONTACT_M
from imm_model.skeleton import Skeleton


class GeometricTerms:
    """pred, real (B, T, J, 3) metres, mask (B, T) bool -> {"foot_contact": scalar, "torso": scalar}."""

    def __init__(self, skeleton: Skeleton):
        names = skeleton.joint_names
        self.up = skeleton.vertical_axis
        self.horizontal = [a for a in range(3) if a != self.up]
        self.feet = [names.index(n) for n in ("left_foot", "right_foot") if n in names]
        self.neighbours = skeleton.root_neighbours

    def __call__(self, pred: torch.Tensor, real: torch.Tensor, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        zero = pred.new_zeros(())
        return {"foot_contact": self.foot_contact(pred, real, mask) if self.feet else zero,
                "torso": self.torso(pred, real, mask) if len(self.neighbours) >= 2 else zero}

    def foot_contact(self, pred: torch.Tensor, real: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        height = real[:, :, self.feet, self.up]  # (B, T, F)
        floor = height.masked_fill(~mask[..., None], float("inf")).amin((1, 2), keepdim=True)
        on_floor = (height < floor + CONTACT_M) & mask[..., None]
        planted = (on_floor[:, 1:] & on_floor[:, :-1]).float()  # (B, T-1, F)
        step = pred[:, 1:, self.feet][..., self.horizontal] - pred[:, :-1, self.feet][..., self.horizontal]
        return ((step**2).sum(-1) * planted).sum() / planted.sum().clamp(min=1.0)

    def torso(self, pred: torch.Tensor, real: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        m = mask.float()
        # the top of the torso is the root neighbour that stands highest in the real followers (Kinect: the neck), as
        # the evaluation's lean picks it
        height = (real[:, :, self.neighbours, self.up] * m[..., None]).sum((0, 1))
        top = self.neighbours[int(height.argmax())]
        rest = [j for j in self.neighbours if j != top]

        def direction(x: torch.Tensor) -> torch.Tensor:
            v = x[:, :, top] - x[:, :, rest].mean(2)
            return v / v.norm(dim=-1, keepdim=True).clamp(min=1e-6)

        return (((direction(pred) - direction(real)) ** 2).sum(-1) * m).sum() / m.sum().clamp(min=1.0)
