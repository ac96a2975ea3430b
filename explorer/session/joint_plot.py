"""A quantity of chosen joints per frame, which the chart under the view plots in place of its error and contact: the
distance between two joints, each of the leader (A) or the follower (B), or the speed of one of the follower's joints.
Each is read off the synthesized follower and, where the take has one, the ground truth, in world metres (what the
view shows; the canonical frame of a `per_frame` dataset would take the leader's own motion out of a speed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from explorer.session.files import FPS

KINDS = ("distance", "speed")
UNITS = {"distance": "metres", "speed": "m/s"}


@dataclass(frozen=True)
class JointPlot:
    """`kind` "distance" with two joints, or "speed" with one of the follower's; a joint is "A.<name>" (the leader's)
    or "B.<name>" (the follower's), <name> one of the skeleton's joint names (imm_model/skeleton.py)."""

    kind: str
    joints: tuple[str, ...]

    def text(self) -> str:
        """As the page's link holds it: "distance:A.right_hand:B.right_hand", "speed:B.right_hand"."""
        return ":".join((self.kind, *self.joints))

    @classmethod
    def parse(cls, text: str, joint_names) -> JointPlot:
        """The link's text -> the plot; ValueError, one line, for anything else."""
        kind, *joints = str(text).split(":")
        if kind not in KINDS:
            raise ValueError(f"plot {text[:40]!r} is not distance:<joint>:<joint> nor speed:<joint>")
        wanted = 2 if kind == "distance" else 1
        names = {f"{who}.{name}" for who in "AB" for name in joint_names}
        if len(joints) != wanted or not set(joints) <= names or (kind == "speed" and not joints[0].startswith("B.")):
            raise ValueError(f"plot {text[:40]!r}: {'two joints (A.<joint> or B.<joint>)' if wanted == 2 else 'one joint of B'}"
                             f" of {', '.join(joint_names)}")
        return cls(kind, tuple(joints))

    @property
    def unit(self) -> str:
        return UNITS[self.kind]

    def series(self, session) -> dict[str, np.ndarray]:
        """(T,) per frame: {"follower": the synthesized follower's, "truth": the ground truth's} (no "truth" without
        one), or {"leader": ...} for a distance between two of the leader's joints (one line: no follower in it)."""
        leader = session.world(session.leader)
        if all(j.startswith("A.") for j in self.joints):
            return {"leader": self._values({"A": leader}, session.data.skeleton.joint_names)}
        followers = {"follower": session.synth, "truth": session.ground_truth}
        return {key: self._values({"A": leader, "B": session.world(follower)}, session.data.skeleton.joint_names)
                for key, follower in followers.items() if follower is not None}

    def _values(self, bodies: dict[str, np.ndarray], joint_names) -> np.ndarray:
        """(T,) the quantity over `bodies` ({"A": (T, J, 3), "B": ...} world metres)."""
        points = [bodies[j[0]][:, list(joint_names).index(j[2:])] for j in self.joints]
        return np.linalg.norm(points[0] - points[1], axis=-1) if self.kind == "distance" else speed(points[0])


def speed(points: np.ndarray) -> np.ndarray:
    """(T, 3) world metres -> (T,) m/s, by central differences (one-sided at the ends), as the view's joint readout."""
    return np.linalg.norm(np.gradient(points, axis=0), axis=-1) * FPS if len(points) > 1 else np.zeros(len(points))
