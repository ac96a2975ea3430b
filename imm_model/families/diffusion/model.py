"""The reaction diffusion model (sampler.py) behind the ReactionModel API: a seed picks one of many reactions."""

from __future__ import annotations

import contextlib
import copy
import functools
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.data.labels import whole_body
from imm_model.errors import CheckpointError, LabelError
from imm_model.families.base import ReactionModel, SamplerSettings, check_compatible, described_weights
from imm_model.families.diffusion.denoiser_numpy import NumpyDenoiser
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance, sample, smoothed
from imm_model.families.diffusion.windows import RESAMPLE, OnlineReactor, take_windows

MAX_TAKE_FRAMES = 36_000  # the longest leader taken (40 minutes at 15 fps; sampled in windows, windows.py)


class DiffusionReactionModel(ReactionModel):
    """The reaction diffusion model (sampler.py) behind the ReactionModel API. A seed fixes the
    sampler's starting noise, so the same seed with a moved label slider moves the reaction continuously; another seed
    is another reaction. `guidance` (label strength, leader guidance, steps) defaults to what the model shipped with.
    On a CPU the denoiser runs in numpy (denoiser_numpy.py: no `import torch`), on a GPU in torch."""

    family = "diffusion"
    weights_prefix = "denoiser"
    BATCH = 64  # sequences per sampler batch (bounds memory for `imm evaluate`'s hundreds of reactions)

    def __init__(self, weights: dict[str, np.ndarray], config, guidance, meta: dict[str, Any], path: Path | None = None,
                 device: str = "cpu"):
        super().__init__(weights, meta, path, device)
        self.config = config
        self.guidance = guidance
        self.fast = NumpyDenoiser(weights, config) if self.device == "cpu" else None
        self.window = int(meta.get("max_train_length", 46))  # frames the sampler reads at once: longer takes go in windows
        self.max_length = MAX_TAKE_FRAMES
        self.memory = None  # the reaction memory (reaction_memory.py) its sampler may start from
        # the model its long takes and live reactions come from: a student's teacher (`teacher_for_takes`), which
        # continues a window better than the student learnt to; None: this model itself
        self.takes: DiffusionReactionModel | None = None
        # the network that reacts live, frame by frame (live.py), when one was trained for this model and lies beside
        # its checkpoint; None: it reacts live in windows (windows.py OnlineReactor)
        self.live = None
        self.resample = RESAMPLE  # times a long take's window takes each sampler step again (windows.py; a draft's 0)
        # the sampling loop, sampler.py `sample` (an experiment may put another with its signature here: it gets the
        # network call, the normalized leaders and masks, labels, starting noise, guidance, steps, seeds, and the
        # network's pair_terms and part_labels)
        self.sampler = sample

    @property
    def settings(self) -> SamplerSettings:
        return SamplerSettings(seed=True, spread=self.config.leader_noise, memory=True, online=True)

    @property
    def part_labels(self) -> bool:
        """A part network reads a label per body part; any network takes one whose sampler joins the parts
        (Guidance.part_join)."""
        return self.config.part_labels or self.guidance.part_join

    def join_parts(self, upper_x0: np.ndarray, lower_x0: np.ndarray) -> np.ndarray:
        """Normalized followers (B, T, D) twice -> (B, T, D): the trunk and arms of the first on the legs and placement
        of the second, joined around the body centre as training composes real followers (model/body_parts.py
        `compose_parts`); the sampler's join (Guidance.part_join)."""
        from imm_model.model.body_parts import compose_parts, part_indices  # numpy only: the studio never imports torch

        mean, std = self.weights["follower_mean"], self.weights["follower_std"]
        b, t, d = upper_x0.shape
        upper, _, centre = part_indices(self.skeleton)
        joined = compose_parts((upper_x0 * std + mean).reshape(b, t, -1, 3), (lower_x0 * std + mean).reshape(b, t, -1, 3),
                               upper, centre)
        return ((joined.reshape(b, t, d) - mean) / std).astype(np.float32)

    @property
    def title(self) -> str:  # what the studio's switch and the messages call it
        return "the diffusion model by parts" if self.config.part_labels else "the diffusion model"

    def _label_input(self, labels: np.ndarray) -> np.ndarray:
        """(N, C) or (N, 2C) checked label vectors (`_label_array`) -> what the sampler composes: a part network's
        whole-body label on both parts."""
        return np.concatenate([labels, labels], 1) if self.config.part_labels and labels.shape[1] == len(self.class_names) else labels

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
        for other in (self.takes, self.draft):  # its long takes and its draft follow the same leader as loosely
            if isinstance(other, DiffusionReactionModel) and other.config.leader_noise:
                other.spread = level

    @functools.cached_property
    def net(self):
        """The torch ReactionDenoiser with these weights, on `device` (built when first needed)."""
        from imm_model.families.diffusion.denoiser import ReactionDenoiser

        return self._torch_module(ReactionDenoiser, self.config, "denoiser")

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu",
                        data: Path | None = None):
        from imm_model.checkpoint import check_state
        from imm_model.families.diffusion.live import KIND, describe, live_for

        if meta.get("kind") == KIND:
            raise CheckpointError(f"{path}: {describe(meta)}")
        cfg, weights = described_weights(arrays, meta, path, DiffusionConfig, cls.weights_prefix)
        try:
            guidance = Guidance.from_dict(meta["guidance"])
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(f"{path}: sidecar lacks valid sampler guidance ({type(err).__name__}: {err})") from None
        check_state(weights, NumpyDenoiser.expected_shapes(cfg), "denoiser", path)
        model = cls({k: np.ascontiguousarray(v, np.float32) for k, v in weights.items()}, cfg, guidance, meta, path, device)
        if model.fast is None:
            model.net  # noqa: B018 - built (and moved to the GPU) now, not at the first synthesis
        model.live = live_for(model, path)
        model.takes = teacher_for_takes(meta, path, device)
        if model.takes is not None:  # what a moving slider draws of a long take: the student's own windows, the faster
            model.draft = copy.copy(model)
            model.draft.takes, model.draft.resample = None, 0  # each window's steps once: a draft is for speed
        return model

    def _denoiser(self, leaders: np.ndarray, mask: np.ndarray, leader_level: int = 0):
        """`sample`'s network call for these (normalized) leaders, carrying the forward process's noise at step
        `leader_level`: numpy on a CPU, torch elsewhere."""
        if self.fast is None:
            from imm_model.families.diffusion.denoiser import torch_denoiser

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

    def _network(self, leaders: list[np.ndarray], raw: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        labels = self._label_input(raw)
        out: list[np.ndarray] = [np.empty(0)] * len(leaders)
        clips = [i for i, a in enumerate(leaders) if len(a) <= self.window]
        for start in range(0, len(clips), self.BATCH):
            rows = clips[start:start + self.BATCH]
            for i, follower in zip(rows, self._sample([leaders[i] for i in rows], labels[rows], [seeds[i] for i in rows]),
                                   strict=True):
                out[i] = smoothed(follower, self.guidance.smoothing)  # a clip's; a window keeps the frames it is given
        takes = self.takes or self
        for i in (i for i, a in enumerate(leaders) if len(a) > self.window):  # a long take: in windows (windows.py)
            out[i] = take_windows(takes, np.asarray(leaders[i], np.float32), takes._label_input(raw[i:i + 1])[0], seeds[i])
        return out

    def _sample(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int],
                noises: list[np.ndarray] | None = None, leader_noises: list[np.ndarray] | None = None,
                known: list[tuple[np.ndarray, int]] | None = None, continue_level: float = 1.0,
                resample: tuple[int, list] | None = None) -> list[np.ndarray]:
        """One sampler batch: canonical leaders (T_i, J, 3), the sampler's labels (`_label_input`), seeds -> followers
        (T_i, J, 3) canonical. The starting noise and the leader's noise default to the seeds' draws for each length
        (a window of a long take brings its slice of the take's); `known`, per row (canonical follower (T_i, J, 3),
        k), gives its first k frames (the sampler inpaints the rest around them); with `continue_level` < 1 and k > 0
        in every row, the sampler starts at that noise level from the given frames, the last one held for the rest
        (what the window continues), not from pure noise; `resample` (times, per row a seed) takes each sampler step
        again so that the given frames and the ones sampled around them settle together (sampler.py `ddim`)."""
        from imm_model.families.diffusion.sampler import forward_noised, initial_noise, leader_noise, schedule_step

        d, steps = self.config.pose_dim, self.config.diffusion_steps
        level = schedule_step(self.guidance.leader_noise, steps)
        if level and not self.config.leader_noise:
            raise LabelError(f"leader noise {self.guidance.leader_noise:g} needs a model trained with noised leaders "
                             "(this one reads only the clean leader)")
        join = self.join_parts if self.guidance.part_join and labels.shape[1] == 2 * len(self.class_names) else None
        x, mask = self._normalize_leaders(leaders)
        denoise = self._denoiser(x, mask)
        if level:
            z, _ = self._padded(leader_noises or [leader_noise(s, len(a), d) for a, s in zip(leaders, seeds, strict=True)])
            noisy = self._denoiser(forward_noised(x, z, mask, level, steps), mask, level)
            denoise = _clean_at_the_last_step(noisy, denoise)
        noise, _ = self._padded(noises or [initial_noise(s, len(a), d) for a, s in zip(leaders, seeds, strict=True)])
        if self.guidance.uses_memory:
            noise = forward_noised(self._memory_starts(leaders, labels, seeds), noise, mask,
                                   schedule_step(self.guidance.memory_level, steps), steps)
        given, guidance = {}, self.guidance  # keywords only some samplers take: an experiment's sampler need not
        if self.config.composed_label:
            given["composed_label"] = True
        if known is not None:
            values, _ = self._padded([f for f, _ in known])
            values = (values - self.weights["follower_mean"]) / self.weights["follower_std"] * mask[..., None]
            counts = np.array([k for _, k in known])
            where = np.arange(mask.shape[1])[None] < counts[:, None]
            given["known"] = (values, where, self.config.given_frames)
            if continue_level < 1 and counts.min() > 0:
                held = np.where(where[..., None], values, values[np.arange(len(counts)), counts - 1][:, None])
                noise = forward_noised(held, noise, mask, schedule_step(continue_level, steps), steps)
                guidance = replace(guidance, memory_level=continue_level)
            if resample and resample[0]:
                given["resample"] = resample
        x0 = self.sampler(denoise, x, mask, labels, noise, guidance, steps, seeds=seeds,
                          pair_terms=self.config.pair_terms, part_labels=self.config.part_labels, join=join, **given)
        followers = x0 * self.weights["follower_std"] + self.weights["follower_mean"]
        return [followers[k, : len(a)].reshape(len(a), -1, 3) for k, a in enumerate(leaders)]

    def _memory_starts(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> np.ndarray:
        """The reaction memory's starting reactions for these rows -> (B, T_max, D) normalized, zero-padded."""
        if self.memory is None:
            raise LabelError(f"guidance memory_level {self.guidance.memory_level:g} starts the sampler from the model's "
                             "reaction memory, and none is attached (attach_memory, or memory_level 1)")
        whole = whole_body(labels, len(self.class_names))  # the memory keeps whole-body reactions
        starts = [self.memory.start(np.asarray(a).reshape(len(a), -1, 3), w, s).reshape(len(a), -1)
                  for a, w, s in zip(leaders, whole, seeds, strict=True)]
        x, mask = self._padded(starts)
        return (x - self.weights["follower_mean"]) / self.weights["follower_std"] * mask[..., None]

    def attach_draft(self, student: ReactionModel) -> None:
        super().attach_draft(student)
        if isinstance(student, DiffusionReactionModel):
            # a draft is for speed: it draws a long take with its own windows, not through this model, each step once
            student.takes, student.resample = None, 0

    def draft_for(self, frames: int) -> ReactionModel | None:
        """A student whose teacher makes its long takes drafts those with its own windows, and a clip with nothing: it
        draws a clip itself, at once."""
        return None if self.takes is not None and frames <= self.window else self.draft

    def online(self, label, scale: float = 1.0, seed: int = 0):
        """Its live reactor's reaction (live.py) where the model that makes its long takes has one, else windows'."""
        from imm_model.families.diffusion.live import LiveReactor

        takes = self.takes or self
        if takes.live is not None:
            return LiveReactor(self, takes.live, label, scale, seed)
        return OnlineReactor(takes, label, scale, seed)

    @contextlib.contextmanager
    def probing(self):
        """One sampler step from pure noise: the reaction's placement without the sampler's cost."""
        guidance = self.guidance
        self.guidance = replace(guidance, sample_steps=1, memory_level=1.0)
        try:
            with super().probing():
                yield self
        finally:
            self.guidance = guidance

    def use_memory(self, level: float, data) -> None:
        """Start the sampler from real reactions to similar leaders (the reaction memory of `data`'s pairs the model was
        trained on), noised to `level` 0..1 (1: from pure noise)."""
        try:
            self.guidance = replace(self.guidance, memory_level=level)
        except ValueError as err:
            raise LabelError(f"memory level: {err}") from None
        self.attach_memory(data)
        if self.takes is not None:
            self.takes.use_memory(level, data)

    def provenance(self, seed: int) -> dict[str, Any]:
        return super().provenance(seed) | {"memory": self.guidance.memory_level if self.guidance.uses_memory else None}

    def attach_memory(self, data, indices=None) -> None:
        """Give the sampler its reaction memory: `data`'s pairs `indices`, by default every pair of the subjects the
        model was trained on (never its held-out subject's)."""
        from imm_model.data.splits import loso_fold
        from imm_model.families.diffusion.reaction_memory import ReactionMemory

        check_compatible(self, data, "reaction memory")
        if indices is None:
            indices = np.arange(len(data)) if self.held_out_subject is None else loso_fold(data.subject_pairs, self.held_out_subject).train
        self.memory = ReactionMemory.from_dataset(data, indices)

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) or (N, 2C) labels -> (N, width): the denoiser's last hidden state, averaged over
        frames, for the leader and label with the follower all noise (the first sampler step's view of the reaction). A
        whole-label network places a label per body part as its whole-body mean (a place on the map, not a reaction)."""
        labels = self._label_array(label_vectors, len(leaders))
        labels = self._label_input(labels) if self.config.part_labels else whole_body(labels, len(self.class_names))
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


def teacher_for_takes(meta: dict[str, Any], path: Path, device: str = "cpu") -> DiffusionReactionModel | None:
    """A distilled student's teacher (distill.py), loaded to make the student's long takes and live reactions: the
    diffusion checkpoint its sidecar names (relative to the student's folder), when that file holds the very weights it
    was distilled from and is no student itself. None for a model that is no student, or whose teacher is not there as
    it was (then the student makes them itself); its weights are loaded only once its sidecar matches."""
    from imm_model.checkpoint import DIGEST, load_checkpoint, peek_sidecar

    named = meta.get("teacher")
    if not (isinstance(named, dict) and isinstance(named.get("path"), str) and isinstance(named.get(DIGEST), str)):
        return None
    where = Path(path).parent / named["path"]
    try:
        if not where.is_file():
            return None
        side = peek_sidecar(where)
        if side.get(DIGEST) != named[DIGEST] or side.get("family") != "diffusion" or "teacher" in side:
            return None
        arrays, teacher_meta = load_checkpoint(where, framework="np")
    except (OSError, ValueError, CheckpointError):
        return None
    return DiffusionReactionModel.from_checkpoint(arrays, teacher_meta, where, device)
