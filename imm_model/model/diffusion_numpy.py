"""The reaction diffusion model's denoiser (model/diffusion.py) in numpy, for sampling on a CPU.

Why by hand: the studio never imports torch (model/numpy_runtime.py says why), and a sampler step is ~60 small
operations, where numpy's per-call cost is a fraction of torch's. The numbers are the torch module's
(tests/test_diffusion.py compares them); training and GPUs stay on torch.

Weights are the torch module's state dict as float32 numpy arrays, under the same names.
"""

from __future__ import annotations

import math

import numpy as np

from imm_model.model.diffusion_sampler import DiffusionConfig


def sinusoid(positions: np.ndarray, width: int) -> np.ndarray:
    half = width // 2
    freq = np.exp(-math.log(10_000.0) * np.arange(half, dtype=np.float32) / half).astype(np.float32)
    angle = positions.astype(np.float32)[..., None] * freq
    return np.concatenate([np.sin(angle), np.cos(angle)], -1)


def _layer_norm(x: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    mean = x.mean(-1, keepdims=True)
    centred = x - mean
    return centred / np.sqrt((centred * centred).mean(-1, keepdims=True) + eps)


def _gelu(x: np.ndarray) -> np.ndarray:
    """GELU, tanh form (the torch module's nn.GELU(approximate="tanh"))."""
    return 0.5 * x * (1.0 + np.tanh(np.float32(math.sqrt(2.0 / math.pi)) * (x + np.float32(0.044715) * x * x * x)))


def _silu(x: np.ndarray) -> np.ndarray:
    return x / (1.0 + np.exp(-x))


class NumpyDenoiser:
    """ReactionDenoiser.forward on numpy arrays: x_t (B, T, D) normalized, step int, leader (B, T, D) normalized,
    leader_on (B,), label (B, C), label_on (B,), mask (B, T) -> x0 (B, T, D) float32."""

    def __init__(self, weights: dict[str, np.ndarray], cfg: DiffusionConfig):
        self.cfg = cfg
        self.w = {k: np.asarray(v, np.float32) for k, v in weights.items()}
        # (in, out) layouts once, so every call is a plain x @ W + b
        self.linear = {k[: -len(".weight")]: (np.ascontiguousarray(v.T), self.w[k[: -len(".weight")] + ".bias"])
                       for k, v in self.w.items() if k.endswith(".weight") and k[: -len(".weight")] + ".bias" in self.w}

    def _lin(self, name: str, x: np.ndarray) -> np.ndarray:
        w, b = self.linear[name]
        return x @ w + b

    def normalize(self, poses: np.ndarray, who: str) -> np.ndarray:
        return (poses - self.w[f"{who}_mean"]) / self.w[f"{who}_std"]

    def denormalize_follower(self, x: np.ndarray) -> np.ndarray:
        return x * self.w["follower_std"] + self.w["follower_mean"]

    @staticmethod
    def expected_shapes(cfg: DiffusionConfig) -> dict[str, tuple[int, ...]]:
        """The torch module's state-dict names and shapes, for checking a checkpoint without torch."""
        w, d, k, c = cfg.width, cfg.pose_dim, cfg.frames_per_token, cfg.num_classes
        shapes: dict[str, tuple[int, ...]] = {
            "input.weight": (w, k * (2 * d + 1)), "input.bias": (w,), "absent_leader": (d,),
            "step_mlp.0.weight": (w, w), "step_mlp.0.bias": (w,), "step_mlp.2.weight": (w, w), "step_mlp.2.bias": (w,),
            "label.weight": (w, c), "label.bias": (w,), "absent_label": (w,),
            "out_norm.weight": (w,), "out_norm.bias": (w,), "output.weight": (k * d, w), "output.bias": (k * d,),
            **{f"{who}_{stat}": (d,) for who in ("follower", "leader") for stat in ("mean", "std")},
        }
        ff = cfg.ff_mult * w
        for i in range(cfg.layers):
            for name, (out, inp) in (("qkv", (3 * w, w)), ("proj", (w, w)), ("mlp.0", (ff, w)), ("mlp.2", (w, ff)),
                                     ("modulation", (6 * w, w))):
                shapes[f"blocks.{i}.{name}.weight"], shapes[f"blocks.{i}.{name}.bias"] = (out, inp), (out,)
        return shapes

    def __call__(self, x_t: np.ndarray, step: int, leader: np.ndarray, leader_on: np.ndarray, label: np.ndarray,
                 label_on: np.ndarray, mask: np.ndarray, return_hidden: bool = False):
        cfg, w = self.cfg, self.w
        b, t, d = x_t.shape
        k, width, heads = cfg.frames_per_token, cfg.width, cfg.heads
        leader = np.where(leader_on[:, None, None], leader, w["absent_leader"])
        present = np.broadcast_to(leader_on[:, None, None].astype(np.float32), (b, t, 1))
        frames = np.concatenate([x_t, leader, present], -1) * mask[..., None]
        pad_frames = -t % k
        if pad_frames:
            frames = np.pad(frames, ((0, 0), (0, pad_frames), (0, 0)))
            mask = np.pad(mask, ((0, 0), (0, pad_frames)))
        tokens = (t + pad_frames) // k
        h = self._lin("input", frames.reshape(b, tokens, -1)) + sinusoid(np.arange(tokens) * k, width)
        cond = self._lin("step_mlp.2", _silu(self._lin("step_mlp.0", sinusoid(np.full(b, step), width))))
        cond = cond + np.where(label_on[:, None], self._lin("label", label), w["absent_label"])
        token_mask = mask.reshape(b, tokens, k).any(-1)
        pad = np.where(token_mask, 0.0, -np.inf).astype(np.float32)[:, None, None, :]  # (B, 1, 1, tokens)
        dh = width // heads
        for i in range(cfg.layers):
            name = f"blocks.{i}"
            shift1, scale1, gate1, shift2, scale2, gate2 = np.split(self._lin(f"{name}.modulation", cond)[:, None], 6, -1)
            z = _layer_norm(h) * (1 + scale1) + shift1
            q, kk, v = self._lin(f"{name}.qkv", z).reshape(b, tokens, 3, heads, dh).transpose(2, 0, 3, 1, 4)
            scores = q @ kk.transpose(0, 1, 3, 2) / np.float32(math.sqrt(dh)) + pad
            scores = np.exp(scores - scores.max(-1, keepdims=True))
            att = (scores / scores.sum(-1, keepdims=True)) @ v  # (B, heads, tokens, dh)
            h = h + gate1 * self._lin(f"{name}.proj", att.transpose(0, 2, 1, 3).reshape(b, tokens, width))
            z = _layer_norm(h) * (1 + scale2) + shift2
            h = h + gate2 * self._lin(f"{name}.mlp.2", _gelu(self._lin(f"{name}.mlp.0", z)))
        h = _layer_norm(h) * w["out_norm.weight"] + w["out_norm.bias"]
        if return_hidden:
            return h, token_mask
        return self._lin("output", h).reshape(b, tokens * k, d)[:, :t].astype(np.float32)
