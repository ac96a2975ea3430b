"""The reaction diffusion model without its network: sizes, noise schedule, guidance and the DDIM sampler that
composes the signed multi-hot label. numpy only, so that the studio samples without importing torch.

The network (denoiser.py in torch for training and GPUs, denoiser_numpy.py in numpy for one CPU) predicts
the clean follower x0 from a noised one x_t, given per frame the leader's pose and, for the whole sequence, the
diffusion step and a label. Training drops the label and the leader independently (each replaced by a learned
"absent" input), so one network gives every term the sampler composes:

    x0(A, {w_c}) = x0(A, -) + s * sum_c w_c * (x0(A, e_c) - x0(A, -))

the composable-diffusion rule (Liu et al., ECCV 2022) on top of the leader-conditioned, label-free reaction: a
class at +1 is a conjunction, at -1 a negation, fractions weigh it, the studio's scale multiplies every w_c and
`s` is the model's guidance strength (at every step, or only below a noise level: `Guidance.guided_below`). All-zero
labels give the label-free reaction. The leader term itself can be guided too (x0(-, -) + g * (x0(A, -) - x0(-, -)))
when g != 1. Above the noise level `Guidance.leader_below` every term is the leader-absent one.

A network that reads a label per body part (`DiffusionConfig.part_labels`: an upper-body and a lower-body one-hot)
composes the same way over (part, class) terms (`label_terms`): a class both parts share weighs the whole-body
condition, a class on one part weighs that part's condition alone, and a class on each part adds the composite
condition the network learned from real followers composed by parts.

A sampler seed fixes the starting noise and, with stochastic steps (eta > 0), each step's fresh noise from a stream
of its own; both depend on the seed and the shape only, so the reaction is a continuous function of the label: a moved
slider moves the reaction, it does not jump to another sample. eta 0 is plain DDIM, where the starting noise is all.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import ClassVar

import numpy as np

from imm_model.typed_config import Flag, Interval, checked_kwargs, param, validate

MAX_WIDTH = 2048


@dataclass(frozen=True)
class DiffusionConfig:
    num_joints: int = param(15, Interval(int, 1, 512))  # joints per character (from the data)
    num_classes: int = param(6, Interval(int, 1, 512))  # interaction classes, the label's length (from the data)
    width: int = param(128, Interval(int, 8, MAX_WIDTH))  # transformer token width
    layers: int = param(4, Interval(int, 1, 64))  # transformer blocks
    heads: int = param(4, Interval(int, 1, 64))  # attention heads per block (width must divide by it)
    ff_mult: int = param(2, Interval(int, 1, 16))  # the blocks' MLP is ff_mult * width wide
    dropout: float = param(0.1, Interval(float, 0, 1, closed="left"))  # on attention and MLP outputs, training only
    diffusion_steps: int = param(100, Interval(int, 2, 10_000))  # T of the cosine noise schedule the network is trained on
    frames_per_token: int = param(1, Interval(int, 1, 8))  # consecutive frames one transformer token carries
    # the network reads how much noise is on its leader input (trained with noised leaders: training's
    # leader_noise_prob); the sampler's Guidance.leader_noise then widens the variations
    leader_noise: bool = param(False, Flag())
    # the network was trained on two-class composites (training's mix_prob) and reads two-hot labels: the sampler adds,
    # for each pair of performed classes, the joint pair term (see `sample`)
    pair_terms: bool = param(False, Flag())
    # the network reads two labels, one for the upper body (trunk and arms) and one for the lower body (legs and where
    # the follower stands), trained on both (training's part_drop and mix_prob): the sampler composes a label per part
    # (see `label_terms`)
    part_labels: bool = param(False, Flag())
    # the network was trained with a row's first frames given clean in its noised input (training's given_prob): the
    # sampler gives the frames a window of a long take continues so (`sample`'s `known`), not noised
    given_frames: bool = param(False, Flag())
    # the network reads the signed label, already times the scale, as one input and predicts the guided composition's
    # x0 at its steps (a student distilled from a teacher's sampler, distill.py): the sampler asks it once per step,
    # whatever the label, instead of once per term
    composed_label: bool = param(False, Flag())

    RULES: ClassVar = (("width", lambda c: c.width % c.heads == 0, "a multiple of heads"),
                       ("part_labels", lambda c: not (c.part_labels and c.pair_terms),
                        "false with pair_terms (a part model composes its own pair terms)"),
                       ("composed_label", lambda c: not (c.composed_label and (c.part_labels or c.pair_terms)),
                        "false with part_labels or pair_terms (a student reads whole-body labels; parts are joined)"))

    def __post_init__(self) -> None:
        validate(self, "diffusion config")

    @property
    def pose_dim(self) -> int:
        return 3 * self.num_joints

    @property
    def label_width(self) -> int:
        """The network's label input: one value per class, or per class and part (upper, then lower)."""
        return 2 * self.num_classes if self.part_labels else self.num_classes

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> DiffusionConfig:
        return cls(**checked_kwargs(cls, d, "diffusion config"))


# ---- noise schedule -------------------------------------------------------------------------------------------
def cosine_alpha_bar(steps: int) -> np.ndarray:
    """(steps,) cumulative signal fraction alpha_bar_t for t = 0..steps-1 (Nichol & Dhariwal 2021), float64."""
    s = 0.008
    t = np.arange(steps + 1, dtype=np.float64) / steps
    f = np.cos((t + s) / (1 + s) * math.pi / 2) ** 2
    alpha_bar = f[1:] / f[0]
    betas = np.clip(1 - alpha_bar / np.concatenate([[1.0], alpha_bar[:-1]]), 0, 0.999)
    return np.cumprod(1 - betas)


# ---- sampling ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Guidance:
    """How the sampler composes its terms; stored with each trained model as its defaults."""

    label_scale: float = param(2.5, Interval(float, 0, 20))  # s: the strength of each class term (times the label value)
    leader_scale: float = param(1.0, Interval(float, 0, 20))  # g: guidance on the leader term; 1 = the leader term alone
    sample_steps: int = param(20, Interval(int, 1, 1000))  # DDIM steps
    clip: float = param(6.0, Interval(float, 0.5, 100))  # x0 predictions clamped to this many training stds per coordinate
    eta: float = param(0.0, Interval(float, 0, 1))  # DDIM's eta: fresh noise per step, 0 = deterministic, 1 = DDPM-like
    # label_scale applies at the steps whose noise level t / (T - 1) is at most this; above it each class term weighs
    # its label value alone (guidance in a limited interval, Kynkaanniemi et al. 2024); 1 = at every step
    guided_below: float = param(1.0, Interval(float, 0, 1))
    # the leader conditions the steps whose noise level t / (T - 1) is at most this; above it every term takes the
    # learned absent-leader input, so that the first steps draw the reaction's coarse shape from the label alone and
    # the leader shapes it after (wider variations); 1 = the leader at every step
    leader_below: float = param(1.0, Interval(float, 0, 1))
    # the noise level t / (T - 1) the network sees its leader through, drawn from the sampler seed and the same at
    # every step but the last (a model with DiffusionConfig.leader_noise only): the reaction follows the leader's
    # coarse motion and samples its detail, so seeds differ more; the last step, whose prediction is the output, reads
    # the clean leader so that the leader's noise does not show as jitter; 0 = the clean leader throughout
    leader_noise: float = param(0.0, Interval(float, 0, 1))
    # the noise level t / (T - 1) the sampler starts from: a real reaction to a similar leader, from the model's
    # reaction memory (reaction_memory.py), noised to this level; 1 = from pure noise, without the memory
    memory_level: float = param(1.0, Interval(float, 0, 1))
    # a label per body part whose parts differ is composed by part at every step: the upper body's values and the lower
    # body's each composed as a whole-body label into a guided prediction of its own, the two joined around the body
    # centre (the model's `join_parts`: trunk and arms of the first on the second's legs and placement); off: a part
    # network's own part conditions (`label_terms`), and a whole-label network takes no label per body part
    part_join: bool = param(False, Flag())
    # with part_join, each part's reaction is sampled on its own from the same start and the two reactions are joined,
    # rather than the two predictions at every step: the network never reads a joined state, which pulls each part
    # towards the other's reaction
    join_outputs: bool = param(False, Flag())
    # each clip's follower blended this far towards its Savitzky-Golay smoothing in time (`smoothed`; a window of a
    # long take keeps the frames it is given): a 2-step student's frames jitter more than its many-step teacher's;
    # 0 = the sampler's followers as they are
    smoothing: float = param(0.0, Interval(float, 0, 1))

    def __post_init__(self) -> None:
        validate(self, "guidance")

    @property
    def uses_memory(self) -> bool:
        return self.memory_level < 1

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Guidance:
        return cls(**checked_kwargs(cls, d, "guidance"))


SMOOTH_FRAMES = 5  # the Savitzky-Golay window of `smoothed`: two frames either side, a quadratic fitted through them
_VANDER = np.vander(np.arange(SMOOTH_FRAMES) - SMOOTH_FRAMES // 2, 3, increasing=True)
# (w, w): the quadratic's fitted value at each position of a window, from the window's frames (least squares)
_FIT = _VANDER @ np.linalg.pinv(_VANDER)


def smoothed(motion: np.ndarray, share: float) -> np.ndarray:
    """motion (T, ...) blended `share` of the way towards its Savitzky-Golay smoothing in time (SMOOTH_FRAMES, order
    2; the ends from the polynomial fitted to the first and last window, as scipy's savgol_filter(mode="interp")
    gives it). Written here in numpy: scipy.signal costs the studio ~1 s to import. Shorter motion is left as it is."""
    w, half, fit = SMOOTH_FRAMES, SMOOTH_FRAMES // 2, _FIT
    if share == 0 or len(motion) < w:
        return motion
    x = np.asarray(motion, np.float64)
    out = np.empty_like(x)
    out[half:len(x) - half] = np.tensordot(np.lib.stride_tricks.sliding_window_view(x, w, axis=0), fit[half], axes=([-1], [0]))
    out[:half] = np.tensordot(fit[:half], x[:w], axes=([1], [0]))
    out[len(x) - half:] = np.tensordot(fit[half + 1:], x[-w:], axes=([1], [0]))
    return ((1 - share) * x + share * out).astype(motion.dtype)


def initial_noise(seed: int, frames: int, dim: int) -> np.ndarray:
    """The sampler's starting point for one sequence: a function of the seed and the shape only (float32)."""
    return np.random.default_rng(int(seed)).standard_normal((frames, dim)).astype(np.float32)


STEP_NOISE_STREAM = 1  # the per-step noise's generator is seeded from (seed, this), apart from the starting noise's
LEADER_NOISE_STREAM = 2  # and the leader noise's from (seed, this)
RESAMPLE_STREAM = 3  # and the noise of `ddim`'s resampling from (its rows' keys, this)


def schedule_step(level: float, diffusion_steps: int) -> int:
    """A noise level as a fraction of the schedule (Guidance.leader_noise, memory_level) -> its step index."""
    return int(round(level * (diffusion_steps - 1)))


def forward_noised(x0: np.ndarray, noise: np.ndarray, mask: np.ndarray, step: int, diffusion_steps: int) -> np.ndarray:
    """Normalized poses (B, T, D) and noise (B, T, D) -> the forward process at `step`, x_step (padding zero)."""
    a = cosine_alpha_bar(diffusion_steps)[step]
    return ((np.sqrt(a) * x0 + np.sqrt(1 - a) * noise) * mask[..., None]).astype(np.float32)


def leader_noise(seed: int, frames: int, dim: int) -> np.ndarray:
    """The noise the network sees its leader through (Guidance.leader_noise) for one sequence: a function of the seed
    and the shape only, drawn from (seed, LEADER_NOISE_STREAM) (float64; forward_noised applies it)."""
    return np.random.default_rng((int(seed), LEADER_NOISE_STREAM)).standard_normal((frames, dim))


def step_noise(seeds, lengths, shape: tuple[int, int, int], stream: int = STEP_NOISE_STREAM):
    """A generator of the stochastic steps' noise, (B, T, D) float32 per call: row i from a numpy Generator of its own
    seeded from (seeds[i], stream) (a seed: an int, or a tuple of ints), drawing (lengths[i], D) a step (zero padding
    beyond), so that a row's noise depends on its seed and length only, not on its batch."""
    gens = [np.random.default_rng((*(int(v) for v in np.atleast_1d(s)), stream)) for s in seeds]
    while True:
        z = np.zeros(shape, np.float32)
        for i, g in enumerate(gens):
            z[i, : lengths[i]] = g.standard_normal((int(lengths[i]), shape[2]))
        yield z


def label_terms(labels: np.ndarray, pair_terms: bool = False, part_labels: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Signed labels (B, C), or (B, 2C) for a part model (upper body's C values, then lower body's), already times the
    scale -> the label inputs the network is asked for, (K, L), and each row's weight on each term, (K, B), such that

        x0 = x0(A, -) + s * sum_k weight[k, b] * (x0(A, condition_k) - x0(A, -)).

    A whole-label network: one term per class some row weighs (condition e_c, weight the value); with `pair_terms`,
    for each pair of classes some row performs (both values > 0), the joint condition e_i + e_j weighs m = min(w_i, w_j)
    and each class term m less: the term s * m * (x0(e_i + e_j) - x0(e_i) - x0(e_j) + x0(-)), zero while either value
    is 0, so the reaction moves continuously from the sum rule, and at w_i = w_j = 1 guidance on the joint condition.

    A part network reads (upper one-hot, lower one-hot); a part left out is zeros. Per class, the value both parts
    share (same sign, the smaller magnitude) weighs the whole-body condition (e_c, e_c), the condition the network saw
    on every one-class row, so a whole-body label composes as a whole-label model's does; what is left on one part
    weighs that part's condition alone ((e_c, 0) or (0, e_c)). For each class performed on the upper body only and
    another on the lower body only, the composite condition (e_i, e_j) the network learned from part composites
    enters as a pair term does, with m = min of the two leftovers."""
    b = labels.shape[0]
    c = labels.shape[1] // 2 if part_labels else labels.shape[1]
    conditions: list[np.ndarray] = []
    weights: list[np.ndarray] = []

    def term(condition: np.ndarray, weight: np.ndarray) -> int:
        conditions.append(condition.astype(np.float32))
        weights.append(weight.astype(np.float64))
        return len(conditions) - 1

    def joint(first: int, second: int, condition: np.ndarray, m: np.ndarray) -> None:
        term(condition, m)
        weights[first] = weights[first] - m
        weights[second] = weights[second] - m

    eye = np.eye(c, dtype=np.float32)
    zero = np.zeros(c, np.float32)
    if not part_labels:
        of = {cls: term(eye[cls], labels[:, cls]) for cls in np.flatnonzero(np.abs(labels).sum(0) > 0).tolist()}
        if pair_terms:
            performed = np.maximum(labels, 0)
            for i, j in itertools.combinations(sorted(of), 2):
                m = np.minimum(performed[:, i], performed[:, j])
                if (m > 0).any():
                    joint(of[i], of[j], eye[i] + eye[j], m)
    else:
        upper, lower = labels[:, :c].astype(np.float64), labels[:, c:].astype(np.float64)
        shared = np.where(upper * lower > 0, np.sign(upper) * np.minimum(np.abs(upper), np.abs(lower)), 0.0)
        upper_only, lower_only = upper - shared, lower - shared
        for cls in np.flatnonzero(np.abs(shared).sum(0) > 0).tolist():
            term(np.concatenate([eye[cls], eye[cls]]), shared[:, cls])
        ups = {cls: term(np.concatenate([eye[cls], zero]), upper_only[:, cls])
               for cls in np.flatnonzero(np.abs(upper_only).sum(0) > 0).tolist()}
        lows = {cls: term(np.concatenate([zero, eye[cls]]), lower_only[:, cls])
                for cls in np.flatnonzero(np.abs(lower_only).sum(0) > 0).tolist()}
        for i, j in itertools.product(sorted(ups), sorted(lows)):
            m = np.minimum(np.maximum(upper_only[:, i], 0), np.maximum(lower_only[:, j], 0))
            if i != j and (m > 0).any():
                joint(ups[i], lows[j], np.concatenate([eye[i], eye[j]]), m)
    width = 2 * c if part_labels else c
    if not conditions:
        return np.zeros((0, width), np.float32), np.zeros((0, b), np.float32)
    return np.stack(conditions), np.stack(weights).astype(np.float32)


def ddim_step(x: np.ndarray, x0: np.ndarray, a: float, a_next: float, eta: float, m: np.ndarray,
              fresh: np.ndarray | None = None) -> np.ndarray:
    """One DDIM update: x_t (B, T, D) at signal fraction `a`, the predicted x0 -> x at `a_next` (float32, padding
    zero through `m` (B, T, 1)). With eta > 0 part of the direction term is the fresh noise `fresh` (B, T, D)
    (Song et al. 2021, eq. 16); eta 0 is deterministic."""
    eps = (x - np.sqrt(a) * x0) / np.sqrt(1 - a)
    if eta > 0:
        sigma = eta * np.sqrt((1 - a_next) / (1 - a)) * np.sqrt(1 - a / a_next)
        x = np.sqrt(a_next) * x0 + np.sqrt(max(1 - a_next - sigma**2, 0.0)) * eps + sigma * fresh
    else:
        x = np.sqrt(a_next) * x0 + np.sqrt(1 - a_next) * eps
    return (x * m).astype(np.float32)


def ddim(predict, noise: np.ndarray, mask: np.ndarray, guidance: Guidance, diffusion_steps: int, seeds=None,
         resample: tuple[int, list] | None = None) -> np.ndarray:
    """The sampling loop, apart from what a step predicts: from `noise` (B, T, D), x_t at the start step
    (Guidance.memory_level's), `predict(x_t, step)` -> x0 (B, T, D) at each of the guidance's `sample_steps` steps
    and a `ddim_step` between them -> the last prediction, float32. With guidance.eta > 0 each step but the last adds
    noise drawn from the rows' `seeds` (B ints, required then; see step_noise). `sample` predicts with the composed
    label; another composition brings its own `predict` and reuses this loop.

    With `resample` = (times, keys) each step but the last is taken `times` more times, its result noised back to the
    step's level in between with noise drawn from the rows' `keys` (B seeds, step_noise's RESAMPLE_STREAM): RePaint's
    resampling (Lugmayr et al. 2022), so that frames held by `predict` (`keeping`) and the frames sampled around them
    settle together rather than the held ones being pasted in once a step."""
    b, t, d = noise.shape
    alpha_bar = cosine_alpha_bar(diffusion_steps)
    steps = np.linspace(schedule_step(guidance.memory_level, diffusion_steps), 0, guidance.sample_steps).round().astype(int)
    m = mask[..., None].astype(np.float32)
    x = noise.astype(np.float32)
    fresh = again = None
    if guidance.eta > 0:
        if seeds is None or len(seeds) != b:
            raise ValueError(f"sampling with eta {guidance.eta} needs one seed per row ({b})")
        fresh = step_noise(seeds, mask.sum(1), (b, t, d))
    times = resample[0] if resample else 0
    if times:
        again = step_noise(resample[1], mask.sum(1), (b, t, d), RESAMPLE_STREAM)
    for i, step in enumerate(steps):
        for turn in range(times + 1):
            x0 = predict(x, int(step))
            if i + 1 == len(steps):
                return x0.astype(np.float32)
            after = ddim_step(x, x0, alpha_bar[step], alpha_bar[steps[i + 1]], guidance.eta, m,
                              None if fresh is None else next(fresh))
            if turn < times:  # back from the next step's level to this one's
                back = alpha_bar[step] / alpha_bar[steps[i + 1]]
                x = ((np.sqrt(back) * after + np.sqrt(1 - back) * next(again)) * m).astype(np.float32)
        x = after
    raise AssertionError("unreachable: sample_steps >= 1")


def sample(denoise, leaders: np.ndarray, mask: np.ndarray, labels: np.ndarray, noise: np.ndarray, guidance: Guidance,
           diffusion_steps: int, seeds=None, pair_terms: bool = False, part_labels: bool = False, join=None,
           known=None, composed_label: bool = False, resample: tuple[int, list] | None = None) -> np.ndarray:
    """DDIM (`ddim`) from `noise` (B, T, D) -> normalized followers x0 (B, T, D), numpy float32, each step predicting
    the composed label's x0.

    `denoise(x_t, step, leader_on, label, label_on)` is the network on a batch of the same rows repeated per term:
    x_t (N, T, D), step int, leader_on (N,) bool, label (N, L) the label input, label_on (N,) bool -> x0 (N, T, D); it
    reads `leaders` (normalized, B rows, repeated alike) and `mask` from its closure. labels (B, C), or (B, 2C) with
    `part_labels`, are signed weights (already times the scale). Each step evaluates, in one batch, the leader-only
    term, the label terms of `label_terms` (`pair_terms`, `part_labels`: what the network was trained to read) and
    (with leader_scale != 1) the unconditioned term; a student (`composed_label`) reads the label itself, one term.

    With `join(upper_x0, lower_x0) -> x0` (normalized (B, T, D) each; Guidance.part_join) `labels` are (B, 2C), the
    upper body's values then the lower body's, for either network: where a row's parts differ, each part's values are
    composed as a whole-body label into a guided prediction of its own and the two are joined at every step, or, with
    Guidance.join_outputs, each part's reaction is sampled on its own from the same start and the two reactions are
    joined; a row whose parts agree takes the upper one's, the whole-body label's reaction.

    With `known` = (values (B, T, D) normalized, where (B, T) bool, clean) the frames `where` marks are given, not
    sampled: every step's prediction holds them at their values (inpainting by replacement, as PriorMDM continues a
    long sequence), and with `clean` (a network trained so: DiffusionConfig.given_frames) the network reads them clean
    in its noised input; the frames sampled around them continue them, as a window of a long take continues the one
    before. `resample` (`ddim`'s) takes each step again so that the two settle together."""
    flags = (pair_terms, part_labels, composed_label)
    if join is None:
        predict = guided_prediction(denoise, labels, guidance, diffusion_steps, mask, *flags)
        return ddim(keeping(predict, known), noise, mask, guidance, diffusion_steps, seeds, resample)
    c = labels.shape[1] // 2
    upper, lower = labels[:, :c], labels[:, c:]
    if part_labels:  # each part's values as the whole-body condition (e_c, e_c) the network saw on every one-class row
        upper, lower = np.concatenate([upper, upper], 1), np.concatenate([lower, lower], 1)
    apart = ~np.all(labels[:, :c] == labels[:, c:], axis=1)[:, None, None]
    if not apart.any():
        return ddim(keeping(guided_prediction(denoise, upper, guidance, diffusion_steps, mask, *flags), known), noise,
                    mask, guidance, diffusion_steps, seeds, resample)
    by_parts = predicting(denoise, [guided_terms(v, guidance, diffusion_steps, mask, *flags) for v in (upper, lower)],
                          guidance, diffusion_steps)
    m = mask[..., None].astype(np.float32)

    def joined(x_upper: np.ndarray, x_lower: np.ndarray) -> np.ndarray:
        return (np.where(apart, join(x_upper, x_lower), x_upper) * m).astype(np.float32)

    if not guidance.join_outputs:
        return ddim(keeping(lambda x, step: joined(*by_parts([x, x], step)), known), noise, mask, guidance,
                    diffusion_steps, seeds, resample)
    # each part's reaction sampled on its own, the two side by side as one batch of 2B rows (one network call a step)
    b = len(labels)

    def twice(a) -> np.ndarray:
        return np.concatenate([a, a])

    both = ddim(keeping(lambda x, step: np.concatenate(by_parts([x[:b], x[b:]], step)),
                        None if known is None else (twice(known[0]), twice(np.asarray(known[1])), known[2])),
                twice(noise), twice(mask), guidance, diffusion_steps, None if seeds is None else [*seeds, *seeds],
                None if resample is None else (resample[0], [*resample[1], *resample[1]]))
    return joined(both[:b], both[b:])


def keeping(predict, known):
    """`predict(x_t, step)` with the frames of `known` = (values, where, clean) held at their values, and read clean
    by the network with `clean` (None: `predict`)."""
    if known is None:
        return predict
    values, where, clean = known
    where = np.asarray(where, bool)[..., None]
    if clean:
        return lambda x, step: np.where(where, values, predict(np.where(where, values, x).astype(np.float32), step)).astype(np.float32)
    return lambda x, step: np.where(where, values, predict(x, step)).astype(np.float32)


@dataclass(frozen=True)
class GuidedTerms:
    """One guided prediction's network rows: per row of x_t, `count` terms whose inputs are `leader_on`, `label` and
    `label_on` (count * B rows, term-major, as `denoise` takes them), and `compose(terms (count, B, T, D), step)` -> x0
    (B, T, D), clipped and masked."""

    count: int
    leader_on: np.ndarray
    label: np.ndarray
    label_on: np.ndarray
    compose: Callable[[np.ndarray, int], np.ndarray]


def guided_terms(labels: np.ndarray, guidance: Guidance, diffusion_steps: int, mask: np.ndarray,
                 pair_terms: bool = False, part_labels: bool = False, composed_label: bool = False) -> GuidedTerms:
    """The network's terms for `labels` (as `sample` takes them) and their composition by the guidance at one step; a
    student's (`composed_label`) one term, the label itself."""
    b = labels.shape[0]
    m = mask[..., None].astype(np.float32)
    if composed_label:
        on = np.ones(b, bool)
        return GuidedTerms(1, on, labels.astype(np.float32), on,
                           lambda terms, step: np.clip(terms[0], -guidance.clip, guidance.clip) * m)
    conditions, weights = label_terms(labels, pair_terms, part_labels)
    k = len(conditions)
    n_terms = 1 + k + (guidance.leader_scale != 1.0)
    label_input = np.zeros((n_terms, b, conditions.shape[1]), np.float32)
    label_input[1:1 + k] = conditions[:, None]
    label_on = np.zeros((n_terms, b), bool)
    label_on[1:1 + k] = True
    leader_on = np.ones((n_terms, b), bool)
    if guidance.leader_scale != 1.0:
        leader_on[-1] = False
    unguided = weights[..., None, None]  # (K, B, 1, 1): the label terms at s = 1

    def compose(terms: np.ndarray, step: int) -> np.ndarray:
        base = terms[0]
        x0 = base
        strength = np.float32(guidance.label_scale) if step <= guidance.guided_below * (diffusion_steps - 1) else np.float32(1)
        if k:
            x0 = x0 + (unguided * strength * (terms[1:1 + k] - base)).sum(0)
        if guidance.leader_scale != 1.0:
            x0 = terms[-1] + guidance.leader_scale * (x0 - terms[-1])
        return np.clip(x0, -guidance.clip, guidance.clip) * m

    return GuidedTerms(n_terms, leader_on.reshape(-1), label_input.reshape(n_terms * b, -1), label_on.reshape(-1), compose)


def predicting(denoise, groups: list[GuidedTerms], guidance: Guidance, diffusion_steps: int):
    """`predict([x_t per group], step)` -> [x0 per group]: each group's guided prediction from its own x_t (B, T, D),
    all in one network call (on a CPU a few small calls cost more than one of their rows together)."""
    leader_on = np.concatenate([g.leader_on for g in groups])
    label = np.concatenate([g.label for g in groups])
    label_on = np.concatenate([g.label_on for g in groups])
    no_leader = np.zeros_like(leader_on)

    def predict(xs: list[np.ndarray], step: int) -> list[np.ndarray]:
        with_leader = leader_on if step <= guidance.leader_below * (diffusion_steps - 1) else no_leader
        terms = denoise(np.concatenate([np.tile(x, (g.count, 1, 1)) for g, x in zip(groups, xs, strict=True)]), step,
                        with_leader, label, label_on)
        out, start = [], 0
        for g, x in zip(groups, xs, strict=True):
            rows = g.count * len(x)
            out.append(g.compose(terms[start:start + rows].reshape(g.count, *x.shape), step))
            start += rows
        return out

    return predict


def guided_prediction(denoise, labels: np.ndarray, guidance: Guidance, diffusion_steps: int, mask: np.ndarray,
                      pair_terms: bool = False, part_labels: bool = False, composed_label: bool = False):
    """`predict(x_t, step)` -> x0 (B, T, D): the network's terms for `labels` (as `sample` takes them) composed by the
    guidance at one step, clipped and masked; a student's (`composed_label`) one call with the label itself."""
    predict = predicting(denoise, [guided_terms(labels, guidance, diffusion_steps, mask, pair_terms, part_labels,
                                                composed_label)], guidance, diffusion_steps)
    return lambda x, step: predict([x], step)[0]
