"""An inference-only, mathematically identical rearrangement of `Generator` for unpadded input.

Training needs padding-exact Bi-LSTMs (two `nn.LSTM` calls per layer, one per direction) and six
separate encoders. A single unpadded sequence needs neither: the six stream embeddings become one
block-diagonal linear layer, the six encoder Bi-LSTMs one bidirectional `nn.LSTM` with
block-diagonal gate weights (zeros between streams, so streams stay independent), and the decoder
one bidirectional `nn.LSTM`. The embedding (linear, no activation) and the input standardization are
folded into the encoder's input weights, so its input projection reads the 3J + C raw numbers.
"""

from __future__ import annotations

import torch
import torch.nn as nn

from imm_model.model.generator import Generator


class FastGenerator(nn.Module):
    def __init__(self, g: Generator):
        super().__init__()
        cfg = g.cfg
        S, E, H, d, C = cfg.num_streams, cfg.stream_embed, cfg.encoder_hidden, cfg.pose_dim, cfg.num_classes
        self.g = g  # attention, output layer and output scaling are shared
        with torch.no_grad():
            embed_w = torch.zeros(S * E, d + C)  # the six stream embeddings as one block-sparse layer
            embed_b = torch.cat([g.embed[k].bias for k in range(S)])
            for k in range(S):
                # a label-free generator's whole-body stream reads the pose only: zero weights on the label
                cols = getattr(g, f"part_cols_{k}") if k < S - 1 else torch.arange(d + C if cfg.label_input else d)
                embed_w[k * E:(k + 1) * E, cols] = g.embed[k].weight
            # standardization x' = (x - mean) / std folded in: W x' + b = (W / std) x + (b - W mean / std)
            embed_b = embed_b - embed_w @ torch.cat([g.leader_mean / g.leader_std, torch.zeros(C)])
            embed_w = embed_w * torch.cat([1 / g.leader_std, torch.ones(C)])
            self.encoder = nn.LSTM(d + C, S * H, batch_first=True, bidirectional=True)
            for suffix, direction in (("", "fwd"), ("_reverse", "bwd")):
                w_ih, w_hh = torch.zeros(4 * S * H, S * E), torch.zeros(4 * S * H, S * H)
                b_ih, b_hh = torch.zeros(4 * S * H), torch.zeros(4 * S * H)
                for k in range(S):
                    src = getattr(g.encoders[k], direction)
                    for gate in range(4):
                        dst = slice(gate * S * H + k * H, gate * S * H + (k + 1) * H)
                        own = slice(gate * H, (gate + 1) * H)
                        w_ih[dst, k * E:(k + 1) * E] = src.weight_ih_l0[own]
                        w_hh[dst, k * H:(k + 1) * H] = src.weight_hh_l0[own]
                        b_ih[dst] = src.bias_ih_l0[own]
                        b_hh[dst] = src.bias_hh_l0[own]
                # the embedding is linear, so W_ih (W_e u + b_e) + b_ih = (W_ih W_e) u + (W_ih b_e + b_ih)
                getattr(self.encoder, "weight_ih_l0" + suffix).copy_(w_ih @ embed_w)
                getattr(self.encoder, "bias_ih_l0" + suffix).copy_(b_ih + w_ih @ embed_b)
                getattr(self.encoder, "weight_hh_l0" + suffix).copy_(w_hh)
                getattr(self.encoder, "bias_hh_l0" + suffix).copy_(b_hh)
            # fused output is [fwd streams 0..5, bwd streams 0..5]; the generator's is [fwd0, bwd0, fwd1, ...]
            order = [base + k * H + j for k in range(S) for base in (0, S * H) for j in range(H)]
            self.register_buffer("order", torch.tensor(order), persistent=False)
            dec = g.decoder
            self.decoder = nn.LSTM(dec.fwd.input_size, dec.fwd.hidden_size, batch_first=True, bidirectional=True)
            for suffix, src in (("", dec.fwd), ("_reverse", dec.bwd)):
                for name in ("weight_ih", "weight_hh", "bias_ih", "bias_hh"):
                    getattr(self.decoder, f"{name}_l0{suffix}").copy_(getattr(src, f"{name}_l0"))
        self.requires_grad_(False).eval()

    def encode(self, leader: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        """leader (1, T, 3J), labels (1, C) -> (1, T, latent) (no padding: every frame valid)."""
        x = torch.cat([leader, labels[:, None, :].expand(-1, leader.shape[1], -1)], dim=-1)
        h, _ = self.encoder(x)
        return h.index_select(2, self.order)

    def forward(self, leader: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        g = self.g
        h = self.encode(leader, labels)
        mask = torch.ones(h.shape[:2], dtype=torch.bool)
        dec, _ = self.decoder(g.decoder_input(h, g.attention(h, mask)))
        return g.out(dec) * g.follower_std + g.follower_mean
