"""The IMM networks: conditional hierarchical generator and class-aware discriminator."""

from imm_model.model.config import BODY_PARTS, ModelConfig, model_config_for
from imm_model.model.discriminator import Discriminator
from imm_model.model.generator import Generator

__all__ = ["BODY_PARTS", "Discriminator", "Generator", "ModelConfig", "model_config_for"]
