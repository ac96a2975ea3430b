"""The paper's GAN behind the ReactionModel API: the hierarchical Bi-LSTM generator, one reaction per leader and label.

One sequence on a CPU runs in numpy (numpy_generator.py: the same numbers, as fast, and no `import torch`, which was
most of the studio's start); batches, GPUs and the paper's frame-by-frame decoder run the torch generator."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np

from imm_model.families.base import ReactionModel, described_weights
from imm_model.families.gan.config import ModelConfig
from imm_model.families.gan.numpy_generator import NumpyGenerator


class GanReactionModel(ReactionModel):
    family = "gan"
    title = "the paper's GAN"
    weights_prefix = "generator"

    def __init__(self, weights: dict[str, np.ndarray], config: ModelConfig, meta: dict[str, Any], path: Path | None = None,
                 device: str = "cpu"):
        super().__init__(weights, meta, path, device)
        self.config = config
        self.fast = NumpyGenerator(weights, config) if self.device == "cpu" and NumpyGenerator.supports(config) else None

    @classmethod
    def from_checkpoint(cls, arrays: dict[str, np.ndarray], meta: dict[str, Any], path: Path, device: str = "cpu",
                        data: Path | None = None):
        from imm_model.checkpoint import check_state

        cfg, weights = described_weights(arrays, meta, path, ModelConfig, cls.weights_prefix)
        if NumpyGenerator.supports(cfg):
            check_state(weights, NumpyGenerator.expected_shapes(cfg), "generator", path)
        model = cls({k: v.astype(np.float32) for k, v in weights.items()}, cfg, meta, path, device)
        if model.fast is None:
            model.generator  # noqa: B018 - torch's strict load checks the weights now, not at the first synthesis
        return model

    @functools.cached_property
    def generator(self):
        """The torch Generator with these weights, on `device` (built when first needed)."""
        from imm_model.families.gan.generator import Generator

        return self._torch_module(Generator, self.config, "generator")

    def _network(self, leaders: list[np.ndarray], labels: np.ndarray, seeds: list[int]) -> list[np.ndarray]:
        """The generator's own followers (T_i, J, 3): numpy for one sequence on a CPU, else one torch batch (the
        generator is deterministic: seeds change nothing)."""
        if self.fast is not None and len(leaders) == 1:
            t = len(leaders[0])
            return [self.fast(np.asarray(leaders[0], np.float32).reshape(t, -1), labels[0]).reshape(t, -1, 3)]
        out, lengths = self._run_batch(leaders, labels, latent=False)
        return [out[i, : lengths[i]].reshape(lengths[i], -1, 3) for i in range(len(leaders))]

    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray:
        """N canonical leaders + (N, C) label vectors -> (N, D): the hierarchical encoder's outputs averaged over frames."""
        if self.fast is not None:
            labels = self._label_array(label_vectors, len(leaders))
            return np.stack([self.fast.encode(np.asarray(a, np.float32).reshape(len(a), -1), lab).mean(0)
                             for a, lab in zip(leaders, labels, strict=True)])
        out, _ = self._run_batch(leaders, label_vectors, latent=True)
        return out

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
