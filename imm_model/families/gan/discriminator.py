"""The discriminator: two Bi-LSTM layers over the follower's motion only, N classes + 1 "fake".

Per-frame features are mean-pooled over valid frames, then one (spectrally normalized, optional)
linear layer gives N + 1 logits; index N is "fake".
"""

from __future__ import annotations

import torch
import torch.nn as nn

from imm_model.families.gan.config import ModelConfig
from imm_model.families.gan.layers import BiLSTM, reverse_index


class Discriminator(nn.Module):
    def __init__(self, cfg: ModelConfig, spectral_norm: bool = True):
        super().__init__()
        self.cfg = cfg
        h = cfg.disc_hidden
        self.register_buffer("follower_mean", torch.zeros(cfg.pose_dim))
        self.register_buffer("follower_std", torch.ones(cfg.pose_dim))
        self.lstm1 = BiLSTM(cfg.pose_dim, h)
        self.lstm2 = BiLSTM(2 * h, h)
        head = nn.Linear(2 * h, cfg.num_classes + 1)
        self.head = nn.utils.parametrizations.spectral_norm(head) if spectral_norm else head

    def forward(self, follower: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """follower (B, T, 3J) canonical metres -> logits (B, C + 1)."""
        T = follower.shape[1]
        mask = (torch.arange(T, device=follower.device)[None] < lengths[:, None]).float()
        rev = reverse_index(lengths, T)
        x = (follower - self.follower_mean) / self.follower_std
        h = self.lstm2(self.lstm1(x, rev), rev)
        pooled = (h * mask[:, :, None]).sum(1) / lengths[:, None].float()
        return self.head(pooled)
