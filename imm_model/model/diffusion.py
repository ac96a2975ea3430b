"""The reaction diffusion model: a leader-conditioned transformer denoiser over the follower's frames, its noise
schedule, and a DDIM sampler that composes the signed multi-hot label.

The network predicts the clean follower x0 from a noised one x_t, given per frame the leader's pose and, for the
whole sequence, the diffusion step and a label. Training drops the label and the leader independently (each
replaced by a learned "absent" input), so one network gives every term the sampler composes:

    x0(A, {w_c}) = x0(A, -) + s * sum_c w_c * (x0(A, e_c) - x0(A, -))

the composable-diffusion rule (Liu et al., ECCV 2022) on top of the leader-conditioned, label-free reaction: a
class at +1 is a conjunction, at -1 a negation, fractions weigh it, the studio's scale multiplies every w_c and
`s` is the model's guidance strength. All-zero labels give the label-free reaction. The leader term itself can be
guided too (x0(-, -) + g * (x0(A, -) - x0(-, -))) when g != 1.

A sampler seed fixes the starting noise and nothing else, and DDIM (eta = 0) is deterministic given it, so the
reaction is a continuous function of the label: a moved slider moves the reaction, it does not jump to another
sample.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from imm_model.typed_config import checked_kwargs

MAX_WIDTH = 2048


@dataclass(frozen=True)
class DiffusionConfig:
    num_joints: int = 15
    num_classes: int = 6
    width: int = 128  # transformer token width
    layers: int = 4  # transformer blocks
    heads: int = 4  # attention heads per block (width must divide by it)
    ff_mult: int = 2  # the blocks' MLP is ff_mult * width wide
    dropout: float = 0.1  # on attention and MLP outputs, training only
    diffusion_steps: int = 100  # T of the cosine noise schedule the network is trained on

    def __post_init__(self) -> None:
        for name, lo, hi in (("num_joints", 1, 512), ("num_classes", 1, 512), ("width", 8, MAX_WIDTH), ("layers", 1, 64),
                             ("heads", 1, 64), ("ff_mult", 1, 16), ("diffusion_steps", 2, 10_000)):
            if not lo <= getattr(self, name) <= hi:
                raise ValueError(f"diffusion config: {name} must be in {lo}..{hi}, not {getattr(self, name)!r}")
        if self.width % self.heads:
            raise ValueError(f"diffusion config: width {self.width} must be a multiple of heads {self.heads}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"diffusion config: dropout must be in [0, 1), not {self.dropout!r}")

    @property
    def pose_dim(self) -> int:
        return 3 * self.num_joints

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> DiffusionConfig:
        return cls(**checked_kwargs(cls, d, "diffusion config"))


# ---- noise schedule -------------------------------------------------------------------------------------------
def cosine_alpha_bar(steps: int) -> np.ndarray:
    """(steps,) cumulative signal fraction alpha_bar_t for t = 0..steps-1 (Nichol & Dhariwal 2021), float64."""
    s = 0.008
    t = np.arange(steps + 1, dtype=np.float64) / steps
    f = np.cos((t + s) / (1 + s) * math.pi / 2) ** 2
    alpha_bar = f[1:] / f[0]
    betas = np.clip(1 - alpha_bar / np.concatenate([[1.0], alpha_bar[:-1]]), 0, 0.999)
    return np.cumprod(1 - betas)


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
        self.mlp = nn.Sequential(nn.Linear(width, ff_mult * width), nn.GELU(), nn.Linear(ff_mult * width, width))
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
    """x_t (B, T, D) normalized follower + leader (B, T, D) normalized + step (B,) + label (B, C) -> x0 (B, T, D).

    `leader_on` / `label_on` (B,) bool select the real input or the learned "absent" one per row. The pose
    normalization (per-coordinate mean and std of the training followers and leaders) lives in buffers, so the
    checkpoint carries it."""

    def __init__(self, cfg: DiffusionConfig):
        super().__init__()
        self.cfg = cfg
        w, d = cfg.width, cfg.pose_dim
        self.input = nn.Linear(2 * d + 1, w)  # [x_t, leader, leader present]
        self.absent_leader = nn.Parameter(torch.zeros(d))
        self.step_mlp = nn.Sequential(nn.Linear(w, w), nn.SiLU(), nn.Linear(w, w))
        self.label = nn.Linear(cfg.num_classes, w)
        self.absent_label = nn.Parameter(torch.zeros(w))
        self.blocks = nn.ModuleList(Block(w, cfg.heads, cfg.ff_mult, cfg.dropout) for _ in range(cfg.layers))
        self.out_norm = nn.LayerNorm(w)
        self.output = nn.Linear(w, d)
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
                return_hidden: bool = False) -> torch.Tensor:
        b, t, _ = x_t.shape
        leader = torch.where(leader_on[:, None, None], leader, self.absent_leader)
        present = leader_on[:, None, None].float().expand(b, t, 1)
        h = self.input(torch.cat([x_t, leader, present], -1)) + sinusoid(torch.arange(t, device=x_t.device), self.cfg.width)
        cond = self.step_mlp(sinusoid(step, self.cfg.width))
        cond = cond + torch.where(label_on[:, None], self.label(label), self.absent_label)
        pad = None
        if mask is not None and not bool(mask.all()):
            pad = torch.zeros(b, 1, 1, t, device=x_t.device).masked_fill(~mask[:, None, None], float("-inf"))
        for block in self.blocks:
            h = block(h, cond, pad)
        h = self.out_norm(h)
        return h if return_hidden else self.output(h)


# ---- sampling -------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Guidance:
    """How the sampler composes its terms; stored with each trained model as its defaults."""

    label_scale: float = 2.5  # s: the strength of each class term (times the label value)
    leader_scale: float = 1.0  # g: guidance on the leader term; 1 = the leader-conditioned term alone
    sample_steps: int = 20  # DDIM steps
    clip: float = 6.0  # x0 predictions clamped to this many training standard deviations per coordinate

    def __post_init__(self) -> None:
        for name, lo, hi in (("label_scale", 0.0, 20.0), ("leader_scale", 0.0, 20.0), ("clip", 0.5, 100.0)):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and lo <= value <= hi):
                raise ValueError(f"guidance: {name} must be in [{lo}, {hi}], not {value!r}")
        if not (isinstance(self.sample_steps, int) and 1 <= self.sample_steps <= 1000):
            raise ValueError(f"guidance: sample_steps must be an integer in 1..1000, not {self.sample_steps!r}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Guidance:
        return cls(**checked_kwargs(cls, d, "guidance"))


def initial_noise(seed: int, frames: int, dim: int) -> np.ndarray:
    """The sampler's starting point for one sequence: a function of the seed and the shape only (float32)."""
    return np.random.default_rng(int(seed)).standard_normal((frames, dim)).astype(np.float32)


@torch.inference_mode()
def sample(net: ReactionDenoiser, leaders: torch.Tensor, mask: torch.Tensor, labels: torch.Tensor, noise: torch.Tensor,
           guidance: Guidance) -> torch.Tensor:
    """DDIM (eta 0) from `noise` (B, T, D) -> followers (B, T, D) in metres (canonical frame).

    leaders (B, T, D) metres, mask (B, T) valid frames, labels (B, C) signed weights (already times the scale).
    Each step evaluates, in one batch, the leader-only term, one term per class any row weighs, and (with
    leader_scale != 1) the unconditioned term."""
    b, t, d = noise.shape
    c = labels.shape[1]
    classes = torch.nonzero(labels.abs().sum(0) > 0).flatten().tolist()  # classes some row asks about
    n_terms = 1 + len(classes) + (guidance.leader_scale != 1.0)
    leader_n = net.normalize(leaders, "leader").repeat(n_terms, 1, 1)
    mask_n = mask.repeat(n_terms, 1)
    one_hot = torch.zeros(n_terms, b, c, device=noise.device)
    label_on = torch.zeros(n_terms, b, dtype=torch.bool, device=noise.device)
    for k, cls in enumerate(classes, start=1):
        one_hot[k, :, cls] = 1.0
        label_on[k] = True
    leader_on = torch.ones(n_terms, b, dtype=torch.bool, device=noise.device)
    if guidance.leader_scale != 1.0:
        leader_on[-1] = False
    one_hot, label_on, leader_on = one_hot.flatten(0, 1), label_on.flatten(), leader_on.flatten()
    weights = labels[:, classes].T[..., None, None] * guidance.label_scale  # (K, B, 1, 1)

    alpha_bar = torch.as_tensor(cosine_alpha_bar(net.cfg.diffusion_steps), dtype=torch.float32, device=noise.device)
    steps = np.linspace(net.cfg.diffusion_steps - 1, 0, guidance.sample_steps).round().astype(int)
    x = noise
    m = mask[..., None].float()
    for i, step in enumerate(steps):
        step_t = torch.full((n_terms * b,), int(step), device=noise.device)
        x0_terms = net(x.repeat(n_terms, 1, 1), step_t, leader_n, leader_on, one_hot, label_on, mask_n).view(n_terms, b, t, d)
        base = x0_terms[0]
        x0 = base
        if classes:
            x0 = x0 + (weights * (x0_terms[1:1 + len(classes)] - base)).sum(0)
        if guidance.leader_scale != 1.0:
            x0 = x0_terms[-1] + guidance.leader_scale * (x0 - x0_terms[-1])
        x0 = x0.clamp(-guidance.clip, guidance.clip) * m
        a = alpha_bar[step]
        if i + 1 == len(steps):
            x = x0
            break
        a_next = alpha_bar[steps[i + 1]]
        eps = (x - a.sqrt() * x0) / (1 - a).sqrt()
        x = (a_next.sqrt() * x0 + (1 - a_next).sqrt() * eps) * m
    return net.denormalize_follower(x) * m


def q_sample(x0: torch.Tensor, step: torch.Tensor, noise: torch.Tensor, alpha_bar: torch.Tensor) -> torch.Tensor:
    """The forward process: x_t = sqrt(alpha_bar_t) x0 + sqrt(1 - alpha_bar_t) noise; x0, noise (B, T, D), step (B,)."""
    a = alpha_bar[step][:, None, None]
    return a.sqrt() * x0 + (1 - a).sqrt() * noise
