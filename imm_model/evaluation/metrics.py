"""Metrics as the paper defines them.

AFD (average frame distance): for one sequence, the mean over its valid frames of the Euclidean norm
of the difference between the synthesized and the ground-truth follower pose vectors (15 joints x 3
= 45 numbers). The paper reports it in SBU's normalized units, so both poses are first put back in
the world (inverse canonical transform) and into those units; the transform is affine per axis, so
this is exact. Per class = mean over that class's test sequences.

AFD squared: the same mean over frames of the *squared* norm, which is what the authors' public code
computes (named apart so that nobody compares it with the paper's table by mistake).

AFD parts (`afd_parts`, metres): where a follower's distance from the real one comes from. The root's offset on
the first frame (where the follower stands when the interaction starts: the leader's motion alone does not say),
the root's mean offset over the sequence, and the joints' mean offset relative to their own root (the limbs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from imm_model.data.canonical import CanonicalFrame
from imm_model.data.sbu import metres_to_normalized
from imm_model.skeleton import Skeleton


def frame_distances(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """pred, gt (T, J, 3) in the same units -> (T,) norm of the per-frame pose-vector difference."""
    if pred.shape != gt.shape:
        raise ValueError(f"prediction shape {pred.shape} differs from ground truth {gt.shape}")
    diff = (np.asarray(pred, np.float64) - np.asarray(gt, np.float64)).reshape(len(gt), -1)
    return np.linalg.norm(diff, axis=-1)


def afd(
    pred_canonical: np.ndarray,
    gt_canonical: np.ndarray,
    frame: CanonicalFrame,
    skeleton: Skeleton,
    units: str = "normalized",
    squared: bool = False,
) -> float:
    """AFD of one sequence. units: "normalized" (SBU dataset units, as in the paper) or "metres"."""
    power = 2 if squared else 1
    if units == "metres":
        # The canonical transform is rigid, so distances are the same in the canonical frame.
        return float((frame_distances(pred_canonical, gt_canonical) ** power).mean())
    if units != "normalized":
        raise ValueError(f"units must be 'normalized' or 'metres', not {units!r}")
    pred = metres_to_normalized(frame.to_world(np.asarray(pred_canonical, np.float64), skeleton))
    gt = metres_to_normalized(frame.to_world(np.asarray(gt_canonical, np.float64), skeleton))
    return float((frame_distances(pred, gt) ** power).mean())


def afd_parts(pred_canonical: np.ndarray, gt_canonical: np.ndarray, root: int) -> dict[str, float]:
    """(T, J, 3) canonical metres, both -> {start_root_m, root_m, limb_m} (module docstring)."""
    pred, gt = np.asarray(pred_canonical, np.float64), np.asarray(gt_canonical, np.float64)
    if pred.shape != gt.shape:
        raise ValueError(f"prediction shape {pred.shape} differs from ground truth {gt.shape}")
    root_offset = np.linalg.norm(pred[:, root] - gt[:, root], axis=-1)  # (T,)
    limbs = (pred - pred[:, root:root + 1]) - (gt - gt[:, root:root + 1])
    return {"start_root_m": float(root_offset[0]), "root_m": float(root_offset.mean()),
            "limb_m": float(np.linalg.norm(limbs, axis=-1).mean())}


def per_class_mean(values: Mapping[int, float], actions: np.ndarray, class_names: Sequence[str]) -> dict[str, float]:
    """{sequence index: value} -> {class name: mean over that class's sequences} (classes present only)."""
    out: dict[str, float] = {}
    for c, name in enumerate(class_names):
        vals = [v for i, v in values.items() if actions[i] == c]
        if vals:
            out[name] = float(np.mean(vals))
    return out
