"""Reaction classifiers trained on real motion only: the judges of every classifier-based metric.

Two inputs, as the field does (Action2Motion, ACTOR, ReGenNet use a recurrent action classifier and its
penultimate layer for FID):
- "interaction": leader and follower together (A + B, canonical frame): FID features, recognition accuracy;
- "follower": the follower alone (B): label adherence. It never sees the leader, so it can only tell
  which reaction B performs, not which one the leader invites.

Two architectures, so that a classifier used as a training critic is never also the judge:
- "gru": two bidirectional GRU layers over per-frame positions and velocities, mean-pooled;
- "conv": two temporal convolutions (kernel 5), mean-pooled.
Both end in a `features`-wide ReLU layer (the FID embedding) and a linear class head. Per-frame inputs are
standardized with the training set's statistics (buffers, saved with the weights). Training augments with
a small yaw, a body-size scale and positional noise; benchmarks/classifier_accuracy.py measures the accuracies that chose them. Used by
the evaluation as judges and, optionally, by the GAN's training as a frozen critic (training/label_critic.py).
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn as nn

from imm_model.model.body_parts import body_part_view
from imm_model.model.classifier_config import ClassifierConfig

VERSION = 2  # part of every cache key: bump when the architecture or training code changes its numbers


class MotionClassifier(nn.Module):
    def __init__(self, cfg: ClassifierConfig, pose_dim: int, num_classes: int):
        super().__init__()
        self.cfg, self.pose_dim, self.num_classes = cfg, pose_dim, num_classes
        d = 2 * pose_dim  # positions and velocities
        self.register_buffer("mean", torch.zeros(d))
        self.register_buffer("std", torch.ones(d))
        if cfg.arch == "gru":
            self.body = nn.GRU(d, cfg.hidden, num_layers=2, batch_first=True, bidirectional=True, dropout=0.2)
            width = 2 * cfg.hidden
        else:
            self.body = nn.ModuleList([nn.Conv1d(d, cfg.hidden, 5, padding=2), nn.Conv1d(cfg.hidden, cfg.hidden, 5, padding=2)])
            width = cfg.hidden
        self.embed = nn.Sequential(nn.Dropout(cfg.dropout), nn.Linear(width, cfg.features), nn.ReLU())
        self.head = nn.Linear(cfg.features, num_classes)

    @staticmethod
    def frame_inputs(x: torch.Tensor) -> torch.Tensor:
        """(B, T, D) positions -> (B, T, 2D) positions and per-frame velocities (0 at the first frame)."""
        return torch.cat([x, torch.diff(x, dim=1, prepend=x[:, :1])], dim=-1)

    def positions(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, D) canonical metres -> the positions the network reads: with cfg.start_centred, relative to the
        horizontal centroid of the body's joints on the first frame (Y is up, so heights are kept)."""
        if not self.cfg.start_centred:
            return x
        p = x.unflatten(-1, (-1, 3))
        origin = p[:, :1].mean(2, keepdim=True) * torch.tensor([1.0, 0.0, 1.0], device=x.device)
        return (p - origin).flatten(-2)

    def features(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """x (B, T, D) canonical metres (padded), lengths (B,) -> (B, features): the FID embedding."""
        z = (self.frame_inputs(self.positions(x)) - self.mean) / self.std
        mask = (torch.arange(x.shape[1], device=x.device)[None] < lengths[:, None]).float()[..., None]
        if self.cfg.arch == "gru":  # packed, so neither direction reads padding: a batch never changes a result
            packed = nn.utils.rnn.pack_padded_sequence(z, lengths.cpu(), batch_first=True, enforce_sorted=False)
            h, _ = nn.utils.rnn.pad_packed_sequence(self.body(packed)[0], batch_first=True, total_length=x.shape[1])
        else:  # padding re-zeroed after every layer, so the last frames read the same zeros as a lone sequence
            h = z * mask
            for conv in self.body:
                h = torch.relu(conv(h.transpose(1, 2))).transpose(1, 2) * mask
        return self.embed((h * mask).sum(1) / mask.sum(1))

    def forward(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x, lengths))


# ---- inputs -----------------------------------------------------------------------------------
def motion_inputs(leaders: list[np.ndarray], followers: list[np.ndarray], inputs: str) -> list[np.ndarray]:
    """Per-sequence classifier input (T, D): [A, B] flattened for "interaction", B alone for "follower", a body part
    of B (body_part_view) for "upper" and "lower"."""
    if inputs == "follower":
        return [np.asarray(b, np.float32).reshape(len(b), -1) for b in followers]
    if inputs in ("upper", "lower"):
        return [body_part_view(b, inputs).reshape(len(b), -1) for b in followers]
    return [np.concatenate([np.asarray(a, np.float32).reshape(len(a), -1), np.asarray(b, np.float32).reshape(len(b), -1)], -1)
            for a, b in zip(leaders, followers, strict=True)]


def _pad(sequences: list[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    lengths = torch.tensor([len(s) for s in sequences])
    x = torch.zeros(len(sequences), int(lengths.max()), sequences[0].shape[-1])
    for i, s in enumerate(sequences):
        x[i, : len(s)] = torch.from_numpy(np.asarray(s, np.float32))
    return x, lengths


def augment(x: torch.Tensor, cfg: ClassifierConfig, gen: torch.Generator) -> torch.Tensor:
    """Yaw about the vertical (Y) axis, scale and noise; every character in a sequence alike. Differentiable in x;
    the random draws come from the CPU generator `gen` and move to x's device."""
    B = x.shape[0]
    p = x.unflatten(-1, (-1, 3))
    ang = ((torch.rand(B, generator=gen) * 2 - 1) * math.radians(cfg.rotate_deg)).to(x.device)
    c, s = torch.cos(ang)[:, None, None], torch.sin(ang)[:, None, None]
    p = torch.stack([c * p[..., 0] + s * p[..., 2], p[..., 1], -s * p[..., 0] + c * p[..., 2]], dim=-1)
    p = p * (1 + (torch.rand(B, 1, 1, 1, generator=gen) * 2 - 1) * cfg.scale_jitter).to(x.device)
    return p.flatten(-2) + torch.randn(x.shape, generator=gen).to(x.device) * cfg.noise_m


# ---- training and use -------------------------------------------------------------------------
def train_classifier(cfg: ClassifierConfig, sequences: list[np.ndarray], labels: np.ndarray, num_classes: int,
                     progress: bool = False, desc: str = "classifier") -> MotionClassifier:
    """Train on real sequences (T_i, D) with class labels; deterministic for a given cfg.seed."""
    from tqdm import tqdm

    torch.manual_seed(cfg.seed)
    gen = torch.Generator().manual_seed(cfg.seed)
    x, lengths = _pad(sequences)
    y = torch.as_tensor(np.asarray(labels), dtype=torch.int64)
    model = MotionClassifier(cfg, x.shape[-1], num_classes)
    frames = MotionClassifier.frame_inputs(model.positions(x))[torch.arange(x.shape[1])[None] < lengths[:, None]]
    model.mean.copy_(frames.mean(0))
    model.std.copy_(frames.std(0).clamp(min=1e-2))
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    model.train()
    for _ in tqdm(range(cfg.epochs), desc=desc, disable=not progress, leave=False, dynamic_ncols=True):
        order = torch.randperm(len(y), generator=gen)
        for k in range(0, len(order), cfg.batch_size):
            idx = order[k:k + cfg.batch_size]
            t = int(lengths[idx].max())
            inputs, target = x[idx, :t], y[idx]
            if cfg.mixup:
                inputs, target = _mixup(inputs, lengths[idx], nn.functional.one_hot(target, num_classes).float(), gen)
            logits = model(augment(inputs, cfg, gen), lengths[idx])
            loss = nn.functional.cross_entropy(logits, target, label_smoothing=cfg.label_smoothing)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
    return model.eval()


def _mixup(x: torch.Tensor, lengths: torch.Tensor, target: torch.Tensor, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Blend each sequence of a padded batch (B, T, D) with a random partner of the batch, resampled in time to its
    length, at a weight U(0, 1) per sequence; targets (B, C) alike."""
    partner = torch.randperm(len(x), generator=gen)
    lam = torch.rand(len(x), generator=gen)
    mixed = x.clone()
    for i, j in enumerate(partner.tolist()):
        n, m = int(lengths[i]), int(lengths[j])
        resampled = nn.functional.interpolate(x[j, :m].T[None], size=n, mode="linear", align_corners=True)[0].T
        mixed[i, :n] = lam[i] * x[i, :n] + (1 - lam[i]) * resampled
    return mixed, lam[:, None] * target + (1 - lam[:, None]) * target[partner]


@torch.inference_mode()
def classify(model: MotionClassifier, sequences: list[np.ndarray], batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """-> (class probabilities (N, C), penultimate features (N, features)) of sequences (T_i, D)."""
    probs, feats = [], []
    for k in range(0, len(sequences), batch):
        x, lengths = _pad(sequences[k:k + batch])
        f = model.features(x, lengths)
        feats.append(f.numpy())
        probs.append(torch.softmax(model.head(f), -1).numpy())
    return np.concatenate(probs).astype(np.float64), np.concatenate(feats).astype(np.float64)
