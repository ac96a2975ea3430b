"""Training the reaction diffusion model (model/diffusion.py) on one fold: x0-prediction with the label and the
leader dropped independently, the GAN's augmentation, an exponential moving average shipped at the end.

Run directory (one per fold): log.csv, last.safetensors/.json (full state for --resume, every
`checkpoint_every` steps and at the end), final.safetensors/.json (the EMA denoiser: what inference loads).
Randomness is re-derived from (seed, step), so a resumed run continues exactly as an uninterrupted one.
"""

from __future__ import annotations

import copy
import csv
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

import imm_model
from imm_model.checkpoint import load_checkpoint, load_module_state, optimizer_from_tensors, optimizer_to_tensors, prefixed, save_checkpoint
from imm_model.cleanup import follower_bone_lengths
from imm_model.data.dataset import InteractionDataset
from imm_model.data.sequence import MAX_COORDINATE_M
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError, TrainingError
from imm_model.model.diffusion import ReactionDenoiser, q_sample
from imm_model.model.diffusion_sampler import DiffusionConfig, Guidance, cosine_alpha_bar
from imm_model.training.data import Augmenter, PaddedData, data_meta
from imm_model.training.geometry import GeometricTerms
from imm_model.training.part_mix import mixed_rows, upper_shares
from imm_model.training.trainer import derive_seed
from imm_model.typed_config import FieldsOf, Interval, ListOf, Name, OneOf, checked_kwargs, param, validate

FAMILY = "diffusion"
LOG_FIELDS = ("step", "loss", "x0", "velocity", "foot_contact", "torso", "lr", "seconds")


FRACTION = Interval(float, 0, 1)
BELOW_1 = Interval(float, 0, 1, closed="left")


@dataclass(frozen=True)
class DiffusionTrainConfig:
    name: str = param("imm-diffusion", Name())  # the recipe's name (run folders and reports carry it)
    family: str = param(FAMILY, OneOf((FAMILY,)))  # tells `imm train` which trainer runs the recipe
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
    checkpoint_every: int = param(1000, Interval(int, 1, None))  # steps between resumable checkpoints
    seed: int = param(0, Interval(int, 0, 2**31 - 1))  # initial weights, batches, noise and augmentation

    RULES: ClassVar = (("leader_noise_prob", lambda c: c.leader_noise_prob == 0 or c.model.get("leader_noise") is True,
                        "0 unless model.leader_noise is true"),
             ("mix_prob", lambda c: c.mix_prob == 0 or c.model.get("pair_terms") is True, "0 unless model.pair_terms is true"))

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
# through noise at 0.3 of the schedule (the spread) but at the last step (docs/experiments/reaction-diffusion.md,
# diffusion-geometric-terms.md and diffusion-leader-noise.md have the variants measured).
IMM_DIFFUSION = DiffusionTrainConfig(
    model=dict(width=128, layers=4, heads=4, ff_mult=2, dropout=0.1, leader_noise=True),
    guidance=dict(label_scale=3.0, leader_scale=1.0, sample_steps=7, guided_below=0.3, leader_noise=0.3),
    lambda_foot_contact=20.0,
    lambda_torso=1.0,
    leader_noise_prob=0.5,
)

# The same with a share of its training rows made two-class composites by body parts, and the sampler's pair terms
# that read them: mixes read as mixed more often, at a cost in limb speed (docs/experiments/part-mix-training.md).
IMM_DIFFUSION_MIXED = replace(IMM_DIFFUSION, name="imm-diffusion-mixed", model=IMM_DIFFUSION.model | {"pair_terms": True},
                              mix_prob=0.3)

NAMED: dict[str, DiffusionTrainConfig] = {"imm-diffusion": IMM_DIFFUSION, "imm-diffusion-mixed": IMM_DIFFUSION_MIXED}


class DiffusionTrainer:
    def __init__(self, cfg: DiffusionTrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path | str,
                 device: torch.device | str = "cpu"):
        self.cfg, self.data, self.subject = cfg, data, subject
        self.device = torch.device(device)
        self.out = Path(out_dir)
        self.train_idx = np.arange(len(data)) if subject is None else loso_fold(data.subject_pairs, subject).train
        self.padded = PaddedData.from_dataset(data)
        torch.manual_seed(cfg.seed)
        self.model_cfg = DiffusionConfig.from_dict(dict(cfg.model) | {"num_joints": data.skeleton.num_joints,
                                                                       "num_classes": len(data.class_names)})
        self.guidance = Guidance.from_dict(dict(cfg.guidance))
        self.net = ReactionDenoiser(self.model_cfg)
        frames = np.concatenate([np.arange(data.frames(i).start, data.frames(i).stop) for i in self.train_idx])
        leaders, followers = (np.asarray(x[frames], np.float64).reshape(len(frames), -1) for x in (data.leader, data.follower))
        largest = max(np.abs(leaders).max(initial=0), np.abs(followers).max(initial=0))
        if not largest <= MAX_COORDINATE_M:  # also NaN: such a pose would swamp the normalization and train on noise
            raise TrainingError(f"training stopped before step 0: a training joint {largest:.3g} m from the origin "
                                f"(positions within {MAX_COORDINATE_M:g} m)")
        self.net.set_normalization(leaders, followers)
        self.net = self.net.to(self.device)
        self.ema = copy.deepcopy(self.net).requires_grad_(False).eval()
        self.opt = torch.optim.AdamW(self.net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        swap = torch.tensor([c in cfg.role_swap_classes for c in data.class_names])
        mirror = torch.tensor([c not in cfg.mirror_exclude_classes for c in data.class_names])
        self.augment = Augmenter(data.skeleton, cfg.mirror_prob, cfg.rotate_deg, cfg.role_swap_prob, swap, cfg.time_warp,
                                 cfg.scale_jitter, mirror)
        self.alpha_bar = torch.as_tensor(cosine_alpha_bar(self.model_cfg.diffusion_steps), dtype=torch.float32, device=self.device)
        self.geometry = GeometricTerms(data.skeleton)
        self.upper_shares = upper_shares([data.follower[data.frames(i)] for i in self.train_idx], data.actions[self.train_idx],
                                         len(data.class_names), data.skeleton)
        self.bone_lengths = follower_bone_lengths([data.follower[data.frames(i)] for i in self.train_idx], data.skeleton)
        self.step = 0

    # ---- one step -------------------------------------------------------------------------
    def lr_at(self, step: int) -> float:
        cfg = self.cfg
        if step < cfg.warmup_steps:
            return cfg.lr * (step + 1) / cfg.warmup_steps
        progress = (step - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
        return cfg.lr * (0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * min(progress, 1.0))))

    def train_step(self) -> dict[str, float]:
        cfg, net = self.cfg, self.net
        gen = torch.Generator().manual_seed(derive_seed(cfg.seed, self.step))
        idx = torch.as_tensor(self.train_idx)[torch.randint(len(self.train_idx), (cfg.batch_size,), generator=gen)]
        leader, follower, lengths, actions = self.augment(self.padded, idx, gen)
        b, t, _ = follower.shape
        mask = torch.arange(t)[None] < lengths[:, None]  # (B, T)
        step = torch.randint(self.model_cfg.diffusion_steps, (b,), generator=gen)
        noise = torch.randn(follower.shape, generator=gen)
        label_on = torch.rand(b, generator=gen) >= cfg.label_drop
        leader_on = torch.rand(b, generator=gen) >= cfg.leader_drop
        if cfg.mix_prob:  # drawn only then, so that recipes without it keep their random stream
            follower, label = mixed_rows(follower, lengths, actions, self.upper_shares, cfg.mix_prob, self.data.skeleton, gen)
        else:
            label = torch.nn.functional.one_hot(actions, len(self.data.class_names)).float()
        to = lambda *ts: [x.to(self.device) for x in ts]  # noqa: E731
        leader, follower, mask, step, noise, label_on, leader_on, label = to(leader, follower, mask, step, noise, label_on,
                                                                          leader_on, label)
        m = mask[..., None].float()
        x0 = net.normalize(follower, "follower") * m
        x_t = q_sample(x0, step, noise, self.alpha_bar) * m
        leader = net.normalize(leader, "leader") * m
        leader_level = None
        if cfg.leader_noise_prob:  # drawn only then, so that recipes without it keep their random stream
            noised = (torch.rand(b, generator=gen) < cfg.leader_noise_prob).to(self.device) & leader_on
            level = torch.randint(self.model_cfg.diffusion_steps, (b,), generator=gen).to(self.device)
            leader_noise = torch.randn(leader.shape, generator=gen).to(self.device)
            leader = torch.where(noised[:, None, None], q_sample(leader, level, leader_noise, self.alpha_bar) * m, leader)
            leader_level = noised.float() * level
        pred = net(x_t, step, leader, leader_on, label, label_on, mask, leader_level=leader_level) * m
        n = m.sum() * x0.shape[-1]
        x0_loss = ((pred - x0) ** 2).sum() / n
        mv = m[:, 1:] * m[:, :-1]
        vel_loss = (((pred[:, 1:] - pred[:, :-1]) - (x0[:, 1:] - x0[:, :-1])) ** 2 * mv).sum() / (mv.sum() * x0.shape[-1])
        loss = x0_loss + cfg.lambda_velocity * vel_loss
        geometric = {"foot_contact": torch.zeros(()), "torso": torch.zeros(())}
        if cfg.lambda_foot_contact or cfg.lambda_torso:
            joints = (b, t, -1, 3)
            geometric = self.geometry(net.denormalize_follower(pred).reshape(joints), follower.reshape(joints), mask)
            loss = loss + cfg.lambda_foot_contact * geometric["foot_contact"] + cfg.lambda_torso * geometric["torso"]
        if not torch.isfinite(loss):
            raise TrainingError(f"training stopped: the loss is not finite at step {self.step}")
        lr = self.lr_at(self.step)
        for group in self.opt.param_groups:
            group["lr"] = lr
        self.opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        self.opt.step()
        decay = min(cfg.ema_decay, (1 + self.step) / (10 + self.step))
        with torch.no_grad():
            for e, p in zip(self.ema.parameters(), net.parameters(), strict=True):
                e.lerp_(p, 1 - decay)
        self.step += 1
        return {"loss": loss.item(), "x0": x0_loss.item(), "velocity": vel_loss.item(),
                **{k: v.item() for k, v in geometric.items()}, "lr": lr}

    # ---- the run --------------------------------------------------------------------------
    def fit(self, progress: bool = True) -> Path:
        from tqdm import tqdm

        self.out.mkdir(parents=True, exist_ok=True)
        log = self.out / "log.csv"
        new_log = not log.exists() or self.step == 0
        t0 = time.time()
        totals: dict[str, float] = {}
        count = 0
        with open(log, "w" if new_log else "a", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=LOG_FIELDS)
            if new_log:
                writer.writeheader()
            bar = tqdm(total=self.cfg.steps, initial=self.step, disable=not progress, desc=f"fold {self.subject or 'none'}",
                       unit="step", mininterval=2.0)
            while self.step < self.cfg.steps:
                self.net.train()
                parts = self.train_step()
                for k, v in parts.items():
                    totals[k] = totals.get(k, 0.0) + v
                count += 1
                bar.update(1)
                if self.step % 100 == 0 or self.step == self.cfg.steps:
                    row = {k: totals[k] / count for k in ("loss", "x0", "velocity", "foot_contact", "torso")} | {"lr": parts["lr"]}
                    writer.writerow({"step": self.step, **{k: f"{v:.5g}" for k, v in row.items()}, "seconds": f"{time.time() - t0:.1f}"})
                    fh.flush()
                    bar.set_postfix(loss=f"{row['loss']:.4f}")
                    totals, count = {}, 0
                if self.step % self.cfg.checkpoint_every == 0 or self.step == self.cfg.steps:
                    self.save_last()
            bar.close()
        final = self.out / "final.safetensors"
        save_checkpoint(final, {f"denoiser.{k}": v.detach().cpu() for k, v in self.ema.state_dict().items()}, self.meta("final"))
        return final

    # ---- checkpoints ----------------------------------------------------------------------
    def meta(self, kind: str) -> dict:
        d = self.data
        return {
            "kind": kind,
            "family": FAMILY,
            "code_version": imm_model.__version__,
            "model_config": self.model_cfg.to_dict(),
            "guidance": self.guidance.to_dict(),
            "train_config": self.cfg.to_dict(),
            **data_meta(d, self.subject, self.train_idx),
            "follower_bone_lengths": self.bone_lengths,
            "training": {"fold": f"loso-{self.subject}" if self.subject else "all", "step": self.step,
                         "train_sequences": len(self.train_idx), "seed": self.cfg.seed},
        }

    def save_last(self) -> None:
        tensors, optim = optimizer_to_tensors(self.opt, "optim")
        tensors |= {f"denoiser.{k}": v.detach().cpu() for k, v in self.ema.state_dict().items()}
        tensors |= {f"denoiser_train.{k}": v.detach().cpu() for k, v in self.net.state_dict().items()}
        save_checkpoint(self.out / "last.safetensors", tensors, self.meta("last") | {"optim": optim})

    def resume(self) -> None:
        path = self.out / "last.safetensors"
        tensors, meta = load_checkpoint(path)
        if meta.get("train_config", {}) | {"steps": self.cfg.steps} != self.cfg.to_dict():
            raise CheckpointError(f"{path}: trained with a different config; resume with the same --config/--seed")
        load_module_state(self.net, prefixed(tensors, "denoiser_train"), "denoiser", path)
        load_module_state(self.ema, prefixed(tensors, "denoiser"), "denoiser", path)
        optimizer_from_tensors(self.opt, tensors, meta["optim"], "optim")
        self.step = int(meta["training"]["step"])


def _read_recipe_file(path: Path) -> dict | None:
    import json

    from imm_model.errors import IMMError
    from imm_model.inputs import MAX_SETTINGS_BYTES, read_input_text

    try:
        d = json.loads(read_input_text(path, "config", MAX_SETTINGS_BYTES))
    except (IMMError, json.JSONDecodeError, RecursionError):
        return None  # the GAN's config loader reports what is wrong with the file
    return d if isinstance(d, dict) else None


def _base_name(d: dict, pop: bool = False) -> str | None:
    """A recipe file's "base" recipe name (default imm-diffusion); None when it is not a name (a list, an object)."""
    base = d.pop("base", "imm-diffusion") if pop else d.get("base")
    return base if isinstance(base, str) else None


def diffusion_recipe(name_or_path: str) -> bool:
    """Whether `imm train --config` names a diffusion recipe (a name here, or a JSON file whose base is one)."""
    if name_or_path in NAMED:
        return True
    path = Path(name_or_path)
    d = _read_recipe_file(path) if path.suffix == ".json" and path.is_file() else None
    return bool(d) and (_base_name(d) in NAMED or d.get("family") == FAMILY)


def load_config(name_or_path: str, **overrides: Any) -> DiffusionTrainConfig:
    """A named diffusion recipe or a JSON file {"base": "imm-diffusion", ...overrides}."""
    if name_or_path in NAMED:
        cfg = NAMED[name_or_path]
    else:
        d = _read_recipe_file(Path(name_or_path))
        if d is None:
            raise ValueError(f"{name_or_path}: not a readable JSON object")
        base = NAMED.get(_base_name(d, pop=True))
        if base is None:
            raise ValueError(f"{name_or_path}: unknown base config (one of {sorted(NAMED)})")
        for key in ("model", "guidance"):
            if not isinstance(d.get(key, {}), dict):
                raise ValueError(f"{name_or_path}: {key} must be a JSON object")
        merged = base.to_dict() | d
        merged["model"] = base.model | d.get("model", {})
        merged["guidance"] = base.guidance | d.get("guidance", {})
        merged.setdefault("name", Path(name_or_path).stem)
        cfg = DiffusionTrainConfig.from_dict(merged)
    return replace(cfg, **{k: v for k, v in overrides.items() if v is not None})
