"""Which torch device to compute on: `--device auto|cpu|cuda` (auto: CUDA when this torch build sees a GPU)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch
    from torch import nn

CHOICES = ("auto", "cpu", "cuda")


def resolve_device(name: str) -> torch.device:
    """'auto' | 'cpu' | 'cuda' -> a torch.device; asking for CUDA without one is a one-line ValueError."""
    import torch  # here, so that building the CLI's parser does not import torch

    if name not in CHOICES:
        raise ValueError(f"--device {name!r}: expected one of {', '.join(CHOICES)}")
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda: this torch build sees no CUDA device (a CPU wheel, or no GPU); use --device cpu")
    return torch.device(name)


def move_module(module: nn.Module, device: torch.device | str) -> nn.Module:
    """`module.to(device)`, then its recurrent layers' weights packed into one cuDNN buffer each.

    `.to()` and `copy.deepcopy` leave an RNN's weights in separate tensors; cuDNN then copies them into one buffer on
    every call (and warns). On a CPU the packing is a no-op. Returns the module, moved in place.
    """
    from torch import nn

    module = module.to(device)
    for layer in module.modules():
        if isinstance(layer, nn.RNNBase):
            layer.flatten_parameters()
    return module


def add_device_argument(parser: argparse.ArgumentParser, default: str = "auto") -> None:
    parser.add_argument("--device", default=default, help=f"auto (CUDA if available, else CPU), cpu or cuda (default {default})")
