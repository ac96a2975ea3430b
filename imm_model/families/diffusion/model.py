"""The reaction diffusion model (sampler.py) behind the ReactionModel API: a seed picks one of many reactions."""

from __future__ import annotations

import contextlib
import functools
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.data.labels import whole_body
from imm_model.errors import CheckpointError, LabelError
from imm_model.families.base import ReactionModel, SamplerSettings, check_compatible, described_weights
from imm_model.families.diffusion.denoiser_numpy import NumpyDenoiser
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance, sample


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
        self.memory = None  # the reaction memory (reaction_memory.py) its sampler may start from
        # the sampling loop, sampler.py `sample` (an experiment may put another with its signature here: it gets the
        # network call, the normalized leaders and masks, labels, starting noise, guidance, steps, seeds, and the
        # network's pair_terms and part_labels)
        self.sampler = sample

    @property
    def settings(self) -> SamplerSettings:
        return SamplerSettings(seed=True, spread=self.config.leader_noise, memory=True)

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

    @functools.cached_property
    def net(self):
        """The torch ReactionDenoiser with these weights, on `device` (built when first needed)."""
        from imm_model.families.diffusion.denoiser import ReactionDenoiser

        return self._torch_module(ReactionDenoiser, self.config, "denoiser")

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu",
                        data: Path | None = None):
        from imm_model.checkpoint import check_state

        cfg, weights = described_weights(arrays, meta, path, DiffusionConfig, cls.weights_prefix)
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

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        from imm_model.families.diffusion.sampler import forward_noised, initial_noise, noised_leaders, schedule_step

        d, steps = self.config.pose_dim, self.config.diffusion_steps
        level = schedule_step(self.guidance.leader_noise, steps)
        if level and not self.config.leader_noise:
            raise LabelError(f"leader noise {self.guidance.leader_noise:g} needs a model trained with noised leaders "
                             "(this one reads only the clean leader)")
        labels = self._label_input(labels)
        join = self.join_parts if self.guidance.part_join and labels.shape[1] == 2 * len(self.class_names) else None
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
            x0 = self.sampler(denoise, x, mask, labels[rows], noise, self.guidance, steps, seeds=[seeds[i] for i in rows],
                              pair_terms=self.config.pair_terms, part_labels=self.config.part_labels, join=join)
            followers = x0 * self.weights["follower_std"] + self.weights["follower_mean"]
            out += [followers[k, : len(leaders[i])].reshape(len(leaders[i]), -1, 3) for k, i in enumerate(rows)]
        return out

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
