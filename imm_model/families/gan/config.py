"""The GAN's model sizes as a typed config (recipes.py holds the named recipes, `paper` among them)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import ClassVar

from imm_model.typed_config import Flag, Interval, ListOf, OneOf, checked_kwargs, param, validate

BODY_PARTS = ("left_arm", "right_arm", "left_leg", "right_leg", "trunk")
DECODER_INPUTS = ("concat", "sum", "context")
ATTENTION_QUERIES = ("encoder", "decoder")
MAX_WIDTH = 4096


WIDTH = Interval(int, 1, MAX_WIDTH)  # a typo of 1e9 must not ask for a terabyte
FLAG = Flag()


@dataclass(frozen=True)
class ModelConfig:
    num_joints: int = param(15, Interval(int, 1, 512))  # joints per character (from the data)
    num_classes: int = param(6, Interval(int, 1, 512))  # interaction classes, the label's length (from the data)
    # Joint indices of the five body-part streams (the sixth stream is the whole body + label).
    body_parts: tuple[tuple[int, ...], ...] = param(check=ListOf(ListOf(Interval(int, 0, 511), min_length=1)),
                                                    factory=tuple)
    stream_embed: int = param(64, WIDTH)  # width of the per-stream fully connected layer
    encoder_hidden: int = param(40, WIDTH)  # per direction: a Bi-LSTM slice is 2 * 40 = 80 (paper, SBU)
    decoder_hidden: int = param(240, WIDTH)  # per direction: the attentive Bi-LSTM decoder is 480 wide (paper, SBU)
    attention_dim: int = param(128, WIDTH)  # additive attention v^T tanh(W h_t + U h_s)
    disc_hidden: int = param(64, WIDTH)  # per direction, two Bi-LSTM layers
    dropout: float = param(0.0, Interval(float, 0, 1, closed="left"))  # on the concatenated encodings and decoder output
    # True: one dropout mask per sequence, shared by all its frames ("variational" dropout for RNNs,
    # Gal & Ghahramani 2016); B x D random draws instead of B x T x D, which dominate dropout's CPU cost.
    dropout_per_sequence: bool = param(False, FLAG)
    # What the attentive decoder reads at each frame t, from the frame's encoding h_t and its attention
    # context c_t: "concat" [h_t, c_t] (2 x latent wide), "sum" h_t + c_t (a residual connection around the
    # attention, as in a Transformer block; latent wide, so the decoder's input projection costs half),
    # or "context" c_t alone (an attention layer placed between encoder and decoder).
    decoder_input: str = param("concat", OneOf(DECODER_INPUTS))
    # False: the whole-body stream reads the pose alone, the label is ignored (the label-free, Men et al.
    # 2022-style baseline `--config men`; the paper's ablation "without the multi-hot embedding").
    label_input: bool = param(True, FLAG)
    # False: no per-stream fully connected layer, each Bi-LSTM reads its stream's coordinates directly (the
    # paper's ablation "without the FC layers").
    stream_fc: bool = param(True, FLAG)
    # The attention query: "encoder", the frame's own encoding h_t (all frames at once, fast); "decoder", the
    # decoder's previous state as in the paper's Eq. 3 (frame by frame, layers.AttentiveDecoder).
    attention_query: str = param("encoder", OneOf(ATTENTION_QUERIES))

    RULES: ClassVar = (
        ("body_parts", lambda c: all(j < c.num_joints for part in c.body_parts for j in part), "joint indices below num_joints"),
    )

    def __post_init__(self) -> None:
        validate(self, "model config")

    @property
    def pose_dim(self) -> int:
        return 3 * self.num_joints

    @property
    def num_streams(self) -> int:
        return len(self.body_parts) + 1

    @property
    def latent_dim(self) -> int:
        return self.num_streams * 2 * self.encoder_hidden

    @property
    def decoder_input_dim(self) -> int:
        return 2 * self.latent_dim if self.decoder_input == "concat" else self.latent_dim

    def to_dict(self) -> dict:
        d = asdict(self)
        d["body_parts"] = [list(p) for p in self.body_parts]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelConfig:
        d = checked_kwargs(cls, d, "model config")
        if "body_parts" in d:
            d["body_parts"] = tuple(tuple(int(j) for j in p) for p in d["body_parts"])
        return cls(**d)


def model_config_for(skeleton, num_classes: int, **overrides) -> ModelConfig:
    """The config for a dataset's skeleton and classes (body parts in BODY_PARTS order)."""
    missing = [p for p in BODY_PARTS if p not in skeleton.body_parts]
    if missing:
        raise ValueError(f"skeleton {skeleton.name} lacks body parts {missing}")
    fixed = {"num_joints", "num_classes", "body_parts"}
    bad = sorted(set(overrides) - ({f.name for f in fields(ModelConfig)} - fixed))
    if bad:
        raise ValueError(f"unknown or fixed model config keys {bad} (joints, classes and body parts come from the data)")
    parts = tuple(tuple(skeleton.body_parts[p]) for p in BODY_PARTS)
    return ModelConfig(num_joints=skeleton.num_joints, num_classes=num_classes, body_parts=parts, **overrides)
