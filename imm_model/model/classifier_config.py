"""The reaction classifiers' typed config (model/classifier.py holds the networks; this module imports no torch, so
the studio can read a classifier file without it)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import ClassVar

from imm_model.typed_config import Flag, Interval, OneOf, checked_kwargs, param, validate

INPUTS = ("interaction", "follower", "upper", "lower")  # "upper"/"lower": a body part of the follower (classifier.py)
ARCHITECTURES = ("gru", "conv")


FRACTION_BELOW_1 = Interval(float, 0, 1, closed="left")


@dataclass(frozen=True)
class ClassifierConfig:
    inputs: str = param("interaction", OneOf(INPUTS))  # what the classifier reads: both characters, or the follower
    arch: str = param("gru", OneOf(ARCHITECTURES))  # a bidirectional GRU or a temporal conv net (model/classifier.py)
    hidden: int = param(64, Interval(int, 1, 1024))  # width of the GRU / conv layers
    features: int = param(64, Interval(int, 2, 1024))  # width of the penultimate layer (the FID embedding)
    dropout: float = param(0.3, FRACTION_BELOW_1)  # before the penultimate layer, training only
    epochs: int = param(60, Interval(int, 1, 10_000))  # passes over the training sequences
    batch_size: int = param(32, Interval(int, 1, 4096))  # sequences per batch
    lr: float = param(2e-3, Interval(float, 0, None, closed="neither"))  # AdamW learning rate
    weight_decay: float = param(1e-2, Interval(float, 0, None))  # AdamW weight decay
    label_smoothing: float = param(0.1, FRACTION_BELOW_1)  # of the class targets
    rotate_deg: float = param(15.0, Interval(float, 0, 180))  # augmentation: yaw of the whole scene in [-rotate_deg, rotate_deg]
    scale_jitter: float = param(0.1, FRACTION_BELOW_1)  # ... body size U(1 - s, 1 + s)
    noise_m: float = param(0.01, Interval(float, 0, 1))  # ... Gaussian positional noise (metres), about Kinect's jitter
    # mixup: each training sequence blended with another of its batch (time-resampled to its length) at a weight
    # U(0, 1), the target blended alike, so the classifier's probabilities between classes follow real motion
    mixup: bool = param(False, Flag())
    # positions taken relative to where the body stood on the first frame (horizontally; heights kept), so the
    # classifier reads how the follower moves, not where it starts
    start_centred: bool = param(False, Flag())
    seed: int = param(0, Interval(int, 0, 2**31 - 1))  # initial weights, batches and augmentation

    RULES: ClassVar = (("start_centred", lambda c: not c.start_centred or c.inputs == "follower", "false for interaction inputs"),)

    def __post_init__(self) -> None:
        validate(self, "classifier config")

    def to_dict(self) -> dict:
        d = asdict(self)
        for option in ("mixup", "start_centred"):  # absent when off, so classifiers cached before it keep their keys
            if not d[option]:
                del d[option]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ClassifierConfig:
        return cls(**checked_kwargs(cls, d, "classifier config"))


# The classifiers `imm evaluate` uses: the interaction GRU (FID, recognition), the follower-only GRU (a
# training critic may use this one) and the follower-only conv net with another seed (the independent judge).
INTERACTION = ClassifierConfig(inputs="interaction", arch="gru")
FOLLOWER = ClassifierConfig(inputs="follower", arch="gru")
FOLLOWER_JUDGE = ClassifierConfig(inputs="follower", arch="conv", seed=1)
# The body-part judges of a mix: the follower's trunk and arms, and its legs and placement, each read alone (a mix may
# read as one class in one part and the other class in the other: shaking hands while stepping back from a push).
UPPER_JUDGE = ClassifierConfig(inputs="upper", arch="conv", seed=1)
LOWER_JUDGE = ClassifierConfig(inputs="lower", arch="conv", seed=1)
