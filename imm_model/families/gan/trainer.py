"""The training loop for one fold: conditional GAN + L1 + bone + continuity, best-on-validation.

Run directory (one per fold): log.csv, curves.png, best.safetensors/.json (lowest validation AFD),
last.safetensors/.json (full state for --resume, every `checkpoint_every` epochs and at the end).
Randomness is re-derived from (seed, epoch) at every epoch start, so resuming from a saved epoch
continues exactly as an uninterrupted run would, and the same seed gives identical weights on CPU.
"""

from __future__ import annotations

import copy
import csv
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

import imm_model
from imm_model.checkpoint import load_checkpoint, load_module_state, optimizer_from_tensors, optimizer_to_tensors, prefixed, save_checkpoint
from imm_model.cleanup import follower_bone_lengths
from imm_model.data.batching import LengthBucketSampler
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold, validation_split
from imm_model.device import move_module
from imm_model.errors import CheckpointError, TrainingError
from imm_model.families.gan import losses
from imm_model.families.gan.config import model_config_for
from imm_model.families.gan.critic import drawn_labels
from imm_model.families.gan.discriminator import Discriminator
from imm_model.families.gan.energy import class_profiles, energy_loss, limb_speeds, mixed_profile
from imm_model.families.gan.generator import Generator
from imm_model.families.gan.recipes import TrainConfig, same_recipe
from imm_model.families.gan.schedule import adversarial_weight, lr_scale
from imm_model.training.curves import plot_curves
from imm_model.training.data import Augmenter, PaddedData, data_meta, derive_seed
from imm_model.training.label_critic import LabelCritic

LOSS_TERMS = ("l1", "bone", "cont", "adv", "critic", "energy")
LOG_FIELDS = ("epoch", "adv_weight", "lr_scale", *LOSS_TERMS, "d_loss", "d_real_acc", "d_fake_acc", "val_afd_m", "val_l1", "seconds")


def build_models(cfg: TrainConfig, data: InteractionDataset, seed: int) -> tuple[Generator, Discriminator]:
    torch.manual_seed(seed)
    mcfg = model_config_for(data.skeleton, len(data.class_names), **cfg.model)
    return Generator(mcfg), Discriminator(mcfg, spectral_norm=cfg.d_spectral_norm)


def make_optimizer(cfg: TrainConfig, params, lr: float) -> torch.optim.Optimizer:
    # fused / foreach: one kernel over all parameters instead of a Python loop over ~70 small tensors
    # (Adam's step 10 ms -> 1.4 ms for the generator on 2 threads)
    if cfg.optimizer == "adam":
        return torch.optim.Adam(params, lr=lr, betas=(0.5, 0.999), weight_decay=cfg.weight_decay, fused=True)
    if cfg.optimizer == "rmsprop":
        return torch.optim.RMSprop(params, lr=lr, weight_decay=cfg.weight_decay, foreach=True)
    raise ValueError(f"unknown optimizer {cfg.optimizer!r} (adam or rmsprop)")


def check_finite(row: dict, epoch: int, out: Path) -> None:
    """Stop a run whose losses stopped being numbers: its weights are lost, and nothing of the epoch is saved."""
    bad = next((k for k, v in row.items() if k != "epoch" and not math.isfinite(v)), None)
    if bad is not None:
        raise TrainingError(f"{out}: training stopped at epoch {epoch}: {bad} is {row[bad]}, the losses diverged "
                            f"(a lower learning rate may help); nothing of this epoch was saved")


@dataclass
class FoldState:
    epoch: int = 0  # next epoch to run
    best_val: float = math.inf
    best_epoch: int = -1
    history: list[dict] = field(default_factory=list)


class Trainer:
    def __init__(self, cfg: TrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path | str,
                 device: torch.device | str = "cpu"):
        self.cfg, self.data, self.subject = cfg, data, subject
        self.device = torch.device(device)  # batches are drawn and augmented on the CPU, then moved here
        self.out = Path(out_dir)
        if subject is None:  # train on everything (no held-out subject); validation still carved out
            train = np.arange(len(data))
        else:
            train = loso_fold(data.subject_pairs, subject).train
        self.train_idx, self.val_idx = validation_split(train, data.actions, cfg.val_fraction, seed=cfg.seed)
        self.padded = PaddedData.from_dataset(data)
        self.G, self.D = build_models(cfg, data, cfg.seed)
        self._set_normalization()
        self.G, self.D = move_module(self.G, self.device), move_module(self.D, self.device)
        self.G_ema = move_module(copy.deepcopy(self.G).requires_grad_(False), self.device) if cfg.ema_decay > 0 else None
        self.opt_g = make_optimizer(cfg, self.G.parameters(), cfg.lr_g)
        self.opt_d = make_optimizer(cfg, self.D.parameters(), cfg.lr_d)
        swap = torch.tensor([c in cfg.role_swap_classes for c in data.class_names])
        mirror = torch.tensor([c not in cfg.mirror_exclude_classes for c in data.class_names])
        self.augment = Augmenter(data.skeleton, cfg.mirror_prob, cfg.rotate_deg, cfg.role_swap_prob, swap, cfg.time_warp,
                                 cfg.scale_jitter, mirror)
        self.bones = torch.tensor(data.skeleton.bones, dtype=torch.int64, device=self.device)
        self.critic = LabelCritic.for_fold(data, subject, self.device) if cfg.lambda_critic > 0 else None
        skeleton = data.skeleton
        self.energy_reference = skeleton.root_neighbours if cfg.energy_reference == "body" else skeleton.root
        self.profiles = self._class_profiles() if cfg.lambda_energy > 0 else None
        # the fold's training subjects, validation sequences included: the selection run and its refit ship one skeleton
        fold_train = np.concatenate([self.train_idx, self.val_idx])
        self.bone_lengths = follower_bone_lengths([data.follower[data.frames(i)] for i in fold_train], data.skeleton)
        self.state = FoldState()

    # ---- setup ----------------------------------------------------------------------------
    def _set_normalization(self) -> None:
        frames = np.concatenate([np.arange(self.data.frames(i).start, self.data.frames(i).stop) for i in self.train_idx])
        a = self.data.leader[frames].reshape(len(frames), -1)
        b = self.data.follower[frames].reshape(len(frames), -1)
        self.G.set_normalization(a.mean(0), np.maximum(a.std(0), 1e-2), b.mean(0), np.maximum(b.std(0), 1e-2))
        self.D.follower_mean.copy_(self.G.follower_mean)
        self.D.follower_std.copy_(self.G.follower_std)

    def _class_profiles(self) -> torch.Tensor:
        followers = [self.data.follower[self.data.frames(i)] for i in self.train_idx]
        profiles = class_profiles(followers, self.data.actions[self.train_idx], len(self.data.class_names), self.energy_reference)
        return profiles.to(self.device)

    def meta(self, kind: str) -> dict:
        d = self.data
        return {
            "kind": kind,
            "code_version": imm_model.__version__,
            "model_config": self.G.cfg.to_dict(),
            "train_config": self.cfg.to_dict(),
            "d_spectral_norm": self.cfg.d_spectral_norm,
            **data_meta(d, self.subject, self.train_idx),
            # the skeleton the inference clean-up holds every synthesized follower to (cleanup.py)
            "follower_bone_lengths": self.bone_lengths,
            "training": {
                "fold": f"loso-{self.subject}" if self.subject else "all",
                "epoch": self.state.epoch,
                "best_epoch": self.state.best_epoch,
                "best_val_afd_m": None if math.isinf(self.state.best_val) else self.state.best_val,
                "train_sequences": len(self.train_idx),
                "val_sequence_ids": [d.sequence_ids[i] for i in self.val_idx],
                "seed": self.cfg.seed,
            },
        }

    # ---- checkpoints ----------------------------------------------------------------------
    @property
    def shipped_generator(self) -> Generator:
        """The generator that is validated and saved as `generator.*`: the EMA copy if there is one."""
        return self.G_ema if self.G_ema is not None else self.G

    def weights(self) -> dict[str, torch.Tensor]:
        t = {f"generator.{k}": v for k, v in self.shipped_generator.state_dict().items()}
        if self.G_ema is not None:
            t.update({f"generator_train.{k}": v for k, v in self.G.state_dict().items()})
        t.update({f"discriminator.{k}": v for k, v in self.D.state_dict().items()})
        return {k: v.detach().cpu() for k, v in t.items()}

    def save_best(self) -> None:
        save_checkpoint(self.out / "best.safetensors", self.weights(), self.meta("best"))

    def save_last(self) -> None:
        tg, mg = optimizer_to_tensors(self.opt_g, "optim_g")
        td, md = optimizer_to_tensors(self.opt_d, "optim_d")
        meta = self.meta("last") | {"optim_g": mg, "optim_d": md, "history": self.state.history,
                                    "best_val": self.state.best_val if math.isfinite(self.state.best_val) else None}
        save_checkpoint(self.out / "last.safetensors", self.weights() | tg | td, meta)

    def resume(self) -> None:
        path = self.out / "last.safetensors"
        tensors, meta = load_checkpoint(path)
        if not same_recipe(meta.get("train_config") or {}, self.cfg.to_dict()):
            raise CheckpointError(f"{path}: saved with a different training config; resume with the same --config/--seed")
        if self.G_ema is not None:
            load_module_state(self.G_ema, prefixed(tensors, "generator"), "generator", path)
            load_module_state(self.G, prefixed(tensors, "generator_train"), "generator_train", path)
        else:
            load_module_state(self.G, prefixed(tensors, "generator"), "generator", path)
        load_module_state(self.D, prefixed(tensors, "discriminator"), "discriminator", path)
        optimizer_from_tensors(self.opt_g, tensors, meta["optim_g"], "optim_g")
        optimizer_from_tensors(self.opt_d, tensors, meta["optim_d"], "optim_d")
        tr = meta["training"]
        best = meta.get("best_val")
        self.state = FoldState(epoch=tr["epoch"], best_val=math.inf if best is None else best,
                               best_epoch=tr["best_epoch"], history=list(meta["history"]))

    # ---- one epoch ------------------------------------------------------------------------
    def train_epoch(self, epoch: int, lr_multiplier: float | None = None) -> dict:
        """One pass over the training sequences. The learning rates are scaled by `lr_multiplier`, by
        default `lr_scale` of this run's own validation history (a refit passes the selection run's)."""
        cfg = self.cfg
        torch.manual_seed(derive_seed(cfg.seed, epoch, 0))  # dropout
        gen = torch.Generator().manual_seed(derive_seed(cfg.seed, epoch, 1))  # augmentation
        sampler = LengthBucketSampler(self.data.lengths, self.train_idx, cfg.batch_size, seed=cfg.seed)
        sampler.set_epoch(epoch)
        w_adv = adversarial_weight(cfg, epoch)
        use_d = cfg.lambda_adv > 0
        scale = lr_scale(cfg, self.state.history, self.select_from) if lr_multiplier is None else lr_multiplier
        for opt, lr in ((self.opt_g, cfg.lr_g), (self.opt_d, cfg.lr_d)):
            for group in opt.param_groups:
                group["lr"] = lr * scale
        sums = dict.fromkeys((*LOSS_TERMS, "d_loss", "d_real_acc", "d_fake_acc"), 0.0)
        n = n_d = 0
        self.G.train()
        self.D.train()
        for k, batch in enumerate(sampler):
            idx = torch.as_tensor(batch)
            batch_cpu = self.augment(self.padded, idx, gen)
            leader, follower, lengths, actions = (x.to(self.device) for x in batch_cpu)
            mask = torch.arange(leader.shape[1], device=self.device)[None] < lengths[:, None]
            labels = torch.nn.functional.one_hot(actions, len(self.data.class_names)).float()
            fake = self.G(leader, labels, lengths)
            if use_d and k % cfg.d_every == 0:  # discriminator step: G's output detached, D alone is updated
                self.D.requires_grad_(True)
                logits = self.D(torch.cat([follower, fake.detach()]), torch.cat([lengths, lengths]))
                real_logits, fake_logits = logits.chunk(2)
                d_loss = losses.discriminator_loss(real_logits, fake_logits, actions, cfg.label_smoothing, cfg.discriminator)
                self.opt_d.zero_grad(set_to_none=True)
                d_loss.backward()
                self.opt_d.step()
                sums["d_loss"] += float(d_loss.detach())
                sums["d_real_acc"] += float((real_logits.argmax(-1) == actions).float().mean())  # right class
                sums["d_fake_acc"] += float((fake_logits.argmax(-1) == fake_logits.shape[-1] - 1).float().mean())  # "fake"
                n_d += 1
            # generator step: D frozen (no gradient accumulates in it, and it is not stepped)
            g_loss, terms = self._generator_loss(epoch, leader, follower, fake, lengths, actions, mask, gen)
            self.opt_g.zero_grad(set_to_none=True)
            g_loss.backward()
            self.opt_g.step()
            if self.G_ema is not None:
                self._update_ema(epoch * len(sampler) + k)
            for key, value in terms.items():
                sums[key] += value
            n += 1
        d_keys = ("d_loss", "d_real_acc", "d_fake_acc")
        return {k: v / (max(n_d, 1) if k in d_keys else n) for k, v in sums.items()} | {"adv_weight": w_adv, "lr_scale": scale}

    def _generator_loss(self, epoch, leader, follower, fake, lengths, actions, mask, gen) -> tuple[torch.Tensor, dict]:
        """The generator's loss for one batch -> (loss, {term: value} for the log)."""
        cfg = self.cfg
        l1 = losses.masked_l1(fake, follower, mask)
        bone = losses.bone_loss(fake, follower, self.bones, mask)
        cont = losses.continuity_loss(fake, follower, mask)
        l1_term = l1 * (mask.sum() * fake.shape[-1]) if cfg.l1_reduction == "sum" else l1
        g_loss = cfg.lambda_l1 * l1_term + cfg.lambda_bone * bone + cfg.lambda_cont * cont
        terms = {"l1": float(l1.detach()), "bone": float(bone.detach()), "cont": float(cont.detach())}
        w_critic = adversarial_weight(cfg, epoch, cfg.lambda_critic)
        w_energy = adversarial_weight(cfg, epoch, cfg.lambda_energy)
        if w_energy > 0:
            ref = self.energy_reference
            with torch.no_grad():
                target = limb_speeds(follower, lengths, ref)
            energy = energy_loss(fake, target, lengths, ref)
            g_loss = g_loss + w_energy * energy
            terms["energy"] = float(energy.detach())
        if self.critic is not None and w_critic > 0:
            critic_loss, critic_terms = self._critic_loss(epoch, leader, fake, lengths, actions, gen, w_critic)
            g_loss = g_loss + critic_loss
            terms |= critic_terms
        if cfg.lambda_adv > 0 and (w_adv := adversarial_weight(cfg, epoch)) > 0:
            self.D.requires_grad_(False)
            adv = losses.generator_adv_loss(self.D(fake, lengths), actions, cfg.discriminator)
            g_loss = g_loss + w_adv * adv
            terms["adv"] = float(adv.detach())
        return g_loss, terms

    def _critic_loss(self, epoch, leader, fake, lengths, actions, gen, w_critic) -> tuple[torch.Tensor, dict]:
        """The label critic's terms: the true-label follower and one for a drawn label; the drawn one has no ground
        truth, so only the critic and motion-energy terms apply to it."""
        cfg = self.cfg
        c = len(self.data.class_names)
        labels, target = (x.to(self.device) for x in drawn_labels(actions.cpu(), c, cfg.critic_mix_prob, gen))
        other = self.G(leader, labels, lengths)
        critic = (self.critic.loss(fake, lengths, torch.nn.functional.one_hot(actions, c).float())
                  + self.critic.loss(other, lengths, target))
        loss, terms = w_critic * critic, {"critic": float(critic.detach())}
        if (w_energy := adversarial_weight(cfg, epoch, cfg.lambda_energy)) > 0:
            loss = loss + w_energy * energy_loss(other, mixed_profile(labels, self.profiles), lengths, self.energy_reference)
        return loss, terms

    @torch.no_grad()
    def _update_ema(self, step: int) -> None:
        decay = min(self.cfg.ema_decay, (1 + step) / (10 + step))  # warm-up: early weights fade quickly
        torch._foreach_lerp_(list(self.G_ema.parameters()), list(self.G.parameters()), 1.0 - decay)

    @torch.inference_mode()
    def validate(self) -> dict:
        G = self.shipped_generator.eval()
        idx = torch.as_tensor(self.val_idx)
        leader, follower, lengths, actions = (x.to(self.device) for x in self.padded.batch(idx))
        mask = torch.arange(leader.shape[1], device=self.device)[None] < lengths[:, None]
        labels = torch.nn.functional.one_hot(actions, len(self.data.class_names)).float()
        pred = G(leader, labels, lengths)
        return {"val_afd_m": float(losses.afd_metres(pred, follower, mask).mean()),
                "val_l1": float(losses.masked_l1(pred, follower, mask))}

    # ---- the loop -------------------------------------------------------------------------
    def fit(self, epochs: int | None = None, progress: bool = True) -> FoldState:
        from tqdm import tqdm

        cfg = self.cfg
        total = epochs if epochs is not None else cfg.epochs
        self.out.mkdir(parents=True, exist_ok=True)
        self._write_log_header()
        desc = f"train {self.subject or 'all'}"
        select_from = min(self.select_from, total - 1)  # a run shorter than the warm-up still keeps a best
        bar = tqdm(range(self.state.epoch, total), desc=desc, disable=not progress, leave=False, dynamic_ncols=True)
        last_saved = time.monotonic()
        for epoch in bar:
            t0 = time.perf_counter()
            row = {"epoch": epoch} | self.train_epoch(epoch) | self.validate()
            check_finite(row, epoch, self.out)
            row["seconds"] = time.perf_counter() - t0
            self.state.history.append(row)
            self.state.epoch = epoch + 1
            self._append_log(row)
            if epoch >= select_from and row["val_afd_m"] < self.state.best_val:
                self.state.best_val, self.state.best_epoch = row["val_afd_m"], epoch
                self.save_best()
            bar.set_postfix(l1=f"{row['l1']:.4f}", val=f"{row['val_afd_m']:.4f}", best=f"{self.state.best_val:.4f}@{self.state.best_epoch}")
            stop = (cfg.patience > 0 and epoch + 1 >= max(cfg.min_epochs, select_from + cfg.patience)
                    and epoch - max(self.state.best_epoch, select_from) >= cfg.patience)
            due = (epoch + 1) % cfg.checkpoint_every == 0 or time.monotonic() - last_saved > 60 * cfg.checkpoint_minutes
            if due or stop or epoch + 1 == total:
                self.save_last()
                self.plot()
                last_saved = time.monotonic()
            if stop:
                break
        return self.state

    @property
    def select_from(self) -> int:
        cfg = self.cfg
        return cfg.select_from_epoch if cfg.select_from_epoch >= 0 else cfg.adv_warmup_epochs + cfg.adv_ramp_epochs

    def _write_log_header(self) -> None:
        path = self.out / "log.csv"
        with path.open("w", newline="") as f:  # rewritten from history, so a resumed log has no duplicates
            w = csv.DictWriter(f, fieldnames=LOG_FIELDS, extrasaction="ignore")
            w.writeheader()
            w.writerows(self.state.history)

    def _append_log(self, row: dict) -> None:
        with (self.out / "log.csv").open("a", newline="") as f:
            csv.DictWriter(f, fieldnames=LOG_FIELDS, extrasaction="ignore").writerow(row)

    def plot(self) -> None:
        plot_curves(self.state.history, self.state.best_epoch, self.subject, self.out / "curves.png")
