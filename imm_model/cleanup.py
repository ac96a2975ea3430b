"""Clean-up of a synthesized follower: one rigid skeleton, feet planted on the floor.

The network predicts 15 free joint positions per frame, so nothing holds its bones to one length (4-5 cm of error,
mostly a body size guessed anew for every sequence) or stops a foot on the floor from sliding. A studio user, and
any rig the motion is exported to, needs both. Two steps, on canonical metres (T, J, 3), numpy only (the studio
never imports torch):

1. `rigid_bones`: every bone set to one length (the training followers' median, stored in the checkpoint; or
   this sequence's own median), keeping each bone's direction, from the root outwards.
2. `plant_feet`: a foot within CONTACT_M of the sequence's lowest foot height is held where it stands, and the
   leg reaches it by two-bone inverse kinematics (the knee stays in the plane it bent in).

Bodies are not pushed apart: stepping the whole follower back until no bone axes came within 5 cm, tried, cost
1-2.5 % AFD, and real followers touch the leader that closely in 25 % of handshake frames and 48 % of hug frames.
Measured: docs/experiments/cleanup.md.
"""

from __future__ import annotations

import numpy as np

from imm_model.contact import CONTACT_M
from imm_model.skeleton import Skeleton

EASE_FRAMES = 2
# live, a planted foot is held where it touched down until the network's foot has slid this far from it, then dragged
# along this far behind: a follower made to walk on (after a walking leader) slides its feet over the floor, and a foot
# held where it touched down lagged the body (0.58 m in the test that slides a body 1 m) until it lifted and snapped
# back. On the held-out s04 clips the live reactor's foot skate is 0.029 m/s with it, 0.028 without (0.053 at 0.15 m)
PIN_REACH_M = 0.3


def clean_follower(follower: np.ndarray, skeleton: Skeleton, bone_lengths: np.ndarray | None = None) -> np.ndarray:
    """follower (T, J, 3) canonical metres -> the follower with rigid bones and planted feet."""
    return plant_feet(rigid_bones(follower, skeleton, bone_lengths), skeleton)


def rigid_bones(motion: np.ndarray, skeleton: Skeleton, bone_lengths: np.ndarray | None = None) -> np.ndarray:
    """Each bone (skeleton.bones order) at `bone_lengths` (default: its median over this motion), direction kept."""
    lengths = np.median(skeleton.bone_lengths(motion), axis=0) if bone_lengths is None else np.asarray(bone_lengths)
    out = motion.copy()
    for parent, child, k in skeleton.bones_from_root:
        out[:, child] = out[:, parent] + lengths[k] * _unit(motion[:, child] - motion[:, parent])
    return out


def plant_feet(motion: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Feet on the floor held still: a foot moves only once lifted (the network's drag along the floor is skating)."""
    names, up = skeleton.joint_names, skeleton.vertical_axis
    feet = [names.index(n) for n in ("left_foot", "right_foot") if n in names]
    if not feet or len(motion) < 2:
        return motion
    out = motion.copy()
    floor = motion[:, feet, up].min()
    for foot in feet:
        knee = skeleton.parents[foot]
        hip = skeleton.parents[knee]
        if knee < 0 or hip < 0:
            continue
        target = _planted(motion[:, foot], motion[:, foot, up] < floor + CONTACT_M, up)
        thigh = np.median(np.linalg.norm(motion[:, knee] - motion[:, hip], axis=-1))
        shin = np.median(np.linalg.norm(motion[:, foot] - motion[:, knee], axis=-1))
        out[:, knee], out[:, foot] = _two_bone_ik(motion[:, hip], motion[:, knee], target, thigh, shin)
    return out


def _planted(foot: np.ndarray, on_floor: np.ndarray, up: int) -> np.ndarray:
    """Foot path (T, 3) with its horizontal position held at the mean of each stretch of floor contact, eased back to
    the network's path over EASE_FRAMES frames on either side (a lifted foot leaves its spot, it does not jump)."""
    target, horizontal = foot.copy(), [a for a in range(3) if a != up]
    contact = np.flatnonzero(np.diff(np.r_[0, on_floor.astype(int), 0]))
    for start, end in contact.reshape(-1, 2):
        pin = foot[start:end, horizontal].mean(0)
        target[start:end, horizontal] = pin
        for k in range(1, EASE_FRAMES + 1):
            weight = 1 - k / (EASE_FRAMES + 1)
            for t in (start - k, end - 1 + k):
                if 0 <= t < len(foot) and not on_floor[t]:
                    target[t, horizontal] = weight * pin + (1 - weight) * foot[t, horizontal]
    return target


def _two_bone_ik(hip: np.ndarray, knee: np.ndarray, target: np.ndarray, thigh: float, shin: float) -> tuple[np.ndarray, np.ndarray]:
    """Knee and foot (T, 3) with the given bone lengths, the foot at `target` (or as near as the leg reaches), the
    knee on the side it was bent towards."""
    to_target = target - hip
    reach = np.linalg.norm(to_target, axis=-1, keepdims=True)
    reach = np.clip(reach, abs(thigh - shin) + 1e-4, thigh + shin - 1e-4)
    axis = _unit(to_target)
    along = (thigh**2 - shin**2 + reach**2) / (2 * reach)  # the knee's distance from the hip along the axis
    out_of_axis = np.sqrt(np.maximum(thigh**2 - along**2, 0.0))
    bend = knee - hip
    bend = bend - (bend * axis).sum(-1, keepdims=True) * axis
    straight = np.linalg.norm(bend, axis=-1) < 1e-6  # a straight leg bends nowhere yet: any perpendicular will do
    bend[straight] = np.cross(axis[straight], np.eye(3)[np.argmin(np.abs(axis[straight]), axis=-1)])
    bend = _unit(bend)
    return hip + along * axis + out_of_axis * bend, hip + reach * axis


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def follower_bone_lengths(followers: list[np.ndarray], skeleton: Skeleton) -> list[float]:
    """Median length of each bone over every frame of `followers` (the training followers): the clean-up's skeleton."""
    return np.median(np.concatenate([skeleton.bone_lengths(f) for f in followers]), axis=0).astype(float).tolist()


class OnlineCleanup:
    """The clean-up of a follower made frame by frame (the online reactor's): what `clean_follower` does, from the
    frames so far only. Bones rigid per frame; the floor is the lowest foot height so far; a foot on it is held where
    it touched down (the offline clean-up holds the contact's mean, which needs the contact's last frame), never more
    than PIN_REACH_M behind the network's foot, and eased back to the network's path over EASE_FRAMES frames once
    lifted."""

    def __init__(self, skeleton: Skeleton, bone_lengths: np.ndarray | None = None):
        self.skeleton, self.bone_lengths = skeleton, bone_lengths
        names = skeleton.joint_names
        self.feet = [names.index(n) for n in ("left_foot", "right_foot") if n in names
                     and skeleton.parents[names.index(n)] >= 0 and skeleton.parents[skeleton.parents[names.index(n)]] >= 0]
        self.floor = np.inf
        self.pins: dict[int, np.ndarray | None] = dict.fromkeys(self.feet)  # a foot on the floor: where it touched down
        self.lifted: dict[int, tuple[np.ndarray, int]] = {}  # a foot just lifted: its last pin, frames since

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """Follower frames (n, J, 3), the next n of the take -> cleaned (n, J, 3) float64."""
        out = rigid_bones(np.asarray(frames, np.float64), self.skeleton, self.bone_lengths)
        up = self.skeleton.vertical_axis
        horizontal = [a for a in range(3) if a != up]
        for t in range(len(out)):
            self.floor = min(self.floor, float(out[t, self.feet, up].min(initial=np.inf)))
            for foot in self.feet:
                knee = self.skeleton.parents[foot]
                hip = self.skeleton.parents[knee]
                target = out[t, foot].copy()
                if target[up] < self.floor + CONTACT_M:
                    if self.pins[foot] is None:
                        self.pins[foot] = target[horizontal].copy()
                    slid = target[horizontal] - self.pins[foot]
                    far = float(np.linalg.norm(slid))
                    if far > PIN_REACH_M:
                        self.pins[foot] = self.pins[foot] + slid * (1 - PIN_REACH_M / far)
                    target[horizontal] = self.pins[foot]
                elif self.pins[foot] is not None or foot in self.lifted:
                    pin, since = (self.pins[foot], 0) if self.pins[foot] is not None else self.lifted[foot]
                    self.pins[foot] = None
                    since += 1
                    weight = 1 - since / (EASE_FRAMES + 1)
                    target[horizontal] = weight * pin + (1 - weight) * target[horizontal]
                    if since < EASE_FRAMES:
                        self.lifted[foot] = (pin, since)
                    else:
                        self.lifted.pop(foot, None)
                if self.pins[foot] is not None:
                    self.lifted.pop(foot, None)
                thigh = np.linalg.norm(out[t, knee] - out[t, hip])
                shin = np.linalg.norm(out[t, foot] - out[t, knee])
                knee_at, foot_at = _two_bone_ik(out[t, hip][None], out[t, knee][None], target[None], thigh, shin)
                out[t, knee], out[t, foot] = knee_at[0], foot_at[0]
        return out
