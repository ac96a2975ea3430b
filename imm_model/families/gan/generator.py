"""The conditional hierarchical generator: leader motion + multi-hot label -> follower motion.

Six streams (five body parts, and the whole body with the label appended per frame), each a
fully connected layer and a one-layer Bi-LSTM; the per-frame encodings are concatenated, attended
over, decoded by a Bi-LSTM and mapped back to a pose at every frame.
Poses are standardized with the training set's per-coordinate mean/std (buffers, saved with it).
"""

from __future__ import annotations

import torch
import torch.nn as nn

from imm_model.families.gan.config import ModelConfig
from imm_model.families.gan.layers import AdditiveAttention, AttentiveDecoder, BiLSTM, Dropout, reverse_index


class Generator(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        d = cfg.pose_dim
        for k, joints in enumerate(cfg.body_parts):
            cols = torch.tensor([3 * j + c for j in joints for c in range(3)], dtype=torch.int64)
            self.register_buffer(f"part_cols_{k}", cols, persistent=False)
        self.register_buffer("leader_mean", torch.zeros(d))
        self.register_buffer("leader_std", torch.ones(d))
        self.register_buffer("follower_mean", torch.zeros(d))
        self.register_buffer("follower_std", torch.ones(d))
        in_sizes = [3 * len(p) for p in cfg.body_parts] + [d + cfg.num_classes if cfg.label_input else d]
        if cfg.stream_fc:
            self.embed = nn.ModuleList(nn.Linear(n, cfg.stream_embed) for n in in_sizes)
        else:
            self.embed = nn.ModuleList(nn.Identity() for _ in in_sizes)
        self.encoders = nn.ModuleList(BiLSTM(cfg.stream_embed if cfg.stream_fc else n, cfg.encoder_hidden) for n in in_sizes)
        if cfg.attention_query == "decoder":
            self.attentive = AttentiveDecoder(cfg.latent_dim, cfg.decoder_input_dim, cfg.attention_dim, cfg.decoder_hidden)
        else:
            self.attention = AdditiveAttention(cfg.latent_dim, cfg.attention_dim)
            self.decoder = BiLSTM(cfg.decoder_input_dim, cfg.decoder_hidden)
        self.drop = Dropout(cfg.dropout, per_sequence=cfg.dropout_per_sequence)
        self.out = nn.Linear(2 * cfg.decoder_hidden, d)

    def set_normalization(self, leader_mean, leader_std, follower_mean, follower_std) -> None:
        for name, v in zip(("leader_mean", "leader_std", "follower_mean", "follower_std"),
                           (leader_mean, leader_std, follower_mean, follower_std), strict=True):
            getattr(self, name).copy_(torch.as_tensor(v, dtype=torch.float32))

    def encode(self, leader: torch.Tensor, labels: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """leader (B, T, 3J) canonical metres, labels (B, C), lengths (B,) -> encodings (B, T, 6 * 2H)."""
        B, T, _ = leader.shape
        x = (leader - self.leader_mean) / self.leader_std
        rev = reverse_index(lengths, T)
        streams = [x.index_select(2, getattr(self, f"part_cols_{k}")) for k in range(len(self.cfg.body_parts))]
        streams.append(torch.cat([x, labels[:, None, :].expand(B, T, -1)], dim=-1) if self.cfg.label_input else x)
        return torch.cat([enc(emb(s), rev) for s, emb, enc in zip(streams, self.embed, self.encoders, strict=True)], dim=-1)

    def decoder_input(self, h: torch.Tensor, context: torch.Tensor) -> torch.Tensor:
        """Encodings h and attention contexts (B, T, latent) -> the decoder's input (see ModelConfig)."""
        mode = self.cfg.decoder_input
        if mode == "concat":
            return torch.cat([h, context], dim=-1)
        if mode == "sum":
            return h + context
        return context

    def forward(self, leader: torch.Tensor, labels: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """-> follower (B, T, 3J) canonical metres (padded frames hold garbage: mask them)."""
        T = leader.shape[1]
        mask = torch.arange(T, device=leader.device)[None] < lengths[:, None]
        h = self.drop(self.encode(leader, labels, lengths))
        rev = reverse_index(lengths, T)
        if self.cfg.attention_query == "decoder":
            dec = self.drop(self.attentive(h, mask, rev, self.decoder_input))
        else:
            dec = self.drop(self.decoder(self.decoder_input(h, self.attention(h, mask)), rev))
        return self.out(dec) * self.follower_std + self.follower_mean
