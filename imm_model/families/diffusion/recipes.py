"""The diffusion family's recipes: a typed config (each field's accepted values declared beside it,
imm_model/typed_config.py) and the named recipes `imm-diffusion` (the bundled model's), `imm-diffusion-mixed`,
`imm-diffusion-parts`, `imm-diffusion-student` (a few-step student distilled from a teacher's sampler) and
`imm-diffusion-live` (a teacher's live reactor, live.py)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any, ClassVar

from imm_model.families.diffusion.live import LiveConfig
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance
from imm_model.typed_config import FieldsOf, Interval, ListOf, Name, OneOf, PathText, checked_kwargs, param, validate

FAMILY = "diffusion"

FRACTION = Interval(float, 0, 1)
BELOW_1 = Interval(float, 0, 1, closed="left")


@dataclass(frozen=True)
class DiffusionTrainConfig:
    # the recipe's name (run folders and reports carry it); a config built without one is no named recipe
    name: str = param("custom", Name())
    family: str = param(FAMILY, OneOf((FAMILY,)))  # the family a saved recipe file belongs to (families/__init__.py)
    # DiffusionConfig sizes (joints and classes come from the data)
    model: dict[str, Any] = param(check=FieldsOf(DiffusionConfig), factory=dict)
    guidance: dict[str, Any] = param(check=FieldsOf(Guidance), factory=dict)  # the sampler's defaults shipped with the model
    steps: int = param(6000, Interval(int, 1, 10_000_000))  # optimizer steps
    batch_size: int = param(32, Interval(int, 1, 4096))  # sequences per step
    # peak AdamW learning rate, after a linear warm-up, decayed by a cosine to a tenth
    lr: float = param(5e-4, Interval(float, 0, 1, closed="right"))
    warmup_steps: int = param(200, Interval(int, 0, None))  # steps of the linear warm-up
    weight_decay: float = param(1e-4, Interval(float, 0, None))  # AdamW weight decay
    label_drop: float = param(0.15, BELOW_1)  # probability a training row sees the "absent" label (the label-free term)
    leader_drop: float = param(0.25, BELOW_1)  # probability a training row sees the "absent" leader (the unconditioned term)
    # probability a training row sees its leader through the forward process's noise at a uniform step, told the step
    # (model.leader_noise): what the sampler's Guidance.leader_noise draws variations from
    leader_noise_prob: float = param(0.0, FRACTION)
    # probability a training row becomes a two-class composite by body parts, labelled with both classes
    # (training/part_mix.py; model.pair_terms): what the sampler's pair terms read
    mix_prob: float = param(0.0, FRACTION)
    # probability a training row's label names one body part only, the other part's label left out (model.part_labels):
    # what the sampler's one-part terms read
    part_drop: float = param(0.0, FRACTION)
    # probability a training row is its pair from a later frame on, standardized from that frame
    # (training/data.py late_starts): the windows a long take is sampled in begin mid-interaction
    late_start_prob: float = param(0.0, FRACTION)
    # probability a training row's first frames (1 .. T - 1 of them) are given clean in its noised input and left out of
    # the loss (model.given_frames): a window of a long take continues the follower frames made before it
    given_prob: float = param(0.0, FRACTION)
    lambda_velocity: float = param(1.0, Interval(float, 0, None))  # weight of the frame-to-frame velocity error beside x0's
    # weights of the geometric terms on the x0 prediction in metres (training/geometry.py): a planted foot's drag (per
    # m^2) and the torso direction's error
    lambda_foot_contact: float = param(0.0, Interval(float, 0, None))
    lambda_torso: float = param(0.0, Interval(float, 0, None))
    ema_decay: float = param(0.999, BELOW_1)  # the shipped model is this exponential moving average of the weights
    mirror_prob: float = param(0.5, FRACTION)  # swap left/right joints and flip the lateral axis
    # SBU's handshakes are all right-handed: never mirrored
    mirror_exclude_classes: tuple[str, ...] = param(("shaking_hands",), ListOf(Name(), unique=True))
    rotate_deg: float = param(0.0, Interval(float, 0, 180))  # uniform yaw of both characters in [-rotate_deg, rotate_deg]
    scale_jitter: float = param(0.0, BELOW_1)  # scale both characters about A's root by U(1 - s, 1 + s)
    time_warp: float = param(0.0, BELOW_1)  # resample each sequence to length * U(1 - w, 1 + w)
    role_swap_prob: float = param(0.0, FRACTION)  # B becomes the leader (re-canonicalized), for role_swap_classes only
    role_swap_classes: tuple[str, ...] = param((), ListOf(Name(), unique=True))  # the classes whose roles may swap
    # a teacher checkpoint whose sampler the network is distilled from, "{fold}" standing for the held-out subject
    # (distill.py; model.composed_label); empty: trained from the data
    teacher: str = param("", PathText())
    pool_rows: int = param(8192, Interval(int, 1, 1_000_000))  # the teacher's reactions a student learns from
    # share of those reactions that also give the student a window of a long take to learn from (distill.py
    # `window_bounds`): the teacher continuing its own reaction's earlier frames, as a long take's windows and the
    # live reactor sample (windows.py)
    window_share: float = param(0.0, FRACTION)
    # every this many steps the windows are given the student's own reaction to their clip instead of the teacher's,
    # the teacher's continuation of it their new target (distill.py `refresh_windows`); 0: the teacher's throughout
    window_refresh: int = param(0, Interval(int, 0, None))
    # weight of a critic's verdict on a student's reactions beside the regression onto the teacher's (distill.py
    # ReactionCritic, trained alongside to tell the teacher's reaction from the student's for the same leader and label)
    lambda_adversarial: float = param(0.0, Interval(float, 0, None))
    # weight of a frozen follower classifier's cross-entropy for the classes a row performs, on a student's reaction
    # (training/label_critic.py: trained on the fold's real training followers; the evaluation judges with others)
    lambda_label: float = param(0.0, Interval(float, 0, None))
    # the teacher's reactions per training leader a live reactor learns from (live_train.py): the run trains the
    # teacher's live reactor, not a denoiser; 0: a denoiser
    live_pool: int = param(0, Interval(int, 0, 10_000))
    live_takes: int = param(0, Interval(int, 0, 100_000))  # the teacher's long takes (windows.py) it learns from too
    live_part_share: float = param(0.0, FRACTION)  # share of those reactions whose label differs per body part
    live: dict[str, Any] = param(check=FieldsOf(LiveConfig), factory=dict)  # the live reactor's network (live.py)
    checkpoint_every: int = param(1000, Interval(int, 1, None))  # steps between resumable checkpoints
    seed: int = param(0, Interval(int, 0, 2**31 - 1))  # initial weights, batches, noise and augmentation

    RULES: ClassVar = (("leader_noise_prob", lambda c: c.leader_noise_prob == 0 or c.model.get("leader_noise") is True,
                        "0 unless model.leader_noise is true"),
             ("mix_prob", lambda c: c.mix_prob == 0 or c.model.get("pair_terms") is True or c.model.get("part_labels") is True,
              "0 unless model.pair_terms or model.part_labels is true"),
             ("part_drop", lambda c: c.part_drop == 0 or c.model.get("part_labels") is True, "0 unless model.part_labels is true"),
             ("given_prob", lambda c: c.given_prob == 0 or c.model.get("given_frames") is True,
              "0 unless model.given_frames is true"),
             ("teacher", lambda c: bool(c.teacher) == (c.model.get("composed_label") is True or c.live_pool > 0),
              "a checkpoint path exactly when model.composed_label is true or live_pool is above 0 (a student and a "
              "live reactor learn from a teacher)"),
             ("live_takes", lambda c: c.live_takes == 0 or c.live_pool > 0, "0 unless live_pool is above 0"),
             ("live_part_share", lambda c: c.live_part_share == 0 or c.live_pool > 0, "0 unless live_pool is above 0"),
             ("lambda_adversarial", lambda c: c.lambda_adversarial == 0 or bool(c.teacher),
              "0 unless a teacher is set (the critic judges a student's reactions)"),
             ("lambda_label", lambda c: c.lambda_label == 0 or bool(c.teacher),
              "0 unless a teacher is set (the label critic reads a student's reactions)"),
             ("window_share", lambda c: c.window_share == 0 or bool(c.teacher),
              "0 unless a teacher is set (the teacher's windows are a student's pool rows)"),
             ("window_refresh", lambda c: c.window_refresh == 0 or c.window_share > 0,
              "0 unless window_share is above 0 (it remakes the window rows)"))

    def __post_init__(self) -> None:
        validate(self, "training config")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["mirror_exclude_classes"] = list(self.mirror_exclude_classes)
        d["role_swap_classes"] = list(self.role_swap_classes)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> DiffusionTrainConfig:
        d = checked_kwargs(cls, d, "training config")
        for key in ("mirror_exclude_classes", "role_swap_classes"):
            if key in d:
                d[key] = tuple(d[key])
        return cls(**d)


# The reaction diffusion model as shipped: 128 wide, 4 blocks, one frame a token, 6000 steps of batch 32, a planted
# foot's drag and the torso's direction weighed beside the x0 error, half the leaders noised at a random level that the
# network is told; guidance 3 on each class term over the last 30 % of the noise levels, 7 DDIM steps, the leader read
# through noise at 0.3 of the schedule (the spread) but at the last step, a label per body part sampled part by part
# and the two reactions joined (docs/experiments/reaction-diffusion.md, diffusion-geometric-terms.md,
# diffusion-leader-noise.md, part-join.md and part-folds.md have the variants measured).
IMM_DIFFUSION = DiffusionTrainConfig(
    name="imm-diffusion",
    model=dict(width=128, layers=4, heads=4, ff_mult=2, dropout=0.1, leader_noise=True),
    guidance=dict(label_scale=3.0, leader_scale=1.0, sample_steps=7, guided_below=0.3, leader_noise=0.3, part_join=True,
                  join_outputs=True),
    lambda_foot_contact=20.0,
    lambda_torso=1.0,
    leader_noise_prob=0.5,
)

# The same with a share of its training rows made two-class composites by body parts, and the sampler's pair terms
# that read them: mixes read as mixed more often, at a cost in limb speed (docs/experiments/part-mix-training.md).
IMM_DIFFUSION_MIXED = replace(IMM_DIFFUSION, name="imm-diffusion-mixed", model=IMM_DIFFUSION.model | {"pair_terms": True},
                              mix_prob=0.3)

# A label per body part: every row teaches both parts' labels (a one-class row its class on both, a composite by parts
# one class on each, with the side drawn), and some name one part only, so that the sampler can compose each part's
# signed values (sampler.py `label_terms`; docs/experiments/part-labels.md).
IMM_DIFFUSION_PARTS = replace(IMM_DIFFUSION, name="imm-diffusion-parts", model=IMM_DIFFUSION.model | {"part_labels": True},
                              mix_prob=0.3, part_drop=0.3)

# A 2-step student of `imm-diffusion` (distill.py), the default model: the network reads the signed label and is asked
# once per step, 2 steps, trained for 2000 steps of batch 32 from 8192 of the teacher's reactions to the fold's training
# leaders, the fold's follower classifier's cross-entropy for the performed classes weighed 0.6 beside the regression
# (a regressed student averages the label away; 0.6 reads mixes and part mixes better than 0.2, nothing worse), and
# each clip's follower blended 0.3 of the way towards its smoothing in time (Guidance.smoothing: the student's frames
# jitter more than the teacher's, and 0.3 brings them to the teacher's on the dev folds). The teacher's run folder is
# runs/imm-diffusion (`imm train --config imm-diffusion`), its sampler settings kept. The teacher makes the student's
# long takes and live reactions (model.py teacher_for_takes), which a student taught on windows too still made further
# from the leader (docs/experiments/sampler-student.md, sampler-student-critics.md, sampler-student-windows.md,
# default-student.md, student-label-weight.md).
IMM_DIFFUSION_STUDENT = DiffusionTrainConfig(
    name="imm-diffusion-student",
    model=dict(composed_label=True),
    guidance=dict(sample_steps=2, smoothing=0.3),
    teacher="runs/imm-diffusion/fold-{fold}/final.safetensors",
    steps=2000,
    lr=1e-4,
    warmup_steps=100,
    ema_decay=0.995,
    lambda_label=0.6,
)

# The live reactor of `imm-diffusion` (live.py, live_train.py): a network causal by construction, reading the leader 4
# frames ahead, trained for 6000 steps of batch 32 on the teacher's reactions to each training leader 32 times (labels
# drawn as the student's are, a fifth of them per body part) and on 200 of its long takes; each frame the mean of
# the last 2 plans' (docs/experiments/causal-reactor.md). The teacher's run folder is runs/imm-diffusion; the result
# goes beside it as final_live.safetensors.
IMM_DIFFUSION_LIVE = DiffusionTrainConfig(
    name="imm-diffusion-live",
    teacher="runs/imm-diffusion/fold-{fold}/final.safetensors",
    live_pool=32,
    live_takes=200,
    live_part_share=0.2,
    live=dict(ensemble=2),
)

NAMED: dict[str, DiffusionTrainConfig] = {"imm-diffusion": IMM_DIFFUSION, "imm-diffusion-mixed": IMM_DIFFUSION_MIXED,
                                          "imm-diffusion-parts": IMM_DIFFUSION_PARTS,
                                          "imm-diffusion-student": IMM_DIFFUSION_STUDENT,
                                          "imm-diffusion-live": IMM_DIFFUSION_LIVE}
