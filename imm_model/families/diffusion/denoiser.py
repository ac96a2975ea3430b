"""The reaction diffusion model's network in torch (training, GPUs): a transformer denoiser over the follower's frames,
conditioned per frame on the leader and per sequence on the diffusion step and the label (sampler.py
has the composition it serves; denoiser_numpy.py the same network in numpy for one CPU)."""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

from imm_model.families.diffusion.sampler import DiffusionConfig


def sinusoid(positions: torch.Tensor, width: int) -> torch.Tensor:
    """positions (...,) -> (..., width) sinusoidal features (Vaswani et al. 2017)."""
    half = width // 2
    freq = torch.exp(-math.log(10_000.0) * torch.arange(half, dtype=torch.float32, device=positions.device) / half)
    angle = positions.float()[..., None] * freq
    return torch.cat([angle.sin(), angle.cos()], -1)


# ---- the network ----------------------------------------------------------------------------------------------
class Block(nn.Module):
    """Pre-norm transformer block whose norms are modulated by the conditioning vector (DiT's adaLN-zero: each
    block starts as the identity, so a deep stack trains from the first step)."""

    def __init__(self, width: int, heads: int, ff_mult: int, dropout: float):
        super().__init__()
        self.heads = heads
        self.norm1 = nn.LayerNorm(width, elementwise_affine=False)
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        self.norm2 = nn.LayerNorm(width, elementwise_affine=False)
        self.mlp = nn.Sequential(nn.Linear(width, ff_mult * width), nn.GELU(approximate="tanh"),
                                 nn.Linear(ff_mult * width, width))  # tanh GELU: ~30x cheaper in numpy than erf
        self.modulation = nn.Linear(width, 6 * width)
        nn.init.zeros_(self.modulation.weight)
        nn.init.zeros_(self.modulation.bias)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, cond: torch.Tensor, pad: torch.Tensor | None) -> torch.Tensor:
        # x (B, T, W), cond (B, W), pad (B, 1, 1, T) additive attention mask or None
        shift1, scale1, gate1, shift2, scale2, gate2 = self.modulation(cond)[:, None].chunk(6, -1)
        h = self.norm1(x) * (1 + scale1) + shift1
        b, t, w = h.shape
        q, k, v = self.qkv(h).view(b, t, 3, self.heads, w // self.heads).permute(2, 0, 3, 1, 4)
        att = torch.nn.functional.scaled_dot_product_attention(q, k, v, attn_mask=pad)
        x = x + gate1 * self.drop(self.proj(att.transpose(1, 2).reshape(b, t, w)))
        h = self.norm2(x) * (1 + scale2) + shift2
        return x + gate2 * self.drop(self.mlp(h))


class ReactionDenoiser(nn.Module):
    """x_t (B, T, D) normalized follower + leader (B, T, D) normalized + step (B,) + label (B, L) -> x0 (B, T, D), L the
    config's label_width.

    `leader_on` / `label_on` (B,) bool select the real input or the learned "absent" one per row. With
    `cfg.leader_noise`, `leader_level` (B,) is the step of the forward process whose noise the leader carries
    (0 = clean), embedded like the step. The pose
    normalization (per-coordinate mean and std of the training followers and leaders) lives in buffers, so the
    checkpoint carries it."""

    def __init__(self, cfg: DiffusionConfig):
        super().__init__()
        self.cfg = cfg
        w, d, k = cfg.width, cfg.pose_dim, cfg.frames_per_token
        self.input = nn.Linear(k * (2 * d + 1), w)  # k frames of [x_t, leader, leader present]
        self.absent_leader = nn.Parameter(torch.zeros(d))
        self.step_mlp = nn.Sequential(nn.Linear(w, w), nn.SiLU(), nn.Linear(w, w))
        if cfg.leader_noise:
            self.leader_noise_mlp = nn.Sequential(nn.Linear(w, w), nn.SiLU(), nn.Linear(w, w))
        self.label = nn.Linear(cfg.label_width, w)  # one value per class (per class and part for a part model)
        self.absent_label = nn.Parameter(torch.zeros(w))
        self.blocks = nn.ModuleList(Block(w, cfg.heads, cfg.ff_mult, cfg.dropout) for _ in range(cfg.layers))
        self.out_norm = nn.LayerNorm(w)
        self.output = nn.Linear(w, k * d)
        for name in ("follower_mean", "leader_mean"):
            self.register_buffer(name, torch.zeros(d))
        for name in ("follower_std", "leader_std"):
            self.register_buffer(name, torch.ones(d))

    def set_normalization(self, leaders: np.ndarray, followers: np.ndarray) -> None:
        """From training frames (F, D) of both characters; stds floored at 1 cm so a still coordinate stays finite."""
        for who, frames in (("leader", leaders), ("follower", followers)):
            getattr(self, f"{who}_mean").copy_(torch.as_tensor(frames.mean(0), dtype=torch.float32))
            getattr(self, f"{who}_std").copy_(torch.as_tensor(np.maximum(frames.std(0), 0.01), dtype=torch.float32))

    def normalize(self, poses: torch.Tensor, who: str) -> torch.Tensor:
        return (poses - getattr(self, f"{who}_mean")) / getattr(self, f"{who}_std")

    def denormalize_follower(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.follower_std + self.follower_mean

    def forward(self, x_t: torch.Tensor, step: torch.Tensor, leader: torch.Tensor, leader_on: torch.Tensor,
                label: torch.Tensor, label_on: torch.Tensor, mask: torch.Tensor | None = None,
                return_hidden: bool = False, leader_level: torch.Tensor | None = None) -> torch.Tensor:
        b, t, d = x_t.shape
        k = self.cfg.frames_per_token
        mask = torch.ones(b, t, dtype=torch.bool, device=x_t.device) if mask is None else mask
        leader = torch.where(leader_on[:, None, None], leader, self.absent_leader)
        present = leader_on[:, None, None].float().expand(b, t, 1)
        frames = torch.cat([x_t, leader, present], -1) * mask[..., None]  # padding reads zeros, in a batch or alone
        pad_frames = -t % k  # the sequence is padded to whole tokens; padded frames are masked out
        if pad_frames:
            frames = torch.nn.functional.pad(frames, (0, 0, 0, pad_frames))
            mask = torch.nn.functional.pad(mask, (0, pad_frames))
        tokens = (t + pad_frames) // k
        h = self.input(frames.reshape(b, tokens, -1)) + sinusoid(torch.arange(tokens, device=x_t.device) * k, self.cfg.width)
        cond = self.step_mlp(sinusoid(step, self.cfg.width))
        cond = cond + torch.where(label_on[:, None], self.label(label), self.absent_label)
        if self.cfg.leader_noise:
            level = torch.zeros(b, device=x_t.device) if leader_level is None else leader_level
            cond = cond + self.leader_noise_mlp(sinusoid(level, self.cfg.width))
        token_mask = mask.reshape(b, tokens, k).any(-1)
        pad = None
        if not bool(token_mask.all()):
            pad = torch.zeros(b, 1, 1, tokens, device=x_t.device).masked_fill(~token_mask[:, None, None], float("-inf"))
        for block in self.blocks:
            h = block(h, cond, pad)
        h = self.out_norm(h)
        if return_hidden:
            return h, token_mask
        return self.output(h).reshape(b, tokens * k, d)[:, :t]


def torch_denoiser(net: ReactionDenoiser, leaders: np.ndarray, mask: np.ndarray, leader_level: int = 0):
    """`sample`'s denoise function for the torch network (training checks, GPUs): leaders (B, T, D) normalized,
    carrying the forward process's noise at step `leader_level` (0: clean)."""
    device = next(net.parameters()).device
    leaders_t, mask_t = torch.as_tensor(leaders, device=device), torch.as_tensor(mask, device=device)

    tiled: dict[int, tuple[torch.Tensor, torch.Tensor]] = {}  # leaders and mask repeated once per term count

    @torch.inference_mode()
    def denoise(x_t, step, leader_on, label, label_on):
        reps = len(x_t) // len(leaders)
        if reps not in tiled:
            tiled[reps] = leaders_t.repeat(reps, 1, 1), mask_t.repeat(reps, 1)
        as_t = lambda a: torch.as_tensor(a, device=device)  # noqa: E731
        on = as_t(leader_on)
        x0 = net(as_t(x_t), torch.full((len(x_t),), step, device=device), tiled[reps][0], on, as_t(label),
                 as_t(label_on), tiled[reps][1], leader_level=on.float() * leader_level)
        return x0.cpu().numpy()

    return denoise


def q_sample(x0: torch.Tensor, step: torch.Tensor, noise: torch.Tensor, alpha_bar: torch.Tensor) -> torch.Tensor:
    """The forward process: x_t = sqrt(alpha_bar_t) x0 + sqrt(1 - alpha_bar_t) noise; x0, noise (B, T, D), step (B,)."""
    a = alpha_bar[step][:, None, None]
    return a.sqrt() * x0 + (1 - a).sqrt() * noise
