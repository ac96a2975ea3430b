"""Training the reaction diffusion model (denoiser.py) on one fold: x0-prediction with the label and the
leader dropped independently, the GAN's augmentation, an exponential moving average shipped at the end.

Run directory (one per fold): log.csv, last.safetensors/.json (full state for --resume, every
`checkpoint_every` steps and at the end), final.safetensors/.json (the EMA denoiser: what inference loads).
Randomness is re-derived from (seed, step), so a resumed run continues exactly as an uninterrupted one.
"""

from __future__ import annotations

import copy
import csv
import time
from pathlib import Path

import numpy as np
import torch

import imm_model
from imm_model.checkpoint import load_checkpoint, load_module_state, optimizer_from_tensors, optimizer_to_tensors, prefixed, save_checkpoint
from imm_model.cleanup import follower_bone_lengths
from imm_model.data.dataset import InteractionDataset
from imm_model.data.sequence import MAX_COORDINATE_M
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError, TrainingError
from imm_model.families.base import Trained
from imm_model.families.diffusion.denoiser import ReactionDenoiser, q_sample
from imm_model.families.diffusion.recipes import FAMILY, DiffusionTrainConfig
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance, cosine_alpha_bar
from imm_model.training.data import Augmenter, PaddedData, data_meta, derive_seed, late_starts
from imm_model.training.geometry import GeometricTerms
from imm_model.training.part_mix import mixed_rows, part_rows, upper_shares

LATE_START_FRAMES = 10  # the shortest late start (training/data.py late_starts): SBU's shortest pair
LOG_FIELDS = ("step", "loss", "x0", "velocity", "foot_contact", "torso", "lr", "seconds")


class DiffusionTrainer:
    def __init__(self, cfg: DiffusionTrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path | str,
                 device: torch.device | str = "cpu"):
        self.cfg, self.data, self.subject = cfg, data, subject
        self.device = torch.device(device)
        self.out = Path(out_dir)
        self.train_idx = np.arange(len(data)) if subject is None else loso_fold(data.subject_pairs, subject).train
        self.padded = PaddedData.from_dataset(data)
        self.late = np.zeros(0, np.int64)  # the padded rows of the training pairs' late starts (cfg.late_start_prob)
        if cfg.late_start_prob:
            late = late_starts(data, self.train_idx, LATE_START_FRAMES)
            self.late = np.arange(len(data), len(data) + len(late))
            self.padded = PaddedData.joined(self.padded, PaddedData.from_dataset(late))
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
    def train_step(self) -> dict[str, float]:
        cfg, net = self.cfg, self.net
        gen = torch.Generator().manual_seed(derive_seed(cfg.seed, self.step))
        idx = torch.as_tensor(self.train_idx)[torch.randint(len(self.train_idx), (cfg.batch_size,), generator=gen)]
        if cfg.late_start_prob:  # drawn only then, so that recipes without it keep their random stream
            late = torch.as_tensor(self.late)[torch.randint(len(self.late), (cfg.batch_size,), generator=gen)]
            idx = torch.where(torch.rand(cfg.batch_size, generator=gen) < cfg.late_start_prob, late, idx)
        leader, follower, lengths, actions = self.augment(self.padded, idx, gen)
        b, t, _ = follower.shape
        mask = torch.arange(t)[None] < lengths[:, None]  # (B, T)
        step = torch.randint(self.model_cfg.diffusion_steps, (b,), generator=gen)
        noise = torch.randn(follower.shape, generator=gen)
        label_on = torch.rand(b, generator=gen) >= cfg.label_drop
        leader_on = torch.rand(b, generator=gen) >= cfg.leader_drop
        if self.model_cfg.part_labels:
            follower, label = part_rows(follower, lengths, actions, len(self.data.class_names), cfg.mix_prob, cfg.part_drop,
                                        self.data.skeleton, gen)
        elif cfg.mix_prob:  # drawn only then, so that recipes without it keep their random stream
            follower, label = mixed_rows(follower, lengths, actions, self.upper_shares, cfg.mix_prob, self.data.skeleton, gen)
        else:
            label = torch.nn.functional.one_hot(actions, len(self.data.class_names)).float()
        to = lambda *ts: [x.to(self.device) for x in ts]  # noqa: E731
        leader, follower, mask, step, noise, label_on, leader_on, label = to(leader, follower, mask, step, noise, label_on,
                                                                          leader_on, label)
        m = mask[..., None].float()
        x0 = net.normalize(follower, "follower") * m
        x_t = q_sample(x0, step, noise, self.alpha_bar) * m
        scored, given = m, None  # the frames the loss reads; those given clean
        if cfg.given_prob:  # drawn only then, so that recipes without it keep their random stream
            rows = (torch.rand(b, generator=gen) < cfg.given_prob).to(self.device)
            count = (torch.rand(b, generator=gen).to(self.device) * (lengths.to(self.device) - 1)).long() + 1  # 1 .. T - 1
            given = (rows[:, None] & (torch.arange(t, device=self.device)[None] < count[:, None]))[..., None].float()
            x_t = given * x0 + (1 - given) * x_t
            scored = m * (1 - given)
        leader = net.normalize(leader, "leader") * m
        leader_level = None
        if cfg.leader_noise_prob:  # drawn only then, so that recipes without it keep their random stream
            noised = (torch.rand(b, generator=gen) < cfg.leader_noise_prob).to(self.device) & leader_on
            level = torch.randint(self.model_cfg.diffusion_steps, (b,), generator=gen).to(self.device)
            leader_noise = torch.randn(leader.shape, generator=gen).to(self.device)
            leader = torch.where(noised[:, None, None], q_sample(leader, level, leader_noise, self.alpha_bar) * m, leader)
            leader_level = noised.float() * level
        pred = net(x_t, step, leader, leader_on, label, label_on, mask, leader_level=leader_level) * m
        n = scored.sum() * x0.shape[-1]
        x0_loss = ((pred - x0) ** 2 * scored).sum() / n
        held = pred if given is None else given * x0 + (1 - given) * pred  # what the sampler keeps: the given frames
        mv = scored[:, 1:] * m[:, :-1]  # a given frame's step to the first sampled one counts: it is the seam
        vel_loss = (((held[:, 1:] - held[:, :-1]) - (x0[:, 1:] - x0[:, :-1])) ** 2 * mv).sum() / (mv.sum() * x0.shape[-1])
        loss = x0_loss + cfg.lambda_velocity * vel_loss
        geometric = {"foot_contact": torch.zeros(()), "torso": torch.zeros(())}
        if cfg.lambda_foot_contact or cfg.lambda_torso:
            joints = (b, t, -1, 3)
            geometric = self.geometry(net.denormalize_follower(pred).reshape(joints), follower.reshape(joints), mask)
            loss = loss + cfg.lambda_foot_contact * geometric["foot_contact"] + cfg.lambda_torso * geometric["torso"]
        lr = optimizer_step(cfg, self.opt, net, self.ema, loss, self.step)
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


def learning_rate(cfg: DiffusionTrainConfig, step: int) -> float:
    """cfg.lr after a linear warm-up of cfg.warmup_steps, decayed by a cosine to a tenth at cfg.steps."""
    if step < cfg.warmup_steps:
        return cfg.lr * (step + 1) / cfg.warmup_steps
    progress = (step - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
    return cfg.lr * (0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * min(progress, 1.0))))


def optimizer_step(cfg: DiffusionTrainConfig, opt: torch.optim.Optimizer, net: torch.nn.Module, ema: torch.nn.Module,
                   loss: torch.Tensor, step: int) -> float:
    """One optimizer step on `loss` at step `step`'s learning rate (gradients clipped at norm 1), then the moving
    average `ema` of the weights updated -> the learning rate; a loss that is not finite stops training (one line)."""
    if not torch.isfinite(loss):
        raise TrainingError(f"training stopped: the loss is not finite at step {step}")
    lr = learning_rate(cfg, step)
    for group in opt.param_groups:
        group["lr"] = lr
    opt.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
    opt.step()
    decay = min(cfg.ema_decay, (1 + step) / (10 + step))
    with torch.no_grad():
        for e, p in zip(ema.parameters(), net.parameters(), strict=True):
            e.lerp_(p, 1 - decay)
    return lr


def train(cfg: DiffusionTrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path, device="cpu",
          resume: bool = False, progress: bool = True) -> Trained:
    """One fold's run to the end (continued from last.safetensors with `resume`) -> what it did."""
    trainer = DiffusionTrainer(cfg, data, subject, out_dir, device)
    if resume and (trainer.out / "last.safetensors").exists():
        trainer.resume()
    final = trainer.fit(progress=progress)
    return Trained(f"{cfg.steps} steps -> {final}", {"steps": cfg.steps})
