"""`InteractionDataset`: many interactions in the canonical frame, as flat arrays.

This is what the model trains on, what the studio shows and what `sample_data/` bundles. Frames of
all sequences are concatenated (F = total frames) and `offsets[i]:offsets[i]+lengths[i]` selects
sequence i, which keeps the bundle small and loading a single `np.load`.
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imm_model.data.canonical import CANONICAL_MODES, CanonicalFrame, CanonicalMode
from imm_model.data.sequence import MAX_COORDINATE_M, Interaction
from imm_model.errors import DataFormatError
from imm_model.skeleton import KINECT15, Skeleton

FORMAT_VERSION = 1
MAX_BUNDLE_BYTES = 256_000_000  # arrays, uncompressed: about 600,000 frames (the SBU sample's 6,822 take 2 MB)
_ARRAYS = ("leader", "follower", "yaw", "origin", "frame_numbers", "lengths", "actions", "held_out")


@dataclass
class InteractionDataset:
    skeleton: Skeleton
    class_names: tuple[str, ...]
    sequence_ids: list[str]
    subject_pairs: list[str]
    leader_sources: list[str]
    leader_rules: list[str]
    actions: np.ndarray  # (N,) int64 index into class_names
    lengths: np.ndarray  # (N,) int64 frames per sequence
    leader: np.ndarray  # (F, J, 3) float32, canonical frame, metres
    follower: np.ndarray  # (F, J, 3) float32, canonical frame, metres
    yaw: np.ndarray  # (F,) float64 canonical -> world rotation about the vertical axis
    origin: np.ndarray  # (F, 3) float64 canonical -> world translation (A's root)
    frame_numbers: np.ndarray  # (F,) int64 original frame numbers
    held_out: np.ndarray  # (N,) bool: not seen by the bundled model during training
    dataset: str = "sbu"
    canonical_mode: str = "first_frame"
    info: dict = field(default_factory=dict)  # provenance: source, held-out subject, ...
    path: Path | None = None  # the bundle file it was read from (None: built in memory)

    # ---- construction -------------------------------------------------------------------
    @classmethod
    def from_interactions(
        cls,
        interactions: Sequence[Interaction],
        class_names: Sequence[str],
        skeleton: Skeleton = KINECT15,
        mode: CanonicalMode = "first_frame",
        info: dict | None = None,
    ) -> InteractionDataset:
        if not interactions:
            raise ValueError("no interactions to build a dataset from")
        class_names = tuple(class_names)
        leaders, followers, yaws, origins = [], [], [], []
        for it in interactions:
            if it.action not in class_names:
                raise ValueError(f"{it.sequence_id}: class {it.action!r} not in {class_names}")
            if it.leader.shape[1:] != (skeleton.num_joints, 3):
                raise DataFormatError(
                    f"{it.sequence_id}: {it.leader.shape[1]} joints, skeleton {skeleton.name} has {skeleton.num_joints}"
                )
            frame = CanonicalFrame.from_leader(it.leader, skeleton, mode)
            leaders.append(frame.to_canonical(it.leader, skeleton))
            followers.append(frame.to_canonical(it.follower, skeleton))
            yaws.append(frame.yaw)
            origins.append(frame.origin)
        return cls(
            skeleton=skeleton,
            class_names=class_names,
            sequence_ids=[it.sequence_id for it in interactions],
            subject_pairs=[it.subject_pair for it in interactions],
            leader_sources=[it.leader_source for it in interactions],
            leader_rules=[it.leader_rule for it in interactions],
            actions=np.array([class_names.index(it.action) for it in interactions], dtype=np.int64),
            lengths=np.array([it.num_frames for it in interactions], dtype=np.int64),
            leader=np.concatenate(leaders).astype(np.float32),
            follower=np.concatenate(followers).astype(np.float32),
            yaw=np.concatenate(yaws),
            origin=np.concatenate(origins),
            frame_numbers=np.concatenate([it.frame_numbers for it in interactions]).astype(np.int64),
            held_out=np.zeros(len(interactions), dtype=bool),
            dataset=interactions[0].dataset,
            canonical_mode=mode,
            info=dict(info or {}),
        )

    # ---- access -------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.sequence_ids)

    @property
    def offsets(self) -> np.ndarray:
        """(N,) first frame of each sequence in the flat arrays."""
        return np.concatenate([[0], np.cumsum(self.lengths)[:-1]]).astype(np.int64)

    def frames(self, i: int) -> slice:
        start = int(self.offsets[i])
        return slice(start, start + int(self.lengths[i]))

    def canonical(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Sequence i -> (leader, follower), each (T, J, 3) float32 in the canonical frame."""
        s = self.frames(i)
        return self.leader[s], self.follower[s]

    def frame_of(self, i: int) -> CanonicalFrame:
        s = self.frames(i)
        return CanonicalFrame(yaw=self.yaw[s], origin=self.origin[s], mode=self.canonical_mode)

    def world(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Sequence i -> (leader, follower) back in world metres, float64."""
        leader, follower = self.canonical(i)
        frame = self.frame_of(i)
        return frame.to_world(leader.astype(np.float64), self.skeleton), frame.to_world(
            follower.astype(np.float64), self.skeleton
        )

    def action_name(self, i: int) -> str:
        return self.class_names[int(self.actions[i])]

    def index_of(self, sequence_id: str) -> int:
        try:
            return self.sequence_ids.index(sequence_id)
        except ValueError:
            raise KeyError(f"unknown sequence {sequence_id!r}") from None

    def subset(self, indices: Sequence[int] | np.ndarray) -> InteractionDataset:
        idx = [int(i) for i in indices]
        frame_idx = np.concatenate([np.arange(self.frames(i).start, self.frames(i).stop) for i in idx]) if idx else np.zeros(0, int)
        pick = lambda xs: [xs[i] for i in idx]  # noqa: E731
        return InteractionDataset(
            skeleton=self.skeleton,
            class_names=self.class_names,
            sequence_ids=pick(self.sequence_ids),
            subject_pairs=pick(self.subject_pairs),
            leader_sources=pick(self.leader_sources),
            leader_rules=pick(self.leader_rules),
            actions=self.actions[idx],
            lengths=self.lengths[idx],
            leader=self.leader[frame_idx],
            follower=self.follower[frame_idx],
            yaw=self.yaw[frame_idx],
            origin=self.origin[frame_idx],
            frame_numbers=self.frame_numbers[frame_idx],
            held_out=self.held_out[idx],
            dataset=self.dataset,
            canonical_mode=self.canonical_mode,
            info=dict(self.info),
        )

    def role_swapped(self) -> InteractionDataset:
        """Role-swap augmentation: every sequence with B as the leader, re-canonicalized on B."""
        interactions = []
        for i in range(len(self)):
            leader, follower = self.world(i)
            s = self.frames(i)
            interactions.append(
                Interaction(
                    sequence_id=f"{self.sequence_ids[i]}:swapped",
                    dataset=self.dataset,
                    action=self.action_name(i),
                    subject_pair=self.subject_pairs[i],
                    leader=follower,
                    follower=leader,
                    leader_source=f"not {self.leader_sources[i]}",
                    leader_rule=f"swapped({self.leader_rules[i]})",
                    frame_numbers=self.frame_numbers[s],
                )
            )
        swapped = InteractionDataset.from_interactions(
            interactions, self.class_names, self.skeleton, self.canonical_mode, info=self.info  # type: ignore[arg-type]
        )
        swapped.held_out = self.held_out.copy()
        return swapped

    # ---- persistence --------------------------------------------------------------------
    def metadata(self) -> dict:
        return {
            "format_version": FORMAT_VERSION,
            "dataset": self.dataset,
            "canonical_mode": self.canonical_mode,
            "skeleton": self.skeleton.to_dict(),
            "class_names": list(self.class_names),
            "sequence_ids": self.sequence_ids,
            "subject_pairs": self.subject_pairs,
            "leader_sources": self.leader_sources,
            "leader_rules": self.leader_rules,
            "info": self.info,
        }

    def save(self, path: Path | str, replace: bool = True) -> None:
        """Write a compressed .npz, byte-for-byte reproducible (fixed zip timestamps and order), atomically (through a
        temporary name of its own); without `replace`, an existing file is refused (outputs.write_files)."""
        from imm_model.outputs import write_atomic

        arrays = {name: np.ascontiguousarray(getattr(self, name)) for name in _ARRAYS}
        arrays["metadata"] = np.frombuffer(json.dumps(self.metadata(), sort_keys=True).encode(), dtype=np.uint8)

        def write(tmp: Path) -> None:
            with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
                for name in sorted(arrays):
                    buf = io.BytesIO()
                    np.lib.format.write_array(buf, arrays[name], allow_pickle=False)
                    zi = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                    zi.compress_type = zipfile.ZIP_DEFLATED
                    zi.external_attr = 0o644 << 16
                    zf.writestr(zi, buf.getvalue(), compresslevel=9)

        write_atomic(path, write, replace)

    @classmethod
    def load(cls, path: Path | str) -> InteractionDataset:
        """Read a bundle written by `save`. Never unpickles, never allocates more than MAX_BUNDLE_BYTES: a malformed
        file gives a one-line error naming it (and the field)."""
        from imm_model.data.npz import read_npz

        path = Path(path)
        if not path.exists():
            raise DataFormatError(f"{path}: data file not found")
        arrays = read_npz(path, (*_ARRAYS, "metadata"), MAX_BUNDLE_BYTES, "interaction bundle")
        try:
            meta = json.loads(arrays.pop("metadata").tobytes().decode())
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
            raise DataFormatError(f"{path}: unreadable bundle metadata ({type(err).__name__})") from None
        if not isinstance(meta, dict):
            raise DataFormatError(f"{path}: bundle metadata is not a JSON object")
        if meta.get("format_version") != FORMAT_VERSION:
            raise DataFormatError(f"{path}: bundle format {meta.get('format_version')!r} (this version reads {FORMAT_VERSION})")
        try:
            ds = cls(
                skeleton=Skeleton.from_dict(meta["skeleton"]),
                class_names=_strings(meta["class_names"], "class_names", unique=True),
                sequence_ids=list(_strings(meta["sequence_ids"], "sequence_ids")),
                subject_pairs=list(_strings(meta["subject_pairs"], "subject_pairs")),
                leader_sources=list(_strings(meta["leader_sources"], "leader_sources")),
                leader_rules=list(_strings(meta["leader_rules"], "leader_rules")),
                dataset=str(meta["dataset"]),
                canonical_mode=str(meta["canonical_mode"]),
                info=dict(meta.get("info", {})),
                path=path.resolve(),
                **arrays,
            )
        except KeyError as err:
            raise DataFormatError(f"{path}: bundle metadata lacks {err}") from None
        except (TypeError, ValueError) as err:
            raise DataFormatError(f"{path}: bundle metadata: {err}") from None
        ds.validate(str(path))
        return ds

    def validate(self, where: str = "dataset") -> None:
        if self.canonical_mode not in CANONICAL_MODES:
            raise DataFormatError(f"{where}: canonical_mode must be one of {', '.join(CANONICAL_MODES)}, not {self.canonical_mode!r}")
        per_sequence = (self.actions, self.lengths, self.held_out, self.subject_pairs, self.leader_sources, self.leader_rules)
        n = len(self.sequence_ids)
        if any(len(x) != n for x in per_sequence) or any(np.ndim(x) != 1 for x in per_sequence[:3]):
            raise DataFormatError(f"{where}: per-sequence arrays disagree on the number of sequences")
        if n and (self.lengths.dtype.kind not in "iu" or self.lengths.min() < 1):
            raise DataFormatError(f"{where}: lengths must be positive frame counts")
        f = int(self.lengths.sum())
        if self.leader.shape != (f, self.skeleton.num_joints, 3) or self.follower.shape != self.leader.shape:
            raise DataFormatError(f"{where}: pose arrays have shape {self.leader.shape}, expected ({f}, {self.skeleton.num_joints}, 3)")
        if len(self.yaw) != f or self.origin.shape != (f, 3) or len(self.frame_numbers) != f:
            raise DataFormatError(f"{where}: canonical-frame arrays do not match the {f} frames")
        # each message names the array and the first sequence that breaks the bound
        for name in ("leader", "follower", "origin", "yaw") if f else ():
            values = getattr(self, name).reshape(f, -1)
            finite = np.isfinite(values).all(axis=1)
            if not finite.all():
                raise DataFormatError(f"{where}: {name} of sequence {self._sequence_at(int(np.argmin(finite)))} holds NaN "
                                      f"or infinity")
            far = np.abs(values).max(axis=1, initial=0) > MAX_COORDINATE_M
            if name != "yaw" and far.any():
                raise DataFormatError(f"{where}: {name} of sequence {self._sequence_at(int(np.argmax(far)))} has positions "
                                      f"beyond {MAX_COORDINATE_M:g} m; positions within {MAX_COORDINATE_M:g} m are accepted")
        if n and (self.actions.dtype.kind not in "iu" or self.actions.min() < 0 or self.actions.max() >= len(self.class_names)):
            raise DataFormatError(f"{where}: class index outside 0..{len(self.class_names) - 1}")


    def _sequence_at(self, frame: int) -> str:
        """The id of the sequence that holds `frame` of the concatenated pose arrays."""
        return str(self.sequence_ids[int(np.searchsorted(np.cumsum(self.lengths), frame, side="right"))])


def dataset_hash(data: InteractionDataset) -> str:
    """sha256 over the poses, labels, lengths and sequence identities (16 hex digits): what cached classifiers and a
    retrieval checkpoint name their data by."""
    h = hashlib.sha256()
    for arr in (data.leader, data.follower, data.actions, data.lengths):
        h.update(np.ascontiguousarray(arr).tobytes())
    h.update(json.dumps([data.sequence_ids, data.subject_pairs, list(data.class_names)]).encode())
    return h.hexdigest()[:16]


def _strings(values, field: str, unique: bool = False) -> tuple[str, ...]:
    """A metadata list of strings -> tuple (ValueError naming `field` otherwise)."""
    if not isinstance(values, list) or not all(isinstance(v, str) for v in values):
        raise ValueError(f"{field} must be a list of strings")
    if unique and len(set(values)) != len(values):
        raise ValueError(f"{field} names {next(v for v in values if values.count(v) > 1)!r} twice")
    return tuple(values)
