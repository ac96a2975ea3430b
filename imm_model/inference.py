"""The inference API the studio builds on, and the `imm generate` command.

    model = ReactionModel.load("sample_data/imm_sbu.safetensors")
    follower = model.synthesize(leader_world, {"kicking": 1.0, "hugging": 0.5})  # (T, J, 3) metres

Labels are multi-hot: one float per class (+1 perform, 0 neutral, -1 avoid, fractions blend, values
beyond 1 exaggerate), given as {class name: value} (missing classes are 0) or a length-C sequence.
World input is standardized with the leader's canonical frame (mode saved in the checkpoint), the
generator runs in that frame, and the follower is mapped back to the leader's world frame.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.cleanup import clean_follower
from imm_model.data.sequence import check_world_positions
from imm_model.errors import CheckpointError, DataFormatError, LabelError

MAX_LENGTH_FACTOR = 10  # inputs longer than this times the longest training sequence are refused
# A label value times the scale: +1 performs a class and values beyond 1 exaggerate it (the studio's sliders reach 2);
# far beyond, the network is fed numbers it never saw and its output means nothing.
MAX_LABEL_VALUE = 10.0
MAX_LEADER_BYTES = 16_000_000  # an .npz leader's arrays, uncompressed (about 44,000 frames of 15 joints in float64)
MAX_BONE_M = 5.0  # a checkpoint's follower bone lengths, metres
MAX_TRAIN_LENGTH = 100_000  # a checkpoint's max_train_length, frames


class ReactionModel:
    """A trained reaction model with what is needed to use it: classes, skeleton, canonical mode.

    Two families share this API: the paper's GAN generator (deterministic: one reaction per leader and label) and the
    reaction diffusion model (`DiffusionReactionModel`: a seed picks one of many reactions). `load` returns the
    checkpoint's family."""

    family = "gan"
    stochastic = False  # True: `seed` picks among reactions; False: every seed gives the same one

    @property
    def spread(self) -> float | None:
        """How loosely a sampler follows the leader (DiffusionReactionModel); None: this model has no such setting."""
        return None

    @spread.setter
    def spread(self, level: float) -> None:  # refused here, not silently stored beside a deterministic generator
        raise LabelError("the paper's GAN draws one reaction per leader and label: it has no spread setting")

    def __init__(self, weights: dict[str, np.ndarray], config, meta: dict[str, Any], path: Path | None = None, device: str = "cpu"):
        from imm_model.model.numpy_runtime import NumpyGenerator

        self.weights = weights  # the generator's state dict, float32 arrays
        self.config = config
        self.device = str(device)
        # One sequence on a CPU runs in numpy (model/numpy_runtime.py: the same numbers, as fast, and no `import torch`,
        # which was most of the studio's start). Batches, GPUs and the paper's frame-by-frame decoder use torch.
        self.fast = NumpyGenerator(weights, config) if self.device == "cpu" and NumpyGenerator.supports(config) else None
        self._read_meta(meta, path)

    def _read_meta(self, meta: dict[str, Any], path: Path | None) -> None:
        from imm_model.skeleton import Skeleton

        check_sidecar(meta, path)
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
        training = meta.get("train_config") or {}
        unmirrored = training.get("mirror_exclude_classes", []) if training.get("mirror_prob", 0) > 0 else self.class_names
        self.handed = np.array([c in unmirrored for c in self.class_names])  # (C,) classes the training never mirrored

    @functools.cached_property
    def generator(self):
        """The torch model.Generator with these weights, on `device` (built when first needed)."""
        from imm_model.model.generator import Generator

        return self._torch_module(Generator, "generator")

    def _torch_module(self, module_class, what: str):
        """`module_class(config)` holding these weights (strict load), in eval mode, on `device`."""
        import torch

        from imm_model.checkpoint import load_module_state
        from imm_model.device import move_module

        module = module_class(self.config)
        load_module_state(module, {k: torch.from_numpy(v) for k, v in self.weights.items()}, what, self.path)
        return move_module(module.eval(), self.device)

    # ---- loading --------------------------------------------------------------------------
    @classmethod
    def load(cls, path: Path | str | None = None, device: str = "cpu") -> ReactionModel:
        """Load a checkpoint (default: the bundled one). Any problem -> CheckpointError (one line)."""
        from imm_model.checkpoint import check_state, load_checkpoint
        from imm_model.model.config import ModelConfig
        from imm_model.model.numpy_runtime import NumpyGenerator
        from imm_model.output_check import check_model_outputs
        from imm_model.paths import SAMPLE_CHECKPOINT

        path = Path(path) if path is not None else SAMPLE_CHECKPOINT
        arrays, meta = load_checkpoint(path, framework="np")
        if meta.get("family") == DiffusionReactionModel.family:
            return check_model_outputs(DiffusionReactionModel.from_checkpoint(arrays, meta, path, device))
        cfg, weights = _described_weights(arrays, meta, path, ModelConfig, "generator")
        if NumpyGenerator.supports(cfg):
            check_state(weights, NumpyGenerator.expected_shapes(cfg), "generator", path)
        model = cls({k: v.astype(np.float32) for k, v in weights.items()}, cfg, meta, path, device)
        if model.fast is None:
            model.generator  # noqa: B018 - torch's strict load checks the weights now, not at the first synthesis
        return check_model_outputs(model)

    # ---- labels and inputs ----------------------------------------------------------------
    def label_vector(self, label: Mapping[str, float] | Sequence[float] | np.ndarray, scale: float = 1.0) -> np.ndarray:
        """A label (name -> value mapping, or one value per class) -> (C,) float32, times `scale`."""
        c = len(self.class_names)
        if isinstance(label, Mapping):
            unknown = [k for k in label if k not in self.class_names]
            if unknown:
                raise LabelError(f"unknown class {unknown[0]!r}; classes: {', '.join(self.class_names)}")
            vec = np.zeros(c, dtype=np.float64)
            for k, v in label.items():
                vec[self.class_names.index(k)] = _as_float(v, k)
        else:
            if isinstance(label, str | bytes):
                raise LabelError("a label is a mapping {class: value} or a sequence of numbers, not a string")
            try:
                vec = np.asarray(label, dtype=np.float64)
            except (TypeError, ValueError):
                raise LabelError("label values must be numbers") from None
            if vec.ndim != 1 or len(vec) != c:
                raise LabelError(f"label has shape {vec.shape}; expected {c} values ({', '.join(self.class_names)})")
        scale = _as_float(scale, "scale")
        with np.errstate(all="ignore"):
            vec = vec * scale
        if not (np.isfinite(vec).all() and np.isfinite(scale)):
            raise LabelError("label values must be finite (no NaN or infinity)")
        if np.abs(vec).max(initial=0.0) > MAX_LABEL_VALUE:
            k = int(np.argmax(np.abs(vec)))
            raise LabelError(f"label value {self.class_names[k]}={vec[k]:g} (after the scale) is outside the range of "
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
            raise DataFormatError(f"leader motion has {len(arr)} frames; at most {self.max_length} "
                                  f"({MAX_LENGTH_FACTOR}x the longest training sequence) are supported")
        if not np.isfinite(arr).all():
            raise DataFormatError("leader motion contains NaN or infinite values")
        return check_world_positions(arr, "leader motion")

    # ---- synthesis ------------------------------------------------------------------------
    def synthesize(self, leader_world: np.ndarray, label, scale: float = 1.0, seed: int = 0,
                   samples: int | None = None) -> np.ndarray:
        """Leader (T, J, 3) world metres + label -> follower (T, J, 3) in the same world frame (float32); with
        `samples` N, N reactions (N, T, J, 3) drawn with seeds seed, seed + 1, ... (all alike for a deterministic
        model)."""
        from imm_model.data.canonical import CanonicalFrame

        leader = self.check_leader(leader_world)
        vec = self.label_vector(label, scale)
        seeds = check_seeds(seed, samples)
        if not self.stochastic:
            seeds = seeds[:1]  # every seed gives this reaction: computed once
        frame = CanonicalFrame.from_leader(leader, self.skeleton, self.canonical_mode)
        canonical = frame.to_canonical(leader, self.skeleton)
        followers = self.synthesize_batch_canonical([canonical] * len(seeds), np.repeat(vec[None], len(seeds), 0), seeds)
        world = np.stack([frame.to_world(f.astype(np.float64), self.skeleton).astype(np.float32) for f in followers])
        if samples is None:
            return world[0]
        return world if len(world) == samples else np.repeat(world, samples, 0)

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

    def _average_placement(self, leaders: list[np.ndarray], labels: np.ndarray, followers: list[np.ndarray],
                           seeds: list[int]) -> None:
        """Move each follower (in place, by one offset for the whole sequence) to the mean of where it stands and where
        the network places it for the leader's mirror image, mirrored back. Where the follower stands is the least
        certain part of a reaction; the network's two answers disagree about it, and for the steered models their mean is
        nearer the real placement (docs/experiments/mirror-placement.md). The motion is left
        as it was."""
        rows = [i for i in range(len(leaders)) if not (labels[i] != 0)[self.handed].any()]
        if not rows:
            return
        twins = self._network([self.skeleton.mirrored(np.asarray(leaders[i])) for i in rows], labels[rows], [seeds[i] for i in rows])
        body = self.skeleton.root_neighbours
        for i, twin in zip(rows, twins, strict=True):
            offset = self.skeleton.mirrored(twin)[:, body].mean((0, 1)) - followers[i][:, body].mean((0, 1))
            followers[i] = followers[i] + 0.5 * offset

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        """The generator's own followers (T_i, J, 3): numpy for one sequence on a CPU, else one torch batch (the
        generator is deterministic: seeds change nothing)."""
        if self.fast is not None and len(leaders) == 1:
            t = len(leaders[0])
            return [self.fast(np.asarray(leaders[0], np.float32).reshape(t, -1), labels[0]).reshape(t, -1, 3)]
        out, lengths = self._run_batch(leaders, labels, latent=False)
        return [out[i, : lengths[i]].reshape(lengths[i], -1, 3) for i in range(len(leaders))]

    def _clean(self, follower: np.ndarray) -> np.ndarray:
        """The network's follower (T, J, 3) -> float32, through the clean-up unless `raw`."""
        if self.raw:
            return follower.astype(np.float32)
        return clean_follower(follower.astype(np.float64), self.skeleton, self.bone_lengths).astype(np.float32)

    def latent(self, leader_world: np.ndarray, label, scale: float = 1.0) -> np.ndarray:
        """Per-sequence embedding (D,): the hierarchical encoder outputs averaged over frames."""
        from imm_model.data.canonical import CanonicalFrame

        leader = self.check_leader(leader_world)
        vec = self.label_vector(label, scale)
        frame = CanonicalFrame.from_leader(leader, self.skeleton, self.canonical_mode)
        return self.latent_canonical_batch([frame.to_canonical(leader, self.skeleton)], vec[None])[0]

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) label vectors -> (N, D) embeddings."""
        if self.fast is not None:
            labels = self._label_array(label_vectors, len(leaders))
            return np.stack([self.fast.encode(np.asarray(a, np.float32).reshape(len(a), -1), lab).mean(0)
                             for a, lab in zip(leaders, labels, strict=True)])
        out, _ = self._run_batch(leaders, label_vectors, latent=True)
        return out

    def _label_array(self, label_vectors: np.ndarray, n: int) -> np.ndarray:
        labels = np.asarray(label_vectors, dtype=np.float32).reshape(n, -1)
        if labels.shape[1] != len(self.class_names):
            raise LabelError(f"label vectors have {labels.shape[1]} values; expected {len(self.class_names)}")
        return labels

    def _run_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray, latent: bool) -> tuple[np.ndarray, np.ndarray]:
        import torch

        from imm_model.data.batching import pad_sequences

        labels = self._label_array(label_vectors, len(leaders))
        lengths = np.array([len(a) for a in leaders])
        x, mask = pad_sequences([np.asarray(a, dtype=np.float32).reshape(len(a), -1) for a in leaders])
        with torch.inference_mode():
            x, mask = x.to(self.device), mask.to(self.device)
            lab, lens = torch.from_numpy(labels).to(self.device), torch.from_numpy(lengths).to(self.device)
            if latent:
                h = self.generator.encode(x, lab, lens)
                m = mask[..., None].float()
                return ((h * m).sum(1) / m.sum(1)).cpu().numpy(), lengths
            return self.generator(x, lab, lens).cpu().numpy(), lengths


MAX_SAMPLES = 64  # reactions drawn by one call


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


class DiffusionReactionModel(ReactionModel):
    """The reaction diffusion model (model/diffusion_sampler.py) behind the ReactionModel API. A seed fixes the
    sampler's starting noise, so the same seed with a moved label slider moves the reaction continuously; another seed
    is another reaction. `guidance` (label strength, leader guidance, steps) defaults to what the model shipped with.
    On a CPU the denoiser runs in numpy (model/diffusion_numpy.py: no `import torch`), on a GPU in torch."""

    family = "diffusion"
    stochastic = True
    BATCH = 64  # sequences per sampler batch (bounds memory for `imm evaluate`'s hundreds of reactions)

    def __init__(self, weights: dict[str, np.ndarray], config, guidance, meta: dict[str, Any], path: Path | None = None,
                 device: str = "cpu"):
        from imm_model.model.diffusion_numpy import NumpyDenoiser

        self.weights = weights  # the denoiser's state dict, float32 arrays
        self.config = config
        self.guidance = guidance
        self.device = str(device)
        self.fast = NumpyDenoiser(weights, config) if self.device == "cpu" else None
        self._read_meta(meta, path)
        self.memory = None  # the reaction memory (model/reaction_memory.py) its sampler may start from

    @property
    def spread(self) -> float | None:
        """How loosely the sampler follows the leader (Guidance.leader_noise, 0..1), for a model trained with noised
        leaders; None for one that reads only the clean leader."""
        return float(self.guidance.leader_noise) if self.config.leader_noise else None

    @spread.setter
    def spread(self, level: float) -> None:
        if not self.config.leader_noise:
            raise LabelError("spread needs a diffusion model trained with noised leaders (this one reads only the clean leader)")
        if isinstance(level, bool) or not isinstance(level, int | float | np.floating) or not 0 <= level <= 1:
            raise LabelError(f"spread must be a number in 0..1, not {level!r}")
        self.guidance = replace(self.guidance, leader_noise=float(level))

    @functools.cached_property
    def net(self):
        """The torch ReactionDenoiser with these weights, on `device` (built when first needed)."""
        from imm_model.model.diffusion import ReactionDenoiser

        return self._torch_module(ReactionDenoiser, "denoiser")

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu"):
        from imm_model.checkpoint import check_state
        from imm_model.model.diffusion_numpy import NumpyDenoiser
        from imm_model.model.diffusion_sampler import DiffusionConfig, Guidance

        cfg, weights = _described_weights(arrays, meta, path, DiffusionConfig, "denoiser")
        try:
            guidance = Guidance.from_dict(meta["guidance"])
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(f"{path}: sidecar lacks valid sampler guidance ({type(err).__name__}: {err})") from None
        check_state(weights, NumpyDenoiser.expected_shapes(cfg), "denoiser", path)
        model = cls({k: np.ascontiguousarray(v, np.float32) for k, v in weights.items()}, cfg, guidance, meta, path, device)
        if model.fast is None:
            model.net  # noqa: B018 - built (and moved to the GPU) now, not at the first synthesis
        return model

    def _denoiser(self, leaders: np.ndarray, mask: np.ndarray, leader_level: int = 0):
        """`sample`'s network call for these (normalized) leaders, carrying the forward process's noise at step
        `leader_level`: numpy on a CPU, torch elsewhere."""
        if self.fast is None:
            from imm_model.model.diffusion import torch_denoiser

            return torch_denoiser(self.net, leaders, mask, leader_level)

        # the network conditioned on the leaders, mask and terms once per sample call, not once per step
        conditioned: dict[bytes, Any] = {}

        def denoise(x_t, step, leader_on, label, label_on):
            terms = b"".join(np.ascontiguousarray(a).tobytes() for a in (leader_on, label, label_on))
            if terms not in conditioned:
                reps = len(x_t) // len(leaders)
                conditioned[terms] = self.fast.conditioned(np.tile(leaders, (reps, 1, 1)), leader_on, label, label_on,
                                                           np.tile(mask, (reps, 1)), leader_on * np.float32(leader_level))
            return conditioned[terms](x_t, step)

        return denoise

    def _padded(self, arrays: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """[(T_i, ...)] -> (B, T_max, D) float32 zero-padded, (B, T_max) bool mask."""
        d = self.config.pose_dim
        out = np.zeros((len(arrays), max(len(a) for a in arrays), d), np.float32)
        mask = np.zeros(out.shape[:2], bool)
        for i, a in enumerate(arrays):
            out[i, : len(a)] = np.asarray(a, np.float32).reshape(len(a), d)
            mask[i, : len(a)] = True
        return out, mask

    def _normalize_leaders(self, leaders: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        x, mask = self._padded(leaders)
        mean, std = self.weights["leader_mean"], self.weights["leader_std"]
        return (x - mean) / std * mask[..., None], mask

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        from imm_model.model.diffusion_sampler import forward_noised, initial_noise, noised_leaders, sample, schedule_step

        d, steps = self.config.pose_dim, self.config.diffusion_steps
        level = schedule_step(self.guidance.leader_noise, steps)
        if level and not self.config.leader_noise:
            raise LabelError(f"leader noise {self.guidance.leader_noise:g} needs a model trained with noised leaders "
                             "(this one reads only the clean leader)")
        out: list[np.ndarray] = []
        for start in range(0, len(leaders), self.BATCH):
            rows = list(range(start, min(start + self.BATCH, len(leaders))))
            x, mask = self._normalize_leaders([leaders[i] for i in rows])
            denoise = self._denoiser(x, mask)
            if level:
                noisy = self._denoiser(noised_leaders(x, mask, [seeds[i] for i in rows], level, steps), mask, level)
                denoise = _clean_at_the_last_step(noisy, denoise)
            noise, _ = self._padded([initial_noise(seeds[i], len(leaders[i]), d) for i in rows])
            if self.guidance.uses_memory:
                noise = forward_noised(self._memory_starts([leaders[i] for i in rows], labels[rows], [seeds[i] for i in rows]),
                                       noise, mask, schedule_step(self.guidance.memory_level, steps), steps)
            x0 = sample(denoise, x, mask, labels[rows], noise, self.guidance, steps, seeds=[seeds[i] for i in rows],
                        pair_terms=self.config.pair_terms)
            followers = x0 * self.weights["follower_std"] + self.weights["follower_mean"]
            out += [followers[k, : len(leaders[i])].reshape(len(leaders[i]), -1, 3) for k, i in enumerate(rows)]
        return out

    def _memory_starts(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> np.ndarray:
        """The reaction memory's starting reactions for these rows -> (B, T_max, D) normalized, zero-padded."""
        if self.memory is None:
            raise LabelError(f"guidance memory_level {self.guidance.memory_level:g} starts the sampler from the model's "
                             "reaction memory, and none is attached (attach_memory, or memory_level 1)")
        starts = [self.memory.start(np.asarray(a).reshape(len(a), -1, 3), w, s).reshape(len(a), -1)
                  for a, w, s in zip(leaders, labels, seeds, strict=True)]
        x, mask = self._padded(starts)
        return (x - self.weights["follower_mean"]) / self.weights["follower_std"] * mask[..., None]

    def attach_memory(self, data, indices=None) -> None:
        """Give the sampler its reaction memory: `data`'s pairs `indices`, by default every pair of the subjects the
        model was trained on (never its held-out subject's)."""
        from imm_model.data.splits import loso_fold
        from imm_model.model.reaction_memory import ReactionMemory

        check_compatible(self, data, "reaction memory")
        if indices is None:
            indices = np.arange(len(data)) if self.held_out_subject is None else loso_fold(data.subject_pairs, self.held_out_subject).train
        self.memory = ReactionMemory.from_dataset(data, indices)

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) labels -> (N, width): the denoiser's last hidden state, averaged over frames,
        for the leader and label with the follower all noise (the first sampler step's view of the reaction)."""
        labels = self._label_array(label_vectors, len(leaders))
        x, mask = self._normalize_leaders(leaders)
        on = np.ones(len(leaders), bool)
        step = self.config.diffusion_steps - 1
        if self.fast is not None:
            h, tokens = self.fast(np.zeros_like(x), step, x, on, labels, np.abs(labels).sum(1) > 0, mask, return_hidden=True)
        else:
            import torch

            dev = self.device
            with torch.inference_mode():
                h, tokens = self.net(torch.zeros(x.shape, device=dev), torch.full((len(x),), step, device=dev),
                                     torch.as_tensor(x, device=dev), torch.as_tensor(on, device=dev),
                                     torch.as_tensor(labels, device=dev), torch.as_tensor(np.abs(labels).sum(1) > 0, device=dev),
                                     torch.as_tensor(mask, device=dev), return_hidden=True)
                h, tokens = h.cpu().numpy(), tokens.cpu().numpy()
        m = tokens[..., None].astype(np.float32)
        return (h * m).sum(1) / m.sum(1)


def _clean_at_the_last_step(noisy, clean):
    """`sample`'s network call from the noised leader's network call, except at the last step (step 0), whose prediction
    is the output: there the clean leader's, or the leader's noise would show in the reaction as jitter."""
    return lambda x_t, step, *terms: (clean if step == 0 else noisy)(x_t, step, *terms)


def _described_weights(arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, config_class, prefix: str):
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
    """Refuse a model (ReactionModel or alike) whose classes, skeleton or canonical frame differ from a dataset's
    (one-line CheckpointError)."""
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


def _as_float(v, name: str) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        raise LabelError(f"value for {name!r} is not a number: {v!r}") from None


@functools.lru_cache(maxsize=4)
def _cached_model(path: str) -> ReactionModel:
    return ReactionModel.load(path)


def _model(checkpoint: ReactionModel | Path | str | None) -> ReactionModel:
    from imm_model.paths import SAMPLE_CHECKPOINT

    if isinstance(checkpoint, ReactionModel):
        return checkpoint
    return _cached_model(str(Path(checkpoint) if checkpoint is not None else SAMPLE_CHECKPOINT))


def synthesize(leader_motion: np.ndarray, label, scale: float = 1.0, checkpoint=None) -> np.ndarray:
    """Follower (T, J, 3) world metres for a world-space leader, with the bundled model by default."""
    return _model(checkpoint).synthesize(leader_motion, label, scale)


def latent(leader_motion: np.ndarray, label, scale: float = 1.0, checkpoint=None) -> np.ndarray:
    """Per-sequence embedding (D,) of a world-space leader + label, with the bundled model by default."""
    return _model(checkpoint).latent(leader_motion, label, scale)


# ---- `imm generate` ----------------------------------------------------------------------------
def parse_label(text: str, class_names: Sequence[str]) -> dict[str, float] | list[float]:
    """'kicking=1,hugging=0.5' -> mapping; '1,0,0,0,0.5,0' -> list (one value per class)."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise LabelError("empty --label")
    if all("=" in p for p in parts):
        out: dict[str, float] = {}
        for p in parts:
            k, v = (s.strip() for s in p.split("=", 1))
            if k in out:
                raise LabelError(f"--label gives {k} twice ({k}={out[k]:g} and {k}={v}); give each class once")
            out[k] = _as_float(v, k)
        return out
    if any("=" in p for p in parts):
        raise LabelError("--label mixes name=value and plain values")
    if len(parts) == 1 and parts[0] in class_names:
        return {parts[0]: 1.0}
    return [_as_float(p, f"class {i}") for i, p in enumerate(parts)]


def read_leader_file(path: Path, bvh_map: Path | None = None) -> np.ndarray:
    """A .bvh (any recognisable human skeleton, data/bvh.py), an .npz with a `leader` array ((T, J, 3), or (T, 3J)
    as `check_leader` reads it), or an SBU skeleton_pos.txt (its more active person) -> (T, J, 3) world metres.
    Suffixes in either case; anything else, or beyond the readers' bounds, is a one-line DataFormatError."""
    from imm_model.inputs import check_input

    check_input(path, "leader file")  # a FIFO or a device named as such, never opened
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        from imm_model.data.bvh import read_bvh

        return read_bvh(path, bvh_map)
    if suffix == ".npz":
        from imm_model.data.npz import read_npz

        leader = read_npz(path, ["leader"], MAX_LEADER_BYTES, "leader")["leader"].astype(np.float64)
        if leader.ndim == 2 and leader.shape[1] % 3 == 0 and leader.shape[1] > 0:
            leader = leader.reshape(len(leader), -1, 3)
        if leader.ndim != 3 or leader.shape[2] != 3:
            raise DataFormatError(f"{path}: 'leader' has shape {leader.shape}; expected (frames, joints, 3)")
        return check_world_positions(leader, f"{path}: 'leader'")
    if suffix == ".txt":
        from imm_model.data.leader import actor_by_motion_energy
        from imm_model.data.sbu import normalized_to_metres, parse_skeleton_file

        _, positions = parse_skeleton_file(path)
        metres = normalized_to_metres(positions)
        return metres[actor_by_motion_energy(metres[0], metres[1])]
    raise DataFormatError(f"{path}: unsupported leader file type {path.suffix!r}; give a .bvh, .npz or SBU skeleton_pos.txt")
