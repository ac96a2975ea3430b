"""The live reactor: a network causal by construction, a student of the clip model, that makes the follower frame by
frame as the leader's frames come (`LiveReactor`, what `model.online` returns when the model has one).

At frame t its context (causal temporal convolutions, `LiveConfig.dilations`) reads the leader's frames up to
t + `lookahead`, the follower frames it made before t and the label; a small diffusion head draws the follower's next
`chunk` frames (its plan) from that context in `sample_steps` DDIM steps, starting from the last push's plan one frame
on, noised to `carry_level`; the frame returned is the mean of what the last `ensemble` plans drew for it (temporal
ensembling, as ACT, Zhao et al. 2023, smooths overlapping action chunks). It reads the label per body part (upper, then
lower) whole, already times the scale, and is asked once per step, whatever the label.

It learnt from the clip model's own reactions (live_train.py): to every training leader under any label (off-label,
signed, mixed, per part) and many seeds, and to long takes made as the clip model makes them (windows.py). Trained on
recorded pairs instead, such a network never used its label: in SBU the leader shows the class
(docs/experiments/causal-reactor.md). Here in numpy, as the studio runs it (no `import torch`); the torch network that
trains it is live_train.py's `LiveNet`, with the same weights' names.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from imm_model.data.canonical import CanonicalFrame
from imm_model.errors import CheckpointError
from imm_model.families.diffusion.denoiser_numpy import _layer_norm, _silu, sinusoid
from imm_model.families.diffusion.sampler import cosine_alpha_bar
from imm_model.families.diffusion.steering import SteeredReaction
from imm_model.typed_config import Interval, ListOf, checked_kwargs, param, validate

KIND = "live_reactor"  # a live reactor checkpoint's sidecar "kind"
SUFFIX = "_live"  # a model's live reactor is the checkpoint beside it named <model's stem>_live.safetensors
LEVEL_FEATURES = 64  # sinusoidal features of the head's noise level
CLIP = 6.0  # x0 predictions clamped to this many training stds, as the clip sampler does
# the take's canonical frame follows the leader (shifted, not turned) so that the leader's root stays within this
# distance of its origin (horizontally): the network learnt leaders who start at the origin and move less than 0.83 m in a
# clip (0.79 m for 99 in 100 SBU clips), and a leader who walks on left that, the follower behind (K3HI's walking
# leaders, 4 in a row: hands in the last copy 0.92 m from the leader's, against 1.26 m in a fixed frame;
# docs/experiments/causal-reactor.md). Its facing is not followed: over 10 frames it turns up to 96 degrees within nine
# in ten SBU clips, too unsteady to follow.
REANCHOR_M = 0.75


@dataclass(frozen=True)
class LiveConfig:
    num_joints: int = param(15, Interval(int, 1, 512))  # joints per character (from the data)
    num_classes: int = param(6, Interval(int, 1, 512))  # interaction classes; the label read has 2 x as many values
    width: int = param(128, Interval(int, 8, 4096))  # channels of the context's causal convolutions
    # dilations of the context's residual causal convolutions (kernel 3): it reads the last 1 + 2 * sum frames
    dilations: tuple[int, ...] = param((1, 2, 4, 8, 16), ListOf(Interval(int, 1, 256), 1, 16))
    head_width: int = param(384, Interval(int, 8, 4096))  # the diffusion head's width
    head_blocks: int = param(3, Interval(int, 1, 32))  # the head's residual MLP blocks
    lookahead: int = param(4, Interval(int, 0, 30))  # leader frames beyond the one a follower frame answers
    chunk: int = param(8, Interval(int, 1, 64))  # follower frames the head draws at once (its plan); the first is emitted
    diffusion_steps: int = param(100, Interval(int, 2, 10_000))  # T of the head's cosine noise schedule
    sample_steps: int = param(4, Interval(int, 1, 100))  # DDIM steps a push takes
    # each push starts its plan from the last one's, one frame on, noised to this level (t / T): the reaction keeps to
    # the plan it drew (the first push starts from pure noise)
    carry_level: float = param(0.6, Interval(float, 0, 1))
    # the frame returned is the mean of what the last this many plans drew for it (1: the newest plan's alone)
    ensemble: int = param(2, Interval(int, 1, 64))

    RULES: ClassVar = (("ensemble", lambda c: c.ensemble <= c.chunk, "at most chunk (a plan draws chunk frames)"),)

    def __post_init__(self) -> None:
        validate(self, "live reactor config")

    @property
    def pose_dim(self) -> int:
        return 3 * self.num_joints

    @property
    def receptive(self) -> int:
        """Frames the context reads at once: the frame it answers and those before it."""
        return 1 + 2 * sum(self.dilations)

    def to_dict(self) -> dict:
        return asdict(self) | {"dilations": list(self.dilations)}

    @classmethod
    def from_dict(cls, d: dict) -> LiveConfig:
        d = checked_kwargs(cls, d, "live reactor config")
        if "dilations" in d and isinstance(d["dilations"], list):
            d["dilations"] = tuple(d["dilations"])
        return cls(**d)


def expected_shapes(cfg: LiveConfig) -> dict[str, tuple[int, ...]]:
    """The weights' names and shapes (live_train.py `LiveNet`'s state dict)."""
    d, c, w, h = cfg.pose_dim, 2 * cfg.num_classes, cfg.width, cfg.head_width
    shapes = {"inp.weight": (w, (cfg.lookahead + 1) * d + 1 + d + 1 + c + 1), "inp.bias": (w,),
              "label.weight": (h, c), "label.bias": (h,), "absent": (h,),
              "level.0.weight": (h, LEVEL_FEATURES), "level.0.bias": (h,), "level.2.weight": (h, h), "level.2.bias": (h,),
              "head_in.weight": (h, cfg.chunk * d + w), "head_in.bias": (h,),
              "out.0.weight": (h,), "out.0.bias": (h,), "out.1.weight": (cfg.chunk * d, h), "out.1.bias": (cfg.chunk * d,)}
    for k in range(len(cfg.dilations)):
        shapes |= {f"convs.{k}.conv.weight": (w, w, 3), f"convs.{k}.conv.bias": (w,),
                   f"convs.{k}.mix.weight": (w, w, 1), f"convs.{k}.mix.bias": (w,)}
    for k in range(cfg.head_blocks):
        shapes |= {f"blocks.{k}.0.weight": (h,), f"blocks.{k}.0.bias": (h,), f"blocks.{k}.1.weight": (2 * h, h),
                   f"blocks.{k}.1.bias": (2 * h,), f"blocks.{k}.4.weight": (h, 2 * h), f"blocks.{k}.4.bias": (h,)}
    for who in ("leader", "follower"):
        shapes |= {f"{who}_mean": (d,), f"{who}_std": (d,)}
    return shapes


class LiveNet:
    """The network's forward pass in numpy (float32)."""

    def __init__(self, weights: dict[str, np.ndarray], cfg: LiveConfig):
        self.w, self.cfg = weights, cfg

    def _linear(self, name: str, x: np.ndarray) -> np.ndarray:
        return x @ self.w[f"{name}.weight"].T + self.w[f"{name}.bias"]

    def context(self, leader_windows: np.ndarray, past: np.ndarray, past_on: np.ndarray, label: np.ndarray,
                label_on: np.ndarray) -> np.ndarray:
        """(B, T, (L+1) D), the follower's frames before each (B, T, D) with whether they exist (B, T, 1), labels
        (B, 2C) and whether each is given (B,) -> the last frame's context (B, width)."""
        b, t, _ = leader_windows.shape
        on = label_on.astype(np.float32)[:, None]
        labels = np.broadcast_to(np.concatenate([label * on, on], -1)[:, None], (b, t, label.shape[1] + 1))
        x = self._linear("inp", np.concatenate([leader_windows, np.ones((b, t, 1), np.float32), past * past_on, past_on,
                                                labels], -1))
        for k, dil in enumerate(self.cfg.dilations):
            kernel, bias = self.w[f"convs.{k}.conv.weight"], self.w[f"convs.{k}.conv.bias"]
            padded = np.concatenate([np.zeros((b, 2 * dil, x.shape[2]), np.float32), x], 1)
            y = sum(padded[:, j * dil:j * dil + t] @ kernel[:, :, j].T for j in range(3)) + bias
            x = x + _silu(y) @ self.w[f"convs.{k}.mix.weight"][:, :, 0].T + self.w[f"convs.{k}.mix.bias"]
        return _silu(x[:, -1])

    def denoise(self, x_t: np.ndarray, level: int, h: np.ndarray, label: np.ndarray, label_on: np.ndarray) -> np.ndarray:
        """Noised plans (N, chunk D) at step `level`, contexts (N, width), labels (N, 2C) given or not (N,) -> x0."""
        lev = self._linear("level.2", _silu(self._linear("level.0", sinusoid(np.full(len(x_t), level), LEVEL_FEATURES))))
        cond = lev + np.where(label_on[:, None], self._linear("label", label), self.w["absent"])
        z = self._linear("head_in", np.concatenate([x_t, h], -1)) + cond
        for k in range(self.cfg.head_blocks):
            y = _layer_norm(z) * self.w[f"blocks.{k}.0.weight"] + self.w[f"blocks.{k}.0.bias"]
            z = z + self._linear(f"blocks.{k}.4", _silu(self._linear(f"blocks.{k}.1", y)))
        return self._linear("out.1", _layer_norm(z) * self.w["out.0.weight"] + self.w["out.0.bias"])


def leader_windows(leader: np.ndarray, lookahead: int) -> np.ndarray:
    """(T, D) -> (T, (L+1) D): frame t's leader frames t .. t + L, the last frame repeated past the end."""
    idx = np.minimum(np.arange(len(leader))[:, None] + np.arange(lookahead + 1)[None], len(leader) - 1)
    return leader[idx].reshape(len(leader), -1)


class LiveReactor(SteeredReaction):
    """A reaction to a leader streamed frame by frame (steering.py `SteeredReaction`), made by a live reactor network
    (windows.py `OnlineReactor` does it for a model without one). The canonical frame is the leader's first frames'
    (the lookahead's), moved with a leader who walks on (REANCHOR_M); the frames returned go through the causal
    clean-up unless the model is `raw`. Memory is bounded: the network reads the last `receptive` frames."""

    def __init__(self, model, live: LiveNet, label, scale: float = 1.0, seed: int = 0):
        from imm_model.cleanup import OnlineCleanup

        self.model, self.net, self.cfg, self.seed = model, live, live.cfg, int(seed)
        self.lookahead = self.cfg.lookahead
        super().__init__(label, scale)
        self._noise = np.random.default_rng(self.seed)
        d = self.cfg.pose_dim
        self._world = np.zeros((0, model.skeleton.num_joints, 3))  # leader frames not standardized yet (the first ones)
        self._frame: CanonicalFrame | None = None
        self._leader = np.zeros((0, d), np.float32)  # standardized, normalized leader frames kept (the context's)
        self._past = np.zeros((0, d), np.float32)  # normalized follower frames made, kept alike
        self._plans = np.zeros((0, self.cfg.chunk * d), np.float32)  # the last `ensemble` plans, newest last
        self._first = 0  # the take's frame the kept buffers start at
        self._alpha_bar = cosine_alpha_bar(self.cfg.diffusion_steps)
        self._clean = None if model.raw else OnlineCleanup(model.skeleton, model.bone_lengths)

    def _label_input(self, label, scale: float) -> np.ndarray:
        vec = self.model.label_vector(label, scale)
        return np.concatenate([vec, vec]) if len(vec) == self.cfg.num_classes else vec

    def _take(self, frame: np.ndarray) -> None:
        self._world = np.concatenate([self._world, frame[None]])

    def _standardize(self) -> None:
        """The leader frames pushed, into the kept buffer: standardized in the take's canonical frame (set by the
        first frames seen, then following the leader, `_follow`) and normalized."""
        if len(self._world) == 0:
            return
        if self._frame is None:
            first = CanonicalFrame.from_leader(self._world, self.model.skeleton, self.model.canonical_mode)
            self._frame = CanonicalFrame(first.yaw[:1], first.origin[:1], first.mode)
        else:
            self._follow(self._world[-1])
        n = len(self._world)
        frame = CanonicalFrame(np.repeat(self._frame.yaw, n), np.repeat(self._frame.origin, n, 0), self._frame.mode)
        canon = frame.to_canonical(self._world, self.model.skeleton).reshape(n, -1)
        w = self.net.w
        self._leader = np.concatenate([self._leader, ((canon - w["leader_mean"]) / w["leader_std"]).astype(np.float32)])
        self._world = self._world[:0]

    def _follow(self, newest: np.ndarray) -> None:
        """The canonical frame shifted towards the leader's newest root until that lies REANCHOR_M from its origin, and
        the frames kept (leader, follower, plans) re-expressed in it: what they are in the world is unchanged."""
        skeleton, up = self.model.skeleton, self.model.skeleton.vertical_axis
        offset = self._frame.to_canonical(newest[None, skeleton.root:skeleton.root + 1], skeleton)[0, 0]
        offset[up] = 0.0  # heights stay measured from the take's start
        away = float(np.linalg.norm(offset))
        if away <= REANCHOR_M:
            return
        offset *= 1 - REANCHOR_M / away  # the origin follows the leader, REANCHOR_M behind it
        origin = self._frame.to_world(offset[None, None], skeleton)[0]  # (1, 3): the offset's point, in the world
        self._frame = CanonicalFrame(self._frame.yaw, origin, self._frame.mode)
        shift = np.tile(offset, skeleton.num_joints).astype(np.float32)
        w = self.net.w
        self._leader = self._leader - shift / w["leader_std"]
        self._past = self._past - shift / w["follower_std"]
        self._plans = self._plans - np.tile(shift / w["follower_std"], self.cfg.chunk)

    def _emit(self, n: int) -> np.ndarray:
        self._standardize()
        out = [self._step() for _ in range(n)]
        # only what the context reads is kept (the frame before its first too): a take of any length runs in bounded
        # memory
        drop = len(self._leader) - (self.cfg.receptive + self.lookahead + 1)
        if drop > 0:
            self._leader, self._past, self._first = self._leader[drop:], self._past[drop:], self._first + drop
        made = self._to_world(np.stack(out))
        return made if self._clean is None else self._clean(made).astype(np.float32)

    def _to_world(self, normalized: np.ndarray) -> np.ndarray:
        w, n = self.net.w, len(normalized)
        canon = (normalized * w["follower_std"] + w["follower_mean"]).reshape(n, -1, 3)
        frame = CanonicalFrame(np.repeat(self._frame.yaw, n), np.repeat(self._frame.origin, n, 0), self._frame.mode)
        return frame.to_world(canon, self.model.skeleton).astype(np.float32)

    def _step(self) -> np.ndarray:
        """The next follower frame (normalized, D)."""
        cfg, d = self.cfg, self.cfg.pose_dim
        t = self.frames_out - self._first  # the frame made, in the kept buffers
        start = max(0, t + 1 - cfg.receptive)
        windows = leader_windows(self._leader[start:], cfg.lookahead)[:t + 1 - start]  # the frames the context reads
        past = np.zeros((len(windows), d), np.float32)
        on = np.ones((len(windows), 1), np.float32)
        past[1:] = self._past[start:t]
        if start > 0:
            past[0] = self._past[start - 1]
        else:
            on[0] = 0  # the take's first frame: nothing made before it
        label = self._current()
        self._ramped += 1
        h = self.net.context(windows[None], past[None], on[None], label[None], np.ones(1, bool))
        noise = self._noise.standard_normal((1, cfg.chunk * d)).astype(np.float32)
        full = np.linspace(cfg.diffusion_steps - 1, 0, cfg.sample_steps).round().astype(int)
        if len(self._plans) == 0:
            steps, x = full, noise
        else:  # the last plan one frame on (its last frame held), noised to carry_level
            plan = self._plans[-1].reshape(cfg.chunk, d)
            plan = np.concatenate([plan[1:], plan[-1:]]).reshape(1, -1)
            steps = np.linspace(round(cfg.carry_level * (cfg.diffusion_steps - 1)), 0, cfg.sample_steps).round().astype(int)
            a = self._alpha_bar[steps[0]]
            x = (math.sqrt(a) * plan + math.sqrt(1 - a) * noise).astype(np.float32)
        for j, step in enumerate(steps):
            x0 = np.clip(self.net.denoise(x, int(step), h, label[None], np.ones(1, bool)), -CLIP, CLIP)
            if j + 1 < len(steps):
                a, a_next = self._alpha_bar[step], self._alpha_bar[steps[j + 1]]
                eps = (x - math.sqrt(a) * x0) / math.sqrt(1 - a)
                x = (math.sqrt(a_next) * x0 + math.sqrt(1 - a_next) * eps).astype(np.float32)
        self._plans = np.concatenate([self._plans, x0])[-cfg.ensemble:]
        votes = [self._plans[-1 - back, back * d:(back + 1) * d] for back in range(len(self._plans))]
        made = np.mean(votes, 0).astype(np.float32)
        self._past = np.concatenate([self._past, made[None]])
        self.frames_out += 1
        return made


def live_for(model, path: Path) -> LiveNet | None:
    """The live reactor beside a clip model's checkpoint (<stem>_live.safetensors), when its sidecar names this very
    model (its weights' digest) as its teacher; None where there is none (the model then reacts live in windows,
    windows.py). A file there that is no such reactor, or whose weights do not match its config, is refused in one
    line: it was put there to be used."""
    from imm_model.checkpoint import DIGEST, check_state, load_checkpoint, peek_sidecar

    where = Path(path).with_name(Path(path).stem + SUFFIX + ".safetensors")
    if not where.is_file():
        return None
    side = peek_sidecar(where)
    teacher = side.get("teacher")
    if side.get("kind") != KIND or not isinstance(teacher, dict):
        raise CheckpointError(f"{where}: not a live reactor (its sidecar's kind is {side.get('kind')!r})")
    if teacher.get(DIGEST) != model.info.get(DIGEST):
        return None  # another model's: this one reacts live in windows
    arrays, meta = load_checkpoint(where, framework="np")
    try:
        cfg = LiveConfig.from_dict(meta["live_config"])
    except (KeyError, TypeError, ValueError) as err:
        raise CheckpointError(f"{where}: sidecar lacks a valid live_config ({type(err).__name__}: {err})") from None
    if cfg.num_joints != model.skeleton.num_joints or cfg.num_classes != len(model.class_names):
        raise CheckpointError(f"{where}: made for {cfg.num_joints} joints and {cfg.num_classes} classes, the model has "
                              f"{model.skeleton.num_joints} and {len(model.class_names)}")
    weights = {k.removeprefix("live."): np.ascontiguousarray(v, np.float32) for k, v in arrays.items()}
    check_state(weights, expected_shapes(cfg), "live reactor", where)
    return LiveNet(weights, cfg)


def describe(meta: dict[str, Any]) -> str:
    """One line on a live reactor checkpoint, for a message that refuses to load it as a model."""
    teacher = meta.get("teacher", {})
    return f"a live reactor for {teacher.get('path', 'another model')}; load that model, which reacts live with it"
