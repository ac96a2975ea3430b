"""IMM Studio's library: an implementation of "Interaction Mix and Match" (Goel, Men, Ho).

data -> model -> training -> evaluation; `explorer/` (the web studio) builds on top of it.
"""

__version__ = "0.1.0"

__all__ = ["ReactionModel", "__version__", "latent", "synthesize"]


def __getattr__(name: str):
    # Lazy: `import imm_model` stays light; torch is imported on first use of the inference API.
    if name in ("ReactionModel", "synthesize", "latent"):
        from imm_model import inference

        return getattr(inference, name)
    raise AttributeError(f"module 'imm_model' has no attribute {name!r}")
