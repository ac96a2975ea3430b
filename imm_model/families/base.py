"""What every model family shares: the family-neutral `ReactionModel` and the `Family` a registry entry describes.

    model = ReactionModel.load("sample_data/imm_sbu.safetensors")      # the checkpoint's family (families/__init__.py)
    follower = model.synthesize(leader_world, {"kicking": 1.0, "hugging": 0.5})  # (T, J, 3) metres

Labels are multi-hot: one float per class (+1 perform, 0 neutral, -1 avoid, fractions blend, values beyond 1
exaggerate), given as {class name: value} (missing classes are 0) or a length-C sequence. A model that reads a label
per body part (`part_labels`) also takes "upper:<class>" (trunk and arms) and "lower:<class>" (legs, and where the
follower stands) keys, or a length-2C sequence (upper, then lower); a class name alone is both parts, and a part key
overrides that part of it. Its label vector is then (2C,); a whole-body label stays (C,). A world leader is checked
and standardized with its canonical frame once (`prepare_leader`), the family's network runs in that frame
(`_network`), the follower goes through the clean-up and is mapped back to the leader's world frame. A family
implements `_network` and `latent_canonical_batch`, and declares in `settings` (SamplerSettings) the sampler settings
it takes (a seed that picks among reactions, a spread, a reaction memory).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.cleanup import clean_follower
from imm_model.data.canonical import CanonicalFrame
from imm_model.data.labels import PARTS, Label
from imm_model.data.sequence import check_world_positions
from imm_model.errors import CheckpointError, DataFormatError, LabelError

MAX_LENGTH_FACTOR = 10  # inputs longer than this times the longest training sequence are refused
# A label value times the scale: +1 performs a class and values beyond 1 exaggerate it (the studio's sliders reach 2);
# far beyond, the network is fed numbers it never saw and its output means nothing.
MAX_LABEL_VALUE = 10.0
MAX_BONE_M = 5.0  # a checkpoint's follower bone lengths, metres
MAX_TRAIN_LENGTH = 100_000  # a checkpoint's max_train_length, frames
MAX_SAMPLES = 64  # reactions drawn by one call
@dataclass(frozen=True)
class SamplerSettings:
    """The sampler settings a model takes, each a control the front ends offer."""

    seed: bool = False  # a seed picks one of many reactions (variations); False: every seed gives the same one
    spread: bool = False  # how loosely it follows the leader (`ReactionModel.spread`)
    memory: bool = False  # starts from real reactions to similar leaders (`ReactionModel.use_memory`)
    online: bool = False  # reacts to a leader streamed frame by frame (`ReactionModel.online`)


@dataclass(frozen=True)
class Trained:
    """What a family's `train` reports of one fold's run."""

    line: str  # what it wrote, in one line (`imm train` prints it)
    counts: dict[str, int]  # how long it trained, as a reproduction records it ({"epochs": .., "best_epoch": ..}, {"steps": ..})


@dataclass(frozen=True)
class Family:
    """One model family, as the registry (families/__init__.py) knows it. Imports that cost (torch) wait for use."""

    name: str  # the checkpoint sidecar's "family"
    title: str  # how people name a model of it ("the paper's GAN")
    model_class: Callable[[], type[ReactionModel]]  # the class that loads its checkpoints
    recipes: Callable[[], Mapping[str, Any]]  # its named recipes, {name: config}
    train: Callable[..., Trained]  # (config, data, subject, out_dir, device, resume, progress) -> what it wrote
    default_recipe: str  # the recipe a JSON recipe file that names this family but no base builds on
    length_option: str | None  # the config field `imm train --epochs/--steps` overrides (None: nothing to train long)
    # what a saved run's config must match for a run to continue it (defaults: equal, but for the length option)
    same_recipe: Callable[[Any, dict], bool] | None = None


@dataclass(frozen=True)
class Leader:
    """A leader motion checked once and standardized once: what every synthesis of it reuses."""

    world: np.ndarray  # (T, J, 3) float64 metres, as given
    frame: CanonicalFrame  # the leader's canonical frame
    canonical: np.ndarray  # (T, J, 3) float32, the leader in that frame (what the networks read)

    @classmethod
    def of_sequence(cls, data, i: int) -> Leader:
        """A dataset's sequence i, whose leader the dataset holds already checked and standardized."""
        return cls(data.world(i)[0], data.frame_of(i), data.canonical(i)[0])

    def to_world(self, follower: np.ndarray, skeleton) -> np.ndarray:
        """A canonical follower (T, J, 3) -> the leader's world frame, float64."""
        return self.frame.to_world(np.asarray(follower, np.float64), skeleton)


class ReactionModel:
    """A trained reaction model with what is needed to use it: classes, skeleton, canonical mode, clean-up.

    `load` returns the checkpoint's family's subclass; everything here is the same for every family."""

    family: str = ""  # the registry's name of the family (a subclass sets it)
    title: str = ""  # how people name it
    weights_prefix = ""  # the checkpoint's tensors live under `prefix.` (what `save` writes)
    settings: SamplerSettings = SamplerSettings()  # the sampler settings it takes (none: one reaction per leader and label)
    part_labels: bool = False  # reads a label per body part ("upper:<class>", "lower:<class>"); a family may set it


    def __init__(self, weights: dict[str, np.ndarray], meta: dict[str, Any], path: Path | None = None, device: str = "cpu"):
        from imm_model.skeleton import Skeleton

        check_sidecar(meta, path)
        self.weights = weights  # the network's state dict, float32 arrays
        self.device = str(device)
        self.fast = None  # the numpy runtime one CPU sequence runs on, where the family has one (else torch)
        self.info: dict[str, Any] = meta
        self.path = path
        self.class_names: tuple[str, ...] = tuple(meta["class_names"])
        self.skeleton: Skeleton = Skeleton.from_dict(meta["skeleton"])
        self.held_out_subject: str | None = meta.get("held_out_subject")
        self.canonical_mode: str = meta.get("canonical_mode", "first_frame")
        self.max_length: int = MAX_LENGTH_FACTOR * int(meta.get("max_train_length", 46))
        # The clean-up (cleanup.py) every synthesized follower goes through unless `raw`: rigid bones at the training
        # followers' lengths (a checkpoint without them: each sequence's own median), feet planted.
        self.raw = False
        self.bone_lengths = _bone_lengths(meta.get("follower_bone_lengths"), self.skeleton, path)
        # Placement averaged with the leader's mirror image (`_average_placement`): off unless asked for. Labels that
        # name a class the training never mirrored (SBU's right-handed handshakes; every class if it mirrored nothing)
        # keep their own placement: their mirror image is a reaction the model never saw.
        self.average_placement = False
        # a faster model distilled from this one (a student whose sidecar names these weights as its teacher's):
        # what the studio draws while a slider moves, this model's own reaction once it rests (`attach_draft`)
        self.draft: ReactionModel | None = None
        training = meta.get("train_config") or {}
        unmirrored = training.get("mirror_exclude_classes", []) if training.get("mirror_prob", 0) > 0 else self.class_names
        self.handed = np.array([c in unmirrored for c in self.class_names])  # (C,) classes the training never mirrored

    # ---- loading and saving ---------------------------------------------------------------
    @classmethod
    def load(cls, path: Path | str | None = None, device: str = "cpu", data: Path | str | None = None) -> ReactionModel:
        """Load a checkpoint of any registered family (default: the bundled diffusion model, paths.SAMPLE_DEFAULT);
        `data` names the bundle a retrieval model retrieves from when it is neither beside the checkpoint nor bundled.
        Any problem -> CheckpointError."""
        from imm_model.families import load_model

        return load_model(path, device, data)

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu",
                        data: Path | None = None) -> ReactionModel:
        """The family's model from a checkpoint's arrays and sidecar, every part checked (one-line CheckpointError);
        `data`, a bundle the user named, for a family that reads its training data at load."""
        raise NotImplementedError

    def save(self, path: Path | str) -> None:
        """This model as a checkpoint `path` (.safetensors + sidecar) that `load` returns as it is."""
        import torch

        from imm_model.checkpoint import save_checkpoint

        tensors = {f"{self.weights_prefix}.{k}": torch.from_numpy(np.ascontiguousarray(v)) for k, v in self.weights.items()}
        save_checkpoint(path, tensors, {k: v for k, v in self.info.items() if k not in ("format", "weights_sha256")})

    def _torch_module(self, module_class, config, what: str):
        """`module_class(config)` holding these weights (strict load), in eval mode, on `device`."""
        import torch

        from imm_model.checkpoint import load_module_state
        from imm_model.device import move_module

        module = module_class(config)
        load_module_state(module, {k: torch.from_numpy(v) for k, v in self.weights.items()}, what, self.path)
        return move_module(module.eval(), self.device)

    def on_torch(self) -> ReactionModel | None:
        """The same model with its numpy runtime off, so that it runs its torch network on this device (the two must
        give the same reactions); None for a model with no numpy runtime to compare."""
        import copy

        if self.fast is None:
            return None
        twin = copy.copy(self)
        twin.fast = None
        return twin

    @contextlib.contextmanager
    def probing(self) -> Iterator[ReactionModel]:
        """The model set for a cheap look at its outputs (the range check at load, output_check.py): no clean-up; a
        family may cut its cost further (the diffusion model samples in one step)."""
        raw = self.raw
        self.raw = True
        try:
            yield self
        finally:
            self.raw = raw

    def online(self, label, scale: float = 1.0, seed: int = 0):
        """A reactor for a leader streamed frame by frame: `push(frame)` -> the follower's frame `lookahead` frames
        behind, or None; `flush()`; `label` and `scale` settable between pushes (families/diffusion/windows.py
        OnlineReactor). A family that cannot react online refuses in one line."""
        raise LabelError(f"{self.title} cannot react online, frame by frame (the diffusion model can)")

    # ---- settings a family may have -------------------------------------------------------
    @property
    def spread(self) -> float | None:
        """How loosely a sampler follows the leader, 0..1; None: this model has no such setting."""
        return None

    @spread.setter
    def spread(self, level: float) -> None:  # refused, not silently stored beside a model that would ignore it
        raise LabelError(f"{self.title} has no spread setting")

    def use_memory(self, level: float, data) -> None:
        """Start the sampler from real reactions to similar leaders (`data`'s training pairs), noised to `level`."""
        raise LabelError(f"{self.title} has no sampler to start from a real reaction")

    def provenance(self, seed: int) -> dict[str, Any]:
        """What an output file records of how this model drew a follower: its seed (None when seeds change nothing),
        spread and reaction-memory level (None when unused)."""
        return {"seed": seed if self.settings.seed else None, "spread": self.spread, "memory": None}

    def draft_for(self, frames: int) -> ReactionModel | None:
        """What draws a leader of `frames` frames while a slider moves, when not this model itself: its `draft`."""
        return self.draft

    def attach_draft(self, student: ReactionModel) -> None:
        """Draw `student` while a slider moves (`draft`): a model distilled from this very one, its sidecar naming these
        weights' digest as its teacher's, for the same classes and skeleton; another is one CheckpointError line."""
        from imm_model.checkpoint import DIGEST

        teacher = (student.info.get("teacher") or {}).get(DIGEST)
        if teacher is None or teacher != self.info.get(DIGEST):
            raise CheckpointError(f"{student.path}: not distilled from {self.path} (its teacher's weights differ), so it "
                                  "cannot draft its reactions")
        if student.class_names != self.class_names or student.skeleton != self.skeleton:
            raise CheckpointError(f"{student.path}: other classes or skeleton than {self.path}")
        self.draft = student

    # ---- labels and inputs ----------------------------------------------------------------
    def label_vector(self, label: Label | Mapping[str, float] | Sequence[float] | np.ndarray, scale: float = 1.0) -> np.ndarray:
        """A label (data/labels.py: a Label, {class or part:class: value}, or one value per class, or per class and part)
        times `scale` -> float32: (C,) for a whole-body label, (2C,) (upper, then lower) for a label per part, which a
        model without part labels refuses in one line."""
        lab = Label.of(label, self.class_names, scale)
        c = len(self.class_names)
        if not (self.part_labels or isinstance(label, Label | Mapping)) and np.size(label) != c:  # a vector per part
            raise LabelError(f"label has shape ({np.size(label)},); expected {c} values ({', '.join(self.class_names)})")
        if lab.parts_differ and not self.part_labels:
            key = next((k for k in lab.keys() if ":" in k), "")
            raise LabelError(f"{self.title} takes no label per body part ({key!r}); give the class alone, for the whole body")
        vec = lab.vector()
        if np.abs(vec).max(initial=0.0) > MAX_LABEL_VALUE:
            k = int(np.argmax(np.abs(vec)))
            name = self.class_names[k % c] if len(vec) == c else f"{PARTS[k // c]}:{self.class_names[k % c]}"
            raise LabelError(f"label value {name}={vec[k]:g} (after the scale) is outside the range of "
                             f"label values, -{MAX_LABEL_VALUE:g}..{MAX_LABEL_VALUE:g}")
        return vec.astype(np.float32)

    def check_leader(self, leader: np.ndarray) -> np.ndarray:
        """Validate a (T, J, 3) leader motion -> float64 array, else DataFormatError (one line)."""
        try:
            arr = np.asarray(leader, dtype=np.float64)
        except (TypeError, ValueError):
            raise DataFormatError("leader motion must be a numeric (T, J, 3) array") from None
        j = self.skeleton.num_joints
        if arr.ndim == 2 and arr.shape[1] == 3 * j:
            arr = arr.reshape(len(arr), j, 3)
        if arr.ndim != 3 or arr.shape[2] != 3:
            raise DataFormatError(f"leader motion has shape {arr.shape}; expected (frames, {j}, 3)")
        if arr.shape[1] != j:
            raise DataFormatError(f"leader motion has {arr.shape[1]} joints; the {self.skeleton.name} skeleton has {j}")
        if len(arr) == 0:
            raise DataFormatError("leader motion is empty (0 frames)")
        if len(arr) < 2:
            raise DataFormatError("leader motion has 1 frame; at least 2 are needed")
        if len(arr) > self.max_length:
            raise DataFormatError(f"leader motion has {len(arr)} frames; {self.title} takes at most {self.max_length}")
        if not np.isfinite(arr).all():
            raise DataFormatError("leader motion contains NaN or infinite values")
        return check_world_positions(arr, "leader motion")

    def prepare_leader(self, leader_world: np.ndarray | Leader) -> Leader:
        """A world leader (T, J, 3) checked and standardized once; a prepared Leader passes through."""
        if isinstance(leader_world, Leader):
            return leader_world
        world = self.check_leader(leader_world)
        frame = CanonicalFrame.from_leader(world, self.skeleton, self.canonical_mode)
        return Leader(world, frame, frame.to_canonical(world, self.skeleton).astype(np.float32))

    # ---- synthesis ------------------------------------------------------------------------
    def synthesize(self, leader_world: np.ndarray | Leader, label, scale: float = 1.0, seed: int = 0,
                   samples: int | None = None) -> np.ndarray:
        """Leader (T, J, 3) world metres + label -> follower (T, J, 3) in the same world frame (float32); with
        `samples` N, N reactions (N, T, J, 3) drawn with seeds seed, seed + 1, ... (all alike for a deterministic
        model)."""
        leader = self.prepare_leader(leader_world)
        vec = self.label_vector(label, scale)
        seeds = check_seeds(seed, samples)
        if not self.settings.seed:
            seeds = seeds[:1]  # every seed gives this reaction: computed once
        world = np.stack(self.synthesize_leaders([leader] * len(seeds), vec, seeds)).astype(np.float32)
        if samples is None:
            return world[0]
        return world if len(world) == samples else np.repeat(world, samples, 0)

    def synthesize_leaders(self, leaders: Sequence[np.ndarray | Leader], label_vector: np.ndarray,
                           seeds: Sequence[int] | None = None) -> list[np.ndarray]:
        """Many world leaders (prepared with `prepare_leader`, or arrays checked here) + one label vector (from
        `label_vector`) + one seed per leader (default 0) -> their world followers (T_i, J, 3) float64, in one batch."""
        prepared = [self.prepare_leader(a) for a in leaders]
        labels = np.repeat(self._label_array(label_vector, 1), len(prepared), 0)
        followers = self.synthesize_batch_canonical([p.canonical for p in prepared], labels, seeds)
        return [p.to_world(f, self.skeleton) for p, f in zip(prepared, followers, strict=True)]

    def synthesize_canonical(self, leader_canonical: np.ndarray, label_vector: np.ndarray, seed: int = 0) -> np.ndarray:
        """Leader (T, J, 3) canonical + (C,) label vector -> follower (T, J, 3) canonical, float32."""
        return self.synthesize_batch_canonical([leader_canonical], np.asarray(label_vector).reshape(1, -1), [seed])[0]

    def synthesize_batch_canonical(self, leaders: list[np.ndarray], label_vectors: np.ndarray,
                                   seeds: Sequence[int] | None = None) -> list[np.ndarray]:
        """N leaders (T_i, J, 3) canonical + (N, C) label vectors (+ N sampler seeds, default 0) -> N followers (T_i, J, 3)."""
        labels = self._label_array(label_vectors, len(leaders))
        seeds = [0] * len(leaders) if seeds is None else [int(s) for s in seeds]
        if len(seeds) != len(leaders):
            raise ValueError(f"{len(seeds)} seeds for {len(leaders)} leaders")
        out = self._network(leaders, labels, seeds)
        if self.average_placement:
            self._average_placement(leaders, labels, out, seeds)
        return [self._clean(f) for f in out]

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        """The family's own followers (T_i, J, 3) canonical for canonical leaders, (N, C) labels and seeds."""
        raise NotImplementedError

    def _average_placement(self, leaders: list[np.ndarray], labels: np.ndarray, followers: list[np.ndarray],
                           seeds: list[int]) -> None:
        """Move each follower (in place, by one offset for the whole sequence) to the mean of where it stands and where
        the network places it for the leader's mirror image, mirrored back. Where the follower stands is the least
        certain part of a reaction; the network's two answers disagree about it, and for the steered models their mean is
        nearer the real placement (docs/experiments/mirror-placement.md). The motion is left
        as it was."""
        rows = [i for i in range(len(leaders)) if not (labels[i].reshape(-1, len(self.class_names)) != 0)[:, self.handed].any()]
        if not rows:
            return
        twins = self._network([self.skeleton.mirrored(np.asarray(leaders[i])) for i in rows], labels[rows], [seeds[i] for i in rows])
        body = self.skeleton.root_neighbours
        for i, twin in zip(rows, twins, strict=True):
            offset = self.skeleton.mirrored(twin)[:, body].mean((0, 1)) - followers[i][:, body].mean((0, 1))
            followers[i] = followers[i] + 0.5 * offset

    def _clean(self, follower: np.ndarray) -> np.ndarray:
        """The network's follower (T, J, 3) -> float32, through the clean-up unless `raw`."""
        if self.raw:
            return follower.astype(np.float32)
        return clean_follower(follower.astype(np.float64), self.skeleton, self.bone_lengths).astype(np.float32)

    def latent(self, leader_world: np.ndarray | Leader, label, scale: float = 1.0) -> np.ndarray:
        """Per-sequence embedding (D,) of a leader and label: what the latent map plots."""
        leader = self.prepare_leader(leader_world)
        return self.latent_canonical_batch([leader.canonical], self.label_vector(label, scale)[None])[0]

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) label vectors -> (N, D) embeddings."""
        raise NotImplementedError

    def _label_array(self, label_vectors: np.ndarray, n: int) -> np.ndarray:
        """(n, C) label vectors, or (n, 2C) for a part model."""
        labels = np.asarray(label_vectors, dtype=np.float32).reshape(n, -1)
        c = len(self.class_names)
        if labels.shape[1] not in ((c, 2 * c) if self.part_labels else (c,)):
            raise LabelError(f"label vectors have {labels.shape[1]} values; expected {c}"
                             + (f" or {2 * c} (per part)" if self.part_labels else ""))
        return labels


def check_seeds(seed: int, samples: int | None) -> list[int]:
    """A sampler seed and an optional number of samples -> the seeds to draw with (LabelError when out of range)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**31:
        raise LabelError(f"seed must be an integer in 0..{2**31 - 1}, not {seed!r}")
    n = 1 if samples is None else samples
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= MAX_SAMPLES:
        raise LabelError(f"samples must be an integer in 1..{MAX_SAMPLES}, not {samples!r}")
    if seed + n > 2**31:
        raise LabelError(f"seed {seed} + {n} samples runs past {2**31 - 1}")
    return [int(seed) + k for k in range(int(n))]


def described_weights(arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, config_class, prefix: str):
    """A checkpoint's model config (checked against its classes and skeleton) and its `prefix.` weights (finite floats)
    -> (config, weights); CheckpointError (one line) otherwise."""
    from imm_model.checkpoint import prefixed
    from imm_model.skeleton import Skeleton

    try:
        cfg = config_class.from_dict(meta["model_config"])
        skeleton = Skeleton.from_dict(meta["skeleton"])
        classes = list(meta["class_names"])
    except (KeyError, TypeError, ValueError) as err:
        raise CheckpointError(f"{path}: sidecar lacks a valid model description ({type(err).__name__}: {err})") from None
    if cfg.num_classes != len(classes) or cfg.num_joints != skeleton.num_joints:
        raise CheckpointError(f"{path}: model config disagrees with the class names or the skeleton")
    weights = prefixed(arrays, prefix)
    bad = sorted(k for k, v in weights.items() if v.dtype.kind != "f" or not np.isfinite(v).all())
    if bad:
        raise CheckpointError(f"{path}: weights that are not finite floats ({', '.join(bad[:3])}{', ...' if len(bad) > 3 else ''})")
    return cfg, weights


def check_compatible(model, data, where: str = "checkpoint") -> None:
    """Refuse a model whose classes, skeleton or canonical frame differ from a dataset's (one-line CheckpointError)."""
    if tuple(model.class_names) != tuple(data.class_names):
        raise CheckpointError(f"{where}: classes {', '.join(model.class_names)} do not match the data's {', '.join(data.class_names)}")
    ms, ds = model.skeleton, data.skeleton
    if tuple(ms.joint_names) != tuple(ds.joint_names) or tuple(ms.parents) != tuple(ds.parents):
        raise CheckpointError(
            f"{where}: skeleton {getattr(ms, 'name', '?')} ({len(ms.joint_names)} joints) does not match "
            f"the data's {ds.name} ({len(ds.joint_names)} joints)"
        )
    model_mode, data_mode = getattr(model, "canonical_mode", None), getattr(data, "canonical_mode", None)
    if model_mode and data_mode and model_mode != data_mode:
        raise CheckpointError(f"{where}: trained on the {model_mode!r} canonical frame, the data uses {data_mode!r}")


def check_sidecar(meta: dict[str, Any], path: Path | None) -> None:
    """The sidecar fields a model reads, checked together before any is used (one-line CheckpointError naming the
    field); the weights' own description (model_config) is its config class's to check."""
    from imm_model.data.canonical import CANONICAL_MODES
    from imm_model.skeleton import Skeleton

    def refuse(problem: str) -> CheckpointError:
        return CheckpointError(f"{path}: sidecar {problem}"[:300])

    classes = meta.get("class_names")
    if not (isinstance(classes, list) and 1 <= len(classes) <= 512 and all(isinstance(c, str) and c for c in classes)):
        raise refuse("class_names must be a list of 1 to 512 class names")
    if len(set(classes)) != len(classes):
        raise refuse(f"class_names names {next(c for c in classes if classes.count(c) > 1)!r} twice")
    try:
        Skeleton.from_dict(meta.get("skeleton"))
    except (TypeError, ValueError) as err:
        raise refuse(str(err)) from None
    length = meta.get("max_train_length", 1)
    if isinstance(length, bool) or not isinstance(length, int) or not 1 <= length <= MAX_TRAIN_LENGTH:
        raise refuse(f"max_train_length must be a frame count in 1..{MAX_TRAIN_LENGTH}, not {length!r}")
    if meta.get("canonical_mode", CANONICAL_MODES[0]) not in CANONICAL_MODES:
        raise refuse(f"canonical_mode must be one of {', '.join(CANONICAL_MODES)}, not {meta.get('canonical_mode')!r}")
    if not isinstance(meta.get("held_out_subject", ""), str | None):
        raise refuse("held_out_subject must be a string")
    training = meta.get("train_config") or {}
    excluded = training.get("mirror_exclude_classes", []) if isinstance(training, dict) else None
    mirror_prob = training.get("mirror_prob", 0) if isinstance(training, dict) else None
    if not (isinstance(excluded, list) and all(isinstance(c, str) for c in excluded)
            and isinstance(mirror_prob, int | float) and not isinstance(mirror_prob, bool)):
        raise refuse("train_config must be an object with a numeric mirror_prob and a list of mirror_exclude_classes")


def _bone_lengths(values, skeleton, path) -> np.ndarray | None:
    """A checkpoint's `follower_bone_lengths` -> (bones,) metres, None when absent; CheckpointError when malformed."""
    if values is None:
        return None
    try:
        lengths = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        lengths = np.zeros(0)
    if lengths.shape != (len(skeleton.bones),) or not (np.isfinite(lengths).all() and (lengths > 0).all()
                                                       and (lengths <= MAX_BONE_M).all()):
        raise CheckpointError(f"{path}: follower_bone_lengths must be {len(skeleton.bones)} lengths in (0, {MAX_BONE_M:g}] m, "
                              "one per bone")
    return lengths
