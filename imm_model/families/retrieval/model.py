"""Nearest-neighbour retrieval as a model: the baseline every learned family must beat, behind the same API.

For a leader and a label it returns the real follower of the training leader nearest to it among the training
sequences of the asked class: the paper's NN baseline (evaluation/baselines.py `nn1` is this function with the true
class). Its checkpoint holds no weights: the sidecar names the training data it retrieves from (the bundle's content
hash, its file name and path) and the subject it never looks at.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.data.sequence import resample
from imm_model.errors import CheckpointError
from imm_model.families.base import ReactionModel, check_compatible

LATENT_FRAMES = 16  # the embedding resamples the leader and the retrieved follower to this many frames


def nearest_follower(leader: np.ndarray, candidates: Sequence[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """A canonical leader (T, J, 3) and canonical (leader, follower) pairs -> the follower (T, J, 3) float32 of the
    candidate whose leader, resampled to T frames, is nearest (mean per-frame pose-vector distance; the first on a
    tie), resampled to T frames."""
    t = len(leader)
    target = np.asarray(leader).reshape(t, -1).astype(np.float64)
    best, best_d = None, np.inf
    for cand_leader, cand_follower in candidates:
        cand = resample(np.asarray(cand_leader).reshape(len(cand_leader), -1).astype(np.float64), t)
        d = float(np.linalg.norm(cand - target, axis=-1).mean())
        if d < best_d:
            best, best_d = cand_follower, d
    if best is None:
        raise ValueError("no candidate to retrieve from")
    return resample(np.asarray(best).astype(np.float64), t).astype(np.float32)


def asked_classes(label: np.ndarray) -> np.ndarray:
    """A multi-hot label (C,) -> the classes a retrieval may answer with: the class asked for most (the largest
    positive value); with none asked, every class not avoided (value >= 0); with every class avoided, all of them."""
    label = np.asarray(label)
    if (label > 0).any():
        return np.array([int(np.argmax(label))])
    allowed = np.flatnonzero(label >= 0)
    return allowed if len(allowed) else np.arange(len(label))


class RetrievalReactionModel(ReactionModel):
    family = "retrieval"
    title = "1-NN retrieval"
    weights_prefix = "retrieval"

    def __init__(self, data, meta: dict[str, Any], path: Path | None = None, device: str = "cpu"):
        from imm_model.data.splits import loso_fold

        super().__init__({}, meta, path, device)
        check_compatible(self, data, f"{path}: its training data" if path else "training data")
        self.data = data
        train = np.arange(len(data)) if self.held_out_subject is None else loso_fold(data.subject_pairs, self.held_out_subject).train
        # canonical (leader, follower) pairs of each class, in training order
        self.pairs = [[data.canonical(int(j)) for j in train if data.actions[j] == c] for c in range(len(self.class_names))]

    @classmethod
    def build(cls, data, held_out_subject: str | None) -> RetrievalReactionModel:
        """Retrieval from `data` (a bundle read from a file, which the checkpoint names), never from
        `held_out_subject`'s sequences."""
        from imm_model.data.dataset import dataset_hash
        from imm_model.data.splits import loso_fold

        if data.path is None:
            raise CheckpointError("a retrieval model names the bundle file it retrieves from: give data read from a file")
        train = np.arange(len(data)) if held_out_subject is None else loso_fold(data.subject_pairs, held_out_subject).train
        meta = {"family": cls.family, "kind": "final", "skeleton": data.skeleton.to_dict(), "class_names": list(data.class_names),
                "canonical_mode": data.canonical_mode, "dataset": data.dataset, "held_out_subject": held_out_subject,
                "max_train_length": int(data.lengths[train].max()),
                "retrieval": {"data_hash": dataset_hash(data), "data_file": data.path.name},
                "train_config": {"name": "retrieval", "mirror_prob": 0.0, "mirror_exclude_classes": []}}
        return cls(data, meta)

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu",
                        data: Path | None = None):
        if arrays:
            raise CheckpointError(f"{path}: a retrieval checkpoint holds no weights, this one holds {len(arrays)} arrays")
        return cls(_training_data(meta, path, data), meta, path, device)

    def save(self, path: Path | str) -> None:
        """The checkpoint names its data by file name and content hash only (`_training_data` says where it is looked
        for)."""
        from imm_model.checkpoint import save_checkpoint

        meta = {k: v for k, v in self.info.items() if k not in ("format", "weights_sha256")}
        meta["retrieval"] = {k: v for k, v in meta["retrieval"].items() if k != "data_path"}
        save_checkpoint(path, {}, meta)

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        out = []
        for leader, label in zip(leaders, labels, strict=True):
            candidates = [pair for c in asked_classes(label) for pair in self.pairs[c]]
            out.append(nearest_follower(leader, candidates))
        return out

    def _clean(self, follower: np.ndarray) -> np.ndarray:
        """A retrieved follower is real motion: nothing to clean."""
        return follower.astype(np.float32)

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) labels -> (N, 2 * 16 * 3J): the leader and the follower it retrieves, each
        resampled to 16 frames (what the retrieval compares, and what it answers)."""
        labels = self._label_array(label_vectors, len(leaders))
        followers = self._network(leaders, labels, [0] * len(leaders))
        return np.stack([np.concatenate([resample(np.asarray(a, np.float64), LATENT_FRAMES).reshape(-1),
                                         resample(f.astype(np.float64), LATENT_FRAMES).reshape(-1)])
                         for a, f in zip(leaders, followers, strict=True)]).astype(np.float32)


def _training_data(meta: dict[str, Any], path: Path, named: Path | None = None):
    """The bundle a retrieval checkpoint names, if its content hash is the one recorded: the one the user names
    (`named`), else the file of its name beside the checkpoint or among the bundled data. A path written in the sidecar
    is never opened (whoever wrote the file chose it)."""
    from imm_model.data.dataset import InteractionDataset, dataset_hash
    from imm_model.errors import IMMError
    from imm_model.paths import SAMPLE_DIR

    source = meta.get("retrieval")
    if not (isinstance(source, dict) and all(isinstance(source.get(k), str) for k in ("data_hash", "data_file"))):
        raise CheckpointError(f"{path}: sidecar retrieval must name the training data (data_hash, data_file)")
    name = Path(source["data_file"]).name
    if name in ("", ".", ".."):
        raise CheckpointError(f"{path}: sidecar retrieval data_file {source['data_file'][:40]!r} names no file")
    candidates = [named] if named is not None else [path.parent / name, SAMPLE_DIR / name]
    for candidate in candidates:
        if not candidate.is_file():
            continue
        try:
            data = InteractionDataset.load(candidate)
        except IMMError:
            continue
        if dataset_hash(data) == source["data_hash"]:
            return data
    where = f"is not {named}" if named is not None else "is neither beside it nor among the bundled data (name it with --data)"
    raise CheckpointError(f"{path}: its training data {name} (content hash {source['data_hash']}) {where}")
