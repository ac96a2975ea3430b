"""The reaction diffusion model's denoiser (denoiser.py) in numpy, for sampling on a CPU.

Why by hand: the studio never imports torch (families/gan/numpy_generator.py says why), and a sampler step is ~60 small
operations, where numpy's per-call cost is a fraction of torch's. The numbers are the torch module's
(tests/test_diffusion.py compares them); training and GPUs stay on torch.

Weights are the torch module's state dict as float32 numpy arrays, under the same names.

A sampler calls the network once per step with the same leaders and labels, so `conditioned` computes their share
once (the leader's part of the input projection, the label's part of every block's modulation) and each step adds
only what depends on x_t and the step; the step embedding's part is cached per step value.
"""

from __future__ import annotations

import math

import numpy as np

from imm_model.families.diffusion.sampler import DiffusionConfig


def sinusoid(positions: np.ndarray, width: int) -> np.ndarray:
    half = width // 2
    freq = np.exp(-math.log(10_000.0) * np.arange(half, dtype=np.float32) / half).astype(np.float32)
    angle = positions.astype(np.float32)[..., None] * freq
    return np.concatenate([np.sin(angle), np.cos(angle)], -1)


def _layer_norm(x: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    mean = x.mean(-1, keepdims=True)
    centred = x - mean
    return centred / np.sqrt((centred * centred).mean(-1, keepdims=True) + eps)


def _modulated_norm(x: np.ndarray, scale: np.ndarray, shift: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    """LayerNorm(x) * scale + shift, x (N, T, W), scale and shift (N, 1, W), in place on one new array. The mean is a
    product with a 1/W column and the variance an einsum: both faster than numpy's reductions along short rows."""
    width = x.shape[-1]
    z = x - x @ np.full((width, 1), 1.0 / width, np.float32)
    var = np.einsum("...i,...i->...", z, z)[..., None]
    var *= np.float32(1.0 / width)
    var += np.float32(eps)
    z /= np.sqrt(var, out=var)
    z *= scale
    z += shift
    return z


def _gelu2(x: np.ndarray) -> np.ndarray:
    """2 * GELU(x), tanh form (the torch module's nn.GELU(approximate="tanh")), in place on one new array; the 1/2 is
    in the next layer's weights (exact: a power of two)."""
    c = np.float32(math.sqrt(2.0 / math.pi))
    u = np.square(x)
    u *= c * np.float32(0.044715)
    u += c
    u *= x
    np.tanh(u, out=u)
    u += 1.0
    u *= x
    return u


def _silu(x: np.ndarray) -> np.ndarray:
    return x / (1.0 + np.exp(-x))


def _attention(q: np.ndarray, k: np.ndarray, v: np.ndarray, pad: np.ndarray | None) -> np.ndarray:
    """softmax(q k^T) v per head: q, k, v (N, heads, tokens, dh), q already scaled by 1/sqrt(dh), pad (N, 1, tokens, 1)
    additive over keys or None -> (N, heads, tokens, dh). The scores are laid out keys x queries, so that the softmax's
    sum over keys runs across rows (vectorized) rather than along each short row; the normalization divides the
    (tokens, dh) result rather than the (tokens, tokens) weights."""
    s = k @ q.swapaxes(-1, -2)  # (N, heads, keys, queries)
    # exp needs no shift by the max where every score is within +-60: e^60 times the values, summed over keys, stays
    # far from float32's overflow and e^-60 far from zero (the bundled model's scores stay within +-40); the max over
    # keys costs more than the rest of the softmax
    shift = max(s.max(), -s.min()) > 60
    if pad is not None:
        s += pad
    if shift:
        s -= s.max(-2, keepdims=True)
    np.exp(s, out=s)
    att = s.swapaxes(-1, -2) @ v
    att /= s.sum(-2)[..., None]
    return att


class NumpyDenoiser:
    """ReactionDenoiser.forward on numpy arrays: x_t (B, T, D) normalized, step int, leader (B, T, D) normalized,
    leader_on (B,), label (B, L), label_on (B,), mask (B, T) -> x0 (B, T, D) float32."""

    def __init__(self, weights: dict[str, np.ndarray], cfg: DiffusionConfig):
        self.cfg = cfg
        self.w = {k: np.asarray(v, np.float32) for k, v in weights.items()}
        # (in, out) layouts once, so every call is a plain x @ W + b
        self.linear = {k[: -len(".weight")]: (np.ascontiguousarray(v.T), self.w[k[: -len(".weight")] + ".bias"])
                       for k, v in self.w.items() if k.endswith(".weight") and k[: -len(".weight")] + ".bias" in self.w}
        width, d, k = cfg.width, cfg.pose_dim, cfg.frames_per_token
        # the input's rows per frame are [x_t (D), leader (D), present (1)]: x_t's rows apart from the leader's
        rows = self.linear["input"][0].reshape(k, 2 * d + 1, width)
        self.input_x = np.ascontiguousarray(rows[:, :d].reshape(k * d, width))
        self.input_leader = np.ascontiguousarray(rows[:, d:].reshape(k * (d + 1), width))
        # every block's modulation in one product: (W, layers * 6 * W); 1 added to the scales' biases (1 + scale)
        self.modulation = np.concatenate([self.linear[f"blocks.{i}.modulation"][0] for i in range(cfg.layers)], 1)
        bias = np.stack([self.linear[f"blocks.{i}.modulation"][1].reshape(6, width) for i in range(cfg.layers)])
        bias[:, [1, 4]] += 1.0
        self.modulation_bias = bias.reshape(-1)
        # per block: qkv with the queries' columns times 1/sqrt(dh) (the attention's scale), and mlp.2's weights
        # halved for _gelu2
        q_scale = np.ones(3 * width, np.float32)
        q_scale[:width] = 1 / math.sqrt(width // cfg.heads)
        self.blocks = []
        for i in range(cfg.layers):
            (qkv, qkv_b), proj, mlp0, (mlp2, mlp2_b) = (self.linear[f"blocks.{i}.{n}"] for n in ("qkv", "proj", "mlp.0", "mlp.2"))
            self.blocks.append(((qkv * q_scale, qkv_b * q_scale), proj, mlp0, (mlp2 * np.float32(0.5), mlp2_b)))
        self._step_modulation: dict[int, np.ndarray] = {}

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
        w, d, k, c = cfg.width, cfg.pose_dim, cfg.frames_per_token, cfg.label_width
        shapes: dict[str, tuple[int, ...]] = {
            "input.weight": (w, k * (2 * d + 1)), "input.bias": (w,), "absent_leader": (d,),
            "step_mlp.0.weight": (w, w), "step_mlp.0.bias": (w,), "step_mlp.2.weight": (w, w), "step_mlp.2.bias": (w,),
            "label.weight": (w, c), "label.bias": (w,), "absent_label": (w,),
            "out_norm.weight": (w,), "out_norm.bias": (w,), "output.weight": (k * d, w), "output.bias": (k * d,),
            **{f"{who}_{stat}": (d,) for who in ("follower", "leader") for stat in ("mean", "std")},
        }
        if cfg.leader_noise:  # the leader's noise level is embedded by an MLP shaped like the step's
            shapes |= {k.replace("step_mlp", "leader_noise_mlp"): v for k, v in shapes.items() if k.startswith("step_mlp.")}
        ff = cfg.ff_mult * w
        for i in range(cfg.layers):
            for name, (out, inp) in (("qkv", (3 * w, w)), ("proj", (w, w)), ("mlp.0", (ff, w)), ("mlp.2", (w, ff)),
                                     ("modulation", (6 * w, w))):
                shapes[f"blocks.{i}.{name}.weight"], shapes[f"blocks.{i}.{name}.bias"] = (out, inp), (out,)
        return shapes

    def step_modulation(self, step: int) -> np.ndarray:
        """(layers, 6, 1, 1, W): the step embedding's share of every block's modulation, without the bias. A sampler
        meets the same few steps on every call, so each is computed once."""
        if step not in self._step_modulation:
            cond = self._lin("step_mlp.2", _silu(self._lin("step_mlp.0", sinusoid(np.array([step]), self.cfg.width))))
            self._step_modulation[step] = (cond @ self.modulation).reshape(self.cfg.layers, 6, 1, 1, -1)
        return self._step_modulation[step]

    def conditioned(self, leader: np.ndarray, leader_on: np.ndarray, label: np.ndarray, label_on: np.ndarray,
                    mask: np.ndarray, leader_level: np.ndarray | None = None) -> ConditionedDenoiser:
        """The network for these rows' leaders, labels, mask and leader noise steps (B,): a function of (x_t, step)
        alone."""
        return ConditionedDenoiser(self, leader, leader_on, label, label_on, mask, leader_level)

    def __call__(self, x_t: np.ndarray, step: int, leader: np.ndarray, leader_on: np.ndarray, label: np.ndarray,
                 label_on: np.ndarray, mask: np.ndarray, return_hidden: bool = False,
                 leader_level: np.ndarray | None = None):
        return self.conditioned(leader, leader_on, label, label_on, mask, leader_level)(x_t, step, return_hidden)


class ConditionedDenoiser:
    """NumpyDenoiser with its leaders, labels and mask fixed: (x_t (B, T, D), step) -> x0 (B, T, D) float32."""

    def __init__(self, net: NumpyDenoiser, leader: np.ndarray, leader_on: np.ndarray, label: np.ndarray,
                 label_on: np.ndarray, mask: np.ndarray, leader_level: np.ndarray | None = None):
        cfg, w = net.cfg, net.w
        b, t, _ = leader.shape
        k = cfg.frames_per_token
        self.net = net
        self.pad_frames = -t % k
        self.tokens = (t + self.pad_frames) // k
        self.frame_mask = mask[..., None].astype(np.float32)  # (B, T, 1)
        leader = np.where(leader_on[:, None, None], leader, w["absent_leader"])
        present = np.broadcast_to(leader_on[:, None, None].astype(np.float32), (b, t, 1))
        frames = np.concatenate([leader, present], -1) * self.frame_mask
        if self.pad_frames:
            frames = np.pad(frames, ((0, 0), (0, self.pad_frames), (0, 0)))
            mask = np.pad(mask, ((0, 0), (0, self.pad_frames)))
        # (B, tokens, W): the input projection's leader share, its bias and the token positions
        self.leader_input = (frames.reshape(b, self.tokens, -1) @ net.input_leader + net.linear["input"][1]
                             + sinusoid(np.arange(self.tokens) * k, cfg.width))
        cond = np.where(label_on[:, None], net._lin("label", label), w["absent_label"])  # (B, W)
        if cfg.leader_noise:
            level = np.zeros(b, np.float32) if leader_level is None else np.asarray(leader_level, np.float32)
            cond = cond + net._lin("leader_noise_mlp.2", _silu(net._lin("leader_noise_mlp.0", sinusoid(level, cfg.width))))
        # (layers, 6, B, 1, W): the label's share of every block's modulation, with the biases
        self.label_modulation = (cond @ net.modulation + net.modulation_bias).reshape(b, cfg.layers, 6, 1, -1).transpose(1, 2, 0, 3, 4)
        self.token_mask = mask.reshape(b, self.tokens, k).any(-1)
        self.pad = None  # (B, 1, tokens, 1) -inf at padded keys; None when there are none
        if not self.token_mask.all():
            self.pad = np.where(self.token_mask, 0.0, -np.inf).astype(np.float32)[:, None, :, None]

    def __call__(self, x_t: np.ndarray, step: int, return_hidden: bool = False):
        net, cfg = self.net, self.net.cfg
        b, t, d = x_t.shape
        tokens, width, heads = self.tokens, cfg.width, cfg.heads
        x = x_t * self.frame_mask
        if self.pad_frames:
            x = np.pad(x, ((0, 0), (0, self.pad_frames), (0, 0)))
        h = (x.reshape(b * tokens, -1) @ net.input_x).reshape(b, tokens, width)
        h += self.leader_input
        modulation = self.label_modulation + net.step_modulation(step)  # (layers, 6, B, 1, W)
        for (qkv, proj, mlp0, mlp2), (shift1, scale1, gate1, shift2, scale2, gate2) in zip(net.blocks, modulation, strict=True):
            z = _modulated_norm(h, scale1, shift1)
            q, k, v = _linear(z, qkv).reshape(b, tokens, 3, heads, -1).transpose(2, 0, 3, 1, 4)  # (B, heads, tokens, dh)
            att = _attention(q, k, v, self.pad).transpose(0, 2, 1, 3).reshape(b, tokens, width)
            y = _linear(att, proj)
            y *= gate1
            h += y
            y = _linear(_gelu2(_linear(_modulated_norm(h, scale2, shift2), mlp0)), mlp2)
            y *= gate2
            h += y
        h = _layer_norm(h) * net.w["out_norm.weight"] + net.w["out_norm.bias"]
        if return_hidden:
            return h, self.token_mask
        return _linear(h, net.linear["output"]).reshape(b, tokens * cfg.frames_per_token, d)[:, :t]


def _linear(x: np.ndarray, layer: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """x (..., in) @ W (in, out) + b as one 2-d product (numpy runs a 3-d one as a loop of smaller ones)."""
    w, b = layer
    y = x.reshape(-1, x.shape[-1]) @ w
    y += b
    return y.reshape(*x.shape[:-1], -1)
