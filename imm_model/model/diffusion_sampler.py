"""The reaction diffusion model without its network: sizes, noise schedule, guidance and the DDIM sampler that
composes the signed multi-hot label. numpy only, so that the studio samples without importing torch.

The network (model/diffusion.py in torch for training and GPUs, model/diffusion_numpy.py in numpy for one CPU) predicts
the clean follower x0 from a noised one x_t, given per frame the leader's pose and, for the whole sequence, the
diffusion step and a label. Training drops the label and the leader independently (each replaced by a learned
"absent" input), so one network gives every term the sampler composes:

    x0(A, {w_c}) = x0(A, -) + s * sum_c w_c * (x0(A, e_c) - x0(A, -))

the composable-diffusion rule (Liu et al., ECCV 2022) on top of the leader-conditioned, label-free reaction: a
class at +1 is a conjunction, at -1 a negation, fractions weigh it, the studio's scale multiplies every w_c and
`s` is the model's guidance strength. All-zero labels give the label-free reaction. The leader term itself can be
guided too (x0(-, -) + g * (x0(A, -) - x0(-, -))) when g != 1.

With composition "parts" the classes at a positive value share the body instead of all moving all of it: per step
and per body part k (the skeleton's parts, each relative to the body centre, and the centre's own trajectory, the
placement), with d_c = x0(A, e_c) - x0(A, -) in metres, m_ck its RMS over the part's joints and the frames,
responsibilities r_ck = w_c m_ck^p / sum_c' w_c' m_c'k^p and W = sum_c w_c (positive values only):

    x0 = x0(A, -) + s * sum_c W * r_ck * d_ck  (+ today's s * w_c * d_c for each negative w_c)

so each part follows the classes whose terms move it most, as a person mixes two actions (one on the arms, the other
in the steps). One class gives r = 1 and W = w: exactly the sum rule (so does p = 0); a class's share fades with its
value, so the reaction stays continuous in the label.

A sampler seed fixes the starting noise and nothing else, and DDIM (eta = 0) is deterministic given it, so the
reaction is a continuous function of the label: a moved slider moves the reaction, it does not jump to another
sample.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import ClassVar

import numpy as np

from imm_model.typed_config import Interval, OneOf, checked_kwargs, param, validate

MAX_WIDTH = 2048
COMPOSITIONS = ("sum", "parts")  # how classes at a positive value combine (the module docstring)


@dataclass(frozen=True)
class DiffusionConfig:
    num_joints: int = param(15, Interval(int, 1, 512))  # joints per character (from the data)
    num_classes: int = param(6, Interval(int, 1, 512))  # interaction classes, the label's length (from the data)
    width: int = param(128, Interval(int, 8, MAX_WIDTH))  # transformer token width
    layers: int = param(4, Interval(int, 1, 64))  # transformer blocks
    heads: int = param(4, Interval(int, 1, 64))  # attention heads per block (width must divide by it)
    ff_mult: int = param(2, Interval(int, 1, 16))  # the blocks' MLP is ff_mult * width wide
    dropout: float = param(0.1, Interval(float, 0, 1, closed="left"))  # on attention and MLP outputs, training only
    diffusion_steps: int = param(100, Interval(int, 2, 10_000))  # T of the cosine noise schedule the network is trained on
    frames_per_token: int = param(1, Interval(int, 1, 8))  # consecutive frames one transformer token carries

    RULES: ClassVar = (("width", lambda c: c.width % c.heads == 0, "a multiple of heads"),)

    def __post_init__(self) -> None:
        validate(self, "diffusion config")

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


# ---- sampling ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Guidance:
    """How the sampler composes its terms; stored with each trained model as its defaults."""

    label_scale: float = param(2.5, Interval(float, 0, 20))  # s: the strength of each class term (times the label value)
    leader_scale: float = param(1.0, Interval(float, 0, 20))  # g: guidance on the leader term; 1 = the leader term alone
    sample_steps: int = param(20, Interval(int, 1, 1000))  # DDIM steps
    clip: float = param(6.0, Interval(float, 0.5, 100))  # x0 predictions clamped to this many training stds per coordinate
    composition: str = param("sum", OneOf(COMPOSITIONS))  # positive classes: "sum" of their terms, or "parts" sharing the body
    routing_power: float = param(2.0, Interval(float, 0, 64))  # p of "parts": 0 = the sum rule, larger = one class per part

    def __post_init__(self) -> None:
        validate(self, "guidance")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Guidance:
        return cls(**checked_kwargs(cls, d, "guidance"))


@dataclass(frozen=True)
class BodyRouting:
    """What "parts" composition needs from the model: the joint groups that share out the body, the joints whose mean
    is the body centre, and the followers' per-coordinate std (D,) to turn normalized differences into metres."""

    groups: tuple[tuple[int, ...], ...]
    centre: tuple[int, ...]
    scale: np.ndarray

    @classmethod
    def of(cls, skeleton, follower_std: np.ndarray) -> BodyRouting:
        """The skeleton's body parts (every joint in none of them is a group of its own) and centre (the root's
        neighbours, as the body-part judges read it)."""
        groups = [tuple(int(j) for j in js) for js in skeleton.body_parts.values()]
        seen = {j for g in groups for j in g}
        groups += [(j,) for j in range(skeleton.num_joints) if j not in seen]
        scale = np.asarray(follower_std, np.float64).reshape(-1)
        if scale.shape != (3 * skeleton.num_joints,) or not np.all(scale > 0):
            raise ValueError(f"body routing needs {3 * skeleton.num_joints} positive follower stds")
        return cls(tuple(groups), tuple(int(j) for j in skeleton.root_neighbours), scale)


def part_responsibilities(rms: np.ndarray, weights: np.ndarray, power: float) -> np.ndarray:
    """rms (K, R, P) each class's difference per row and part (metres), weights (K, R) its positive value ->
    r (K, R, P), summing to 1 over the classes: w_c m^p / sum_c' w_c' m^p (by the value alone where no class moves the
    part)."""
    rel = rms / np.maximum(rms.max(0, keepdims=True), 1e-30)  # scale-free before the power
    score = weights[..., None] * rel ** power
    norm = score.sum(0, keepdims=True)
    fallback = np.broadcast_to((weights / weights.sum(0))[..., None], score.shape)
    return np.where(norm > 0, score / np.where(norm > 0, norm, 1.0), fallback)


def compose(base: np.ndarray, class_terms: np.ndarray, weights: np.ndarray, guidance: Guidance,
            routing: BodyRouting | None = None, mask: np.ndarray | None = None) -> np.ndarray:
    """One step's label composition: base x0(A, -) (B, T, D), class terms x0(A, e_c) (K, B, T, D), weights (K, B) the
    signed label values times s -> x0 (B, T, D) by guidance.composition (the module docstring). mask (B, T) bool: the
    frames the part magnitudes read (default all)."""
    d = class_terms - base
    w = weights.astype(np.float32)[..., None, None]
    if guidance.composition == "sum":
        return base + (w * d).sum(0)
    if routing is None:
        raise ValueError("composition 'parts' needs the model's body routing")
    positive = np.maximum(weights, 0).astype(np.float64)  # (K, B)
    out = base + (w * d).sum(0)  # the sum rule: kept by rows with one positive class or none
    rows = np.flatnonzero((positive > 0).sum(0) > 1)
    if len(rows) == 0:
        return out
    out[rows] = base[rows] + (np.minimum(w, 0)[:, rows] * d[:, rows]).sum(0)  # negations keep the sum rule
    k, _, t, dim = d.shape
    frames = np.ones((len(rows), t), bool) if mask is None else np.asarray(mask, bool)[rows]
    m = frames[None, :, :, None, None].astype(np.float64)  # (1, R, T, 1, 1)
    metres = (d[:, rows].astype(np.float64) * routing.scale).reshape(k, len(rows), t, dim // 3, 3)
    centre = metres[:, :, :, list(routing.centre)].mean(3, keepdims=True)  # (K, R, T, 1, 3): placement
    relative = metres - centre
    wp, total = positive[:, rows], positive[:, rows].sum(0)  # (K, R), (R,)
    count = np.maximum(m.sum((2, 3, 4)), 1.0)  # valid frames per row (1, R)

    parts = [centre] + [relative[:, :, :, list(g)] for g in routing.groups]  # placement, then each group
    rms = np.stack([np.sqrt((x ** 2 * m).sum((2, 3, 4)) / (count * x.shape[3])) for x in parts], -1)  # (K, R, P)
    r = part_responsibilities(rms, wp, guidance.routing_power)
    mixed = np.zeros(metres.shape[1:])  # (R, T, J, 3)
    mixed += ((total * r[..., 0])[..., None, None, None] * centre).sum(0)
    for p, group in enumerate(routing.groups, start=1):
        g = list(group)
        mixed[:, :, g] += ((total * r[..., p])[..., None, None, None] * relative[:, :, :, g]).sum(0)
    out[rows] += (mixed.reshape(len(rows), t, dim) / routing.scale).astype(np.float32)
    return out


def initial_noise(seed: int, frames: int, dim: int) -> np.ndarray:
    """The sampler's starting point for one sequence: a function of the seed and the shape only (float32)."""
    return np.random.default_rng(int(seed)).standard_normal((frames, dim)).astype(np.float32)


def sample(denoise, leaders: np.ndarray, mask: np.ndarray, labels: np.ndarray, noise: np.ndarray, guidance: Guidance,
           diffusion_steps: int, routing: BodyRouting | None = None) -> np.ndarray:
    """DDIM (eta 0) from `noise` (B, T, D) -> normalized followers x0 (B, T, D), numpy float32.

    `denoise(x_t, step, leader_on, label, label_on)` is the network on a batch of the same rows repeated per term:
    x_t (N, T, D), step int, leader_on (N,) bool, label (N, C) one-hot, label_on (N,) bool -> x0 (N, T, D); it reads
    `leaders` (normalized, B rows, repeated alike) and `mask` from its closure. labels (B, C) are signed weights
    (already times the scale). Each step evaluates, in one batch, the leader-only term, one term per class any row
    weighs, and (with leader_scale != 1) the unconditioned term; compose() combines them (`routing`: for "parts")."""
    b, t, d = noise.shape
    c = labels.shape[1]
    classes = np.flatnonzero(np.abs(labels).sum(0) > 0).tolist()  # classes some row asks about
    n_terms = 1 + len(classes) + (guidance.leader_scale != 1.0)
    one_hot = np.zeros((n_terms, b, c), np.float32)
    label_on = np.zeros((n_terms, b), bool)
    for k, cls in enumerate(classes, start=1):
        one_hot[k, :, cls] = 1.0
        label_on[k] = True
    leader_on = np.ones((n_terms, b), bool)
    if guidance.leader_scale != 1.0:
        leader_on[-1] = False
    one_hot, label_on, leader_on = one_hot.reshape(-1, c), label_on.reshape(-1), leader_on.reshape(-1)
    if guidance.composition == "parts" and routing is None:
        raise ValueError("composition 'parts' needs the model's body routing")
    weights = (labels[:, classes].T * guidance.label_scale).astype(np.float32)  # (K, B)

    alpha_bar = cosine_alpha_bar(diffusion_steps)
    steps = np.linspace(diffusion_steps - 1, 0, guidance.sample_steps).round().astype(int)
    m = mask[..., None].astype(np.float32)
    x = noise.astype(np.float32)
    for i, step in enumerate(steps):
        terms = denoise(np.tile(x, (n_terms, 1, 1)), int(step), leader_on, one_hot, label_on).reshape(n_terms, b, t, d)
        base = terms[0]
        x0 = base
        if classes:
            x0 = compose(base, terms[1:1 + len(classes)], weights, guidance, routing, mask)
        if guidance.leader_scale != 1.0:
            x0 = terms[-1] + guidance.leader_scale * (x0 - terms[-1])
        x0 = np.clip(x0, -guidance.clip, guidance.clip) * m
        if i + 1 == len(steps):
            return x0.astype(np.float32)
        a, a_next = alpha_bar[step], alpha_bar[steps[i + 1]]
        eps = (x - np.sqrt(a) * x0) / np.sqrt(1 - a)
        x = ((np.sqrt(a_next) * x0 + np.sqrt(1 - a_next) * eps) * m).astype(np.float32)
    raise AssertionError("unreachable: sample_steps >= 1")
