"""The IMM networks: conditional hierarchical generator and class-aware discriminator.

The torch modules are imported when first asked for, so that model.config and model.numpy_runtime (the studio's
torch-free inference) do not import torch.
"""

from imm_model.model.config import BODY_PARTS, ModelConfig, model_config_for

__all__ = ["BODY_PARTS", "Discriminator", "Generator", "ModelConfig", "model_config_for"]


def __getattr__(name: str):
    if name == "Generator":
        from imm_model.model.generator import Generator

        return Generator
    if name == "Discriminator":
        from imm_model.model.discriminator import Discriminator

        return Discriminator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
