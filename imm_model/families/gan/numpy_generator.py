"""The paper's generator on one sequence with numpy alone (families/gan/generator.py's numbers, to 1e-5).

Why: the studio runs the generator on one sequence at a time, and `import torch` took 2.0-2.2 s of its 3.7 s start
here (python -X importtime); numpy was already loaded. Written by hand because the library that would fit, ONNX
Runtime, needs an export step (and the onnx package) for every checkpoint and 27 MB more to install. Training,
batches, GPUs and the paper's frame-by-frame decoder (attention_query="decoder") stay on torch.

Weights are the torch module's state dict as float32 numpy arrays, under the same names.
"""

from __future__ import annotations

import numpy as np

from imm_model.families.gan.config import ModelConfig
from imm_model.model.numpy_runtime import linear


def _gate_scale(hidden: int) -> np.ndarray:
    """sigmoid(x) = (1 + tanh(x / 2)) / 2: one tanh over all four gates per step, the sigmoid gates' inputs halved."""
    scale = np.full(4 * hidden, 0.5, np.float32)
    scale[2 * hidden : 3 * hidden] = 1.0
    return scale


def recurrence(w_hh: list[np.ndarray]) -> np.ndarray:
    """N LSTMs' W_hh (4H, H) -> (N, H, 4H), transposed and gate-scaled for lstm_runs (prepared once per model)."""
    w = np.stack(w_hh)
    return np.ascontiguousarray(w.transpose(0, 2, 1)) * _gate_scale(w.shape[2])


def lstm_runs(gate_inputs: np.ndarray, w: np.ndarray) -> np.ndarray:
    """N independent one-layer LSTMs stepped together: gate_inputs (N, T, 4H) = W_ih x_t + b_ih + b_hh for each,
    w from `recurrence` -> hidden states (N, T, H). Gates in torch's order: input, forget, cell, output."""
    n, steps, four_h = gate_inputs.shape
    hidden = four_h // 4
    inputs = gate_inputs * _gate_scale(hidden)
    h = np.zeros((n, 1, hidden), np.float32)
    c = np.zeros((n, 1, hidden), np.float32)
    out = np.empty((n, steps, hidden), np.float32)
    for t in range(steps):
        gates = np.tanh(inputs[:, t : t + 1] + h @ w)  # (N, 1, 4H)
        ifo = 0.5 + 0.5 * gates
        c = ifo[..., hidden : 2 * hidden] * c + ifo[..., :hidden] * gates[..., 2 * hidden : 3 * hidden]
        h = ifo[..., 3 * hidden :] * np.tanh(c)
        out[:, t] = h[:, 0]
    return out


DIRECTIONS = ("fwd", "bwd")


def bilstm_gate_inputs(x: np.ndarray, weights: dict[str, np.ndarray], prefix: str) -> list[np.ndarray]:
    """x (T, D) through a layers.BiLSTM's two directions -> [forward, time-reversed backward] gate inputs (T, 4H)."""
    runs = []
    for direction, frames in zip(DIRECTIONS, (x, x[::-1]), strict=True):
        p = f"{prefix}.{direction}."
        runs.append(frames @ weights[p + "weight_ih_l0"].T + weights[p + "bias_ih_l0"] + weights[p + "bias_hh_l0"])
    return runs


class NumpyGenerator:
    """model.Generator for one unpadded sequence: leader (T, 3J) canonical metres + label (C,) -> follower (T, 3J)."""

    def __init__(self, weights: dict[str, np.ndarray], cfg: ModelConfig):
        if not self.supports(cfg):
            raise ValueError("the frame-by-frame attentive decoder (attention_query='decoder') runs on torch only")
        self.w = {k: np.asarray(v, np.float32) for k, v in weights.items()}
        self.cfg = cfg
        self.part_cols = [np.array([3 * j + c for j in joints for c in range(3)]) for joints in cfg.body_parts]
        hh = [f"{d}.weight_hh_l0" for d in DIRECTIONS]
        self.encoder_w = recurrence([self.w[f"encoders.{k}.{n}"] for k in range(cfg.num_streams) for n in hh])
        self.decoder_w = recurrence([self.w[f"decoder.{n}"] for n in hh])

    @staticmethod
    def supports(cfg: ModelConfig) -> bool:
        return cfg.attention_query == "encoder"

    @staticmethod
    def expected_shapes(cfg: ModelConfig) -> dict[str, tuple[int, ...]]:
        """The shapes of model.Generator(cfg)'s state dict (attention_query="encoder"), to check a checkpoint with."""
        d, E, H, A, Hd = cfg.pose_dim, cfg.stream_embed, cfg.encoder_hidden, cfg.attention_dim, cfg.decoder_hidden
        shapes = {f"{name}_{stat}": (d,) for name in ("leader", "follower") for stat in ("mean", "std")}
        inputs = [3 * len(p) for p in cfg.body_parts] + [d + cfg.num_classes if cfg.label_input else d]
        for k, n in enumerate(inputs):
            if cfg.stream_fc:
                shapes |= {f"embed.{k}.weight": (E, n), f"embed.{k}.bias": (E,)}
            shapes |= _lstm_shapes(f"encoders.{k}", E if cfg.stream_fc else n, H)
        latent = cfg.latent_dim
        shapes |= {"attention.query.weight": (A, latent), "attention.key.weight": (A, latent), "attention.key.bias": (A,),
                   "attention.v.weight": (1, A), "out.weight": (d, 2 * Hd), "out.bias": (d,)}
        return shapes | _lstm_shapes("decoder", cfg.decoder_input_dim, Hd)

    def encode(self, leader: np.ndarray, label: np.ndarray) -> np.ndarray:
        """-> the six streams' Bi-LSTM encodings (T, latent), [stream 0 forward, stream 0 backward, stream 1 ...]."""
        w, cfg = self.w, self.cfg
        x = (np.asarray(leader, np.float32) - w["leader_mean"]) / w["leader_std"]
        label = np.asarray(label, np.float32).reshape(-1)
        streams = [x[:, cols] for cols in self.part_cols]
        streams.append(np.concatenate([x, np.broadcast_to(label, (len(x), len(label)))], 1) if cfg.label_input else x)
        runs = [r for k, s in enumerate(streams)
                for r in bilstm_gate_inputs(linear(s, w, f"embed.{k}") if cfg.stream_fc else s, w, f"encoders.{k}")]
        states = lstm_runs(np.stack(runs), self.encoder_w)  # (12, T, H): per stream, forward then backward
        return np.concatenate([s if k % 2 == 0 else s[::-1] for k, s in enumerate(states)], axis=1)

    def attention(self, h: np.ndarray) -> np.ndarray:
        """layers.AdditiveAttention over all frames: (T, latent) -> contexts (T, latent)."""
        q, k = linear(h, self.w, "attention.query"), linear(h, self.w, "attention.key")
        scores = np.tanh(q[:, None, :] + k[None, :, :]) @ self.w["attention.v.weight"][0]  # (T, T)
        scores = np.exp(scores - scores.max(1, keepdims=True))
        return (scores / scores.sum(1, keepdims=True)) @ h

    def __call__(self, leader: np.ndarray, label: np.ndarray) -> np.ndarray:
        w, mode = self.w, self.cfg.decoder_input
        h = self.encode(leader, label)
        context = self.attention(h)
        dec_in = np.concatenate([h, context], 1) if mode == "concat" else h + context if mode == "sum" else context
        fwd, bwd = lstm_runs(np.stack(bilstm_gate_inputs(dec_in, w, "decoder")), self.decoder_w)
        dec = np.concatenate([fwd, bwd[::-1]], axis=1)
        return linear(dec, w, "out") * w["follower_std"] + w["follower_mean"]


def _lstm_shapes(prefix: str, inputs: int, hidden: int) -> dict[str, tuple[int, ...]]:
    """A layers.BiLSTM's parameters."""
    out = {}
    for direction in DIRECTIONS:
        p = f"{prefix}.{direction}."
        out |= {p + "weight_ih_l0": (4 * hidden, inputs), p + "weight_hh_l0": (4 * hidden, hidden),
                p + "bias_ih_l0": (4 * hidden,), p + "bias_hh_l0": (4 * hidden,)}
    return out
