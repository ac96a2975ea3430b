"""One .npz layout for every synthesized interaction the project writes (`imm generate`, the studio's export);
`imm generate --leader` reads it back. docs/formats.md describes each key.

World positions come with the canonical ones (A's root at the origin, A facing +Z, Y up) and with what is needed
to read them: the skeleton's joint names and parents, the frame rate, the classes, the label and the model.
"""

from __future__ import annotations

import io

import numpy as np

from imm_model.data.canonical import CanonicalFrame
from imm_model.data.labels import label_text
from imm_model.skeleton import Skeleton

FORMAT = "imm-interaction-1"


def interaction_arrays(leader: np.ndarray, follower: np.ndarray, frame: CanonicalFrame, skeleton: Skeleton, *,
                       class_names, label: np.ndarray, scale: float, checkpoint: str, fps: float,
                       ground_truth: np.ndarray | None = None, sequence_id: str | None = None,
                       seed: int | None = None, spread: float | None = None,
                       memory: float | None = None, live: tuple[int, list[tuple[int, str]]] | None = None) -> dict[str, np.ndarray]:
    """leader, follower (and ground truth): (T, J, 3) world metres -> the file's arrays. `seed`: the sampler seed that
    drew the follower (stochastic models only), so the same reaction can be drawn again; `spread`: the sampler's
    leader noise it was drawn with (models trained with noised leaders only); `memory`: the noise level its sampler
    started at from the reaction memory (only when it did); `live`: a follower made frame by frame as the leader played
    (the studio's live mode): how many of its first frames were made so, and each label it was steered with from the
    frame it took effect (the rest of the frames are the offline reaction to the last label)."""
    out = {
        "format": np.array(FORMAT),
        "leader": np.asarray(leader, np.float32),
        "follower": np.asarray(follower, np.float32),
        "leader_canonical": frame.to_canonical(np.asarray(leader, np.float64), skeleton).astype(np.float32),
        "follower_canonical": frame.to_canonical(np.asarray(follower, np.float64), skeleton).astype(np.float32),
        "joint_names": np.array(skeleton.joint_names),
        "parents": np.array(skeleton.parents, np.int64),
        "fps": np.float32(fps),
        "class_names": np.array(list(class_names)),
        "label": np.asarray(label, np.float32),
        "label_text": np.array(label_text(label, class_names)),
        "scale": np.float32(scale),
        "checkpoint": np.array(checkpoint),
    }
    if ground_truth is not None:
        out["ground_truth"] = np.asarray(ground_truth, np.float32)
        out["ground_truth_canonical"] = frame.to_canonical(np.asarray(ground_truth, np.float64), skeleton).astype(np.float32)
    if sequence_id is not None:
        out["sequence_id"] = np.array(sequence_id)
    if seed is not None:
        out["seed"] = np.int64(seed)
    if spread is not None:
        out["spread"] = np.float32(spread)
    if memory is not None:
        out["memory"] = np.float32(memory)
    if live is not None:
        made, steered = live
        out["live_frames"] = np.int64(made)
        out["live_label_from"] = np.array([f for f, _ in steered], np.int64)
        out["live_label_text"] = np.array([t for _, t in steered])
    return out


def interaction_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()
