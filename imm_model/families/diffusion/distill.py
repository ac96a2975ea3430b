"""A few-step student distilled from the diffusion model's sampler: the same network, started from the teacher's
weights, that reads the signed label (times the scale) as one input and lands in a few DDIM steps where the teacher's
composing sampler lands in its many.

The teacher composes the label term by term (sampler.py): 1 + classes network calls at each of its steps. The student
(DiffusionConfig.composed_label) is asked once per step whatever the label, the guidance distilled into the network as
Meng et al. (CVPR 2023) distil classifier-free guidance, and the steps cut by regressing the teacher's reaction from
the same starting noise and the same noised leader (Luhman & Luhman 2021), through the student's own DDIM steps.
Composition survives as far as the teacher's pool teaches it: reactions to the training leaders for labels drawn as
the front ends ask for them (`pool_labels`), at spread levels and seeds drawn alike. A label per body part needs no
teaching: the sampler samples each part as a whole-body label and joins the reactions (Guidance.join_outputs).

A regressed student averages what it cannot resolve, and an averaged reaction reads less as any class. Beside the
regression: the fold's frozen follower classifier reads each reaction against the classes its row performs
(`lambda_label`, what the recipe weighs), and optionally an adversarial critic tells the student's reaction from the
teacher's (`ReactionCritic`, `lambda_adversarial`, an experiment: docs/experiments/sampler-student-critics.md).

Run directory: log.csv and final.safetensors/.json (the EMA student), like the trainer's.
"""

from __future__ import annotations

import copy
import csv
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

import imm_model
from imm_model.checkpoint import DIGEST, load_checkpoint, save_checkpoint
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError, TrainingError
from imm_model.families.base import Trained
from imm_model.families.diffusion.denoiser import ReactionDenoiser
from imm_model.families.diffusion.model import DiffusionReactionModel
from imm_model.families.diffusion.recipes import FAMILY, DiffusionTrainConfig
from imm_model.families.diffusion.sampler import Guidance, cosine_alpha_bar, initial_noise, leader_noise, schedule_step
from imm_model.families.diffusion.trainer import optimizer_step
from imm_model.families.diffusion.windows import BLEND, CONTINUE_LEVEL, LOOKAHEAD, STRIDE, TAKE_LOOKAHEAD, WINDOW
from imm_model.training.data import Augmenter, PaddedData, data_meta, derive_seed
from imm_model.training.label_critic import LabelCritic

LOG_FIELDS = ("step", "loss", "x0", "velocity", "adversarial", "critic", "label", "lr", "seconds")
CRITIC_WIDTH = 128  # the critic's channels
CRITIC_LR = 1e-3  # the critic's Adam learning rate (betas 0.5, 0.999: the usual GAN setting)
POOL_BATCH = 64  # teacher reactions drawn per sampler call
DEFAULT_SPREAD_SHARE = 0.5  # pool batches at the teacher's own spread; the rest at a uniform spread in 0..1

# The labels a pool row asks for, with their shares: what the front ends ask for (the studio's sliders reach 2)
LABEL_KINDS = (
    ("one class at +1", 0.35),
    ("one class at a value in -1..2", 0.15),
    ("two classes performed, each 0.3..1.5", 0.2),
    ("one class performed, another avoided", 0.1),
    ("three classes at values in -1..1.5", 0.15),
    ("no label", 0.05),
)


def window_bounds(rng: np.random.Generator, length: int) -> tuple[int, int, int]:
    """A window of a long take inside a clip of `length` frames, as windows.py cuts them -> (start, end, given): it ends
    at a frame drawn uniformly from the 8th on, reads up to WINDOW frames back, and is given the follower frames before
    the ones it makes, as a long take's window (BLEND + STRIDE + TAKE_LOOKAHEAD made) or, as often, the live reactor's
    (LOOKAHEAD + 1 made) is; at least one frame given, at least one made."""
    end = int(rng.integers(min(8, length), length + 1))
    start = max(0, end - WINDOW)
    made = BLEND + STRIDE + TAKE_LOOKAHEAD if rng.random() < 0.5 else LOOKAHEAD + 1
    return start, end, int(np.clip(end - start - made, 1, end - start - 1))


def pool_labels(rng: np.random.Generator, n: int, classes: int) -> np.ndarray:
    """(n, classes) float32 signed labels, each row of a kind of LABEL_KINDS drawn by its share."""
    kinds = rng.choice(len(LABEL_KINDS), n, p=[share for _, share in LABEL_KINDS])
    labels = np.zeros((n, classes), np.float32)
    for row, kind in enumerate(kinds):
        picked = rng.permutation(classes)
        if kind == 0:
            labels[row, picked[0]] = 1.0
        elif kind == 1:
            labels[row, picked[0]] = rng.uniform(-1, 2)
        elif kind == 2:
            labels[row, picked[:2]] = rng.uniform(0.3, 1.5, 2)
        elif kind == 3:
            labels[row, picked[:2]] = (1.0, -1.0)
        elif kind == 4:
            labels[row, picked[:3]] = rng.uniform(-1, 1.5, 3)
    return labels


class ReactionCritic(nn.Module):
    """Tells the teacher's reaction from the student's, given the leader and the signed label: dilated temporal
    convolutions over each frame's leader pose, follower pose and follower velocity (normalized), pooled over the valid
    frames, then a linear score plus the projection of the label onto the pooled features (Miyato & Koyama 2018), so a
    reaction is judged as a reaction to this leader for this label. Spectrally normalized: its scores stay bounded.
    Why hand-written: the GAN family's discriminator reads the follower alone and scores one-hot classes."""

    def __init__(self, pose_dim: int, classes: int, width: int = CRITIC_WIDTH):
        super().__init__()
        sn = nn.utils.parametrizations.spectral_norm
        self.convs = nn.ModuleList([sn(nn.Conv1d(3 * pose_dim, width, 5, padding=2))] +
                                   [sn(nn.Conv1d(width, width, 5, padding=2 * d, dilation=d)) for d in (2, 4)])
        self.score = sn(nn.Linear(width, 1))
        self.label = sn(nn.Linear(classes, width, bias=False))

    def forward(self, leader: torch.Tensor, follower: torch.Tensor, label: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """leader, follower (B, T, D) normalized, label (B, C), mask (B, T) -> scores (B,)."""
        velocity = torch.cat([torch.zeros_like(follower[:, :1]), follower[:, 1:] - follower[:, :-1]], 1)
        m = mask[:, None].float()
        h = torch.cat([leader, follower, velocity], -1).transpose(1, 2) * m
        for conv in self.convs:
            h = F.leaky_relu(conv(h), 0.2) * m
        pooled = h.sum(-1) / m.sum(-1)
        return self.score(pooled)[:, 0] + (self.label(label) * pooled).sum(-1)


class StudentTrainer:
    def __init__(self, cfg: DiffusionTrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path | str,
                 device: torch.device | str = "cpu"):
        self.cfg, self.data, self.subject = cfg, data, subject
        self.device = torch.device(device)
        self.out = Path(out_dir)
        self.teacher_path = Path(cfg.teacher.format(fold=subject or "all"))
        if not self.teacher_path.is_file():
            raise CheckpointError(f"{self.teacher_path}: the student's teacher not found (train it first: imm train "
                                  f"--config imm-diffusion --fold {subject or 'none'} --out {self.teacher_path.parents[1]})")
        arrays, meta = load_checkpoint(self.teacher_path, framework="np")
        if meta.get("family") != FAMILY:
            raise CheckpointError(f"{self.teacher_path}: not a diffusion model, which a teacher must be")
        teacher = DiffusionReactionModel.from_checkpoint(arrays, meta, self.teacher_path)
        if teacher.config.composed_label or teacher.config.part_labels:
            raise CheckpointError(f"{self.teacher_path}: a teacher reads a label per class, not {teacher.title}'s")
        if teacher.held_out_subject != subject:
            raise CheckpointError(f"{self.teacher_path}: the teacher held out {teacher.held_out_subject}, the student "
                                  f"{subject}: it would teach what the fold keeps back")
        self.teacher = teacher
        self.train_idx = np.arange(len(data)) if subject is None else loso_fold(data.subject_pairs, subject).train
        self.model_cfg = replace(teacher.config, composed_label=True)
        self.guidance = Guidance.from_dict(teacher.guidance.to_dict() | dict(cfg.guidance))
        self.net = ReactionDenoiser(self.model_cfg)
        self.net.load_state_dict({k: torch.as_tensor(v) for k, v in teacher.weights.items()})
        self.net = self.net.to(self.device)
        self.ema = copy.deepcopy(self.net).requires_grad_(False).eval()
        self.opt = torch.optim.AdamW(self.net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        teacher_cfg = DiffusionTrainConfig.from_dict(teacher.info["train_config"])  # the leaders its own training saw
        swap = torch.tensor([c in teacher_cfg.role_swap_classes for c in data.class_names])
        mirror = torch.tensor([c not in teacher_cfg.mirror_exclude_classes for c in data.class_names])
        self.augment = Augmenter(data.skeleton, teacher_cfg.mirror_prob, teacher_cfg.rotate_deg, teacher_cfg.role_swap_prob,
                                 swap, teacher_cfg.time_warp, teacher_cfg.scale_jitter, mirror)
        self.padded = PaddedData.from_dataset(data)
        self.alpha_bar = torch.as_tensor(cosine_alpha_bar(self.model_cfg.diffusion_steps), dtype=torch.float32)
        self.critic = None
        if cfg.lambda_adversarial:
            self.critic = ReactionCritic(self.model_cfg.pose_dim, len(data.class_names)).to(self.device)
            self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=CRITIC_LR, betas=(0.5, 0.999))
        self.label_critic = None
        if cfg.lambda_label:  # it reads metres: the student's normalized reactions are scaled back
            self.label_critic = LabelCritic.for_fold(data, subject, self.device)
            self.follower_scale = {k: torch.as_tensor(teacher.weights[k], device=self.device) for k in ("follower_mean", "follower_std")}
        self.step = 0
        self.pool: dict[str, torch.Tensor] = {}  # the teacher's reactions (`draw_pool`), normalized
        self.seeds = np.zeros(0, np.int64)  # the pool rows' sampler seeds

    # ---- the teacher's reactions ----------------------------------------------------------------
    def draw_pool(self, progress: bool = True) -> None:
        """cfg.pool_rows teacher reactions: augmented training leaders, labels (`pool_labels`), seeds and spreads,
        each row's starting noise and leader noise as the sampler draws them from its seed; and, for a share
        (cfg.window_share) of them, a window of it that continues the teacher's reaction (`window_bounds`), sampled as
        windows.py samples one (its slices of the row's noise, the given frames noised to CONTINUE_LEVEL), as one more
        row. All normalized."""
        from tqdm import tqdm

        cfg, teacher, d = self.cfg, self.teacher, self.model_cfg.pose_dim
        rng = np.random.default_rng((cfg.seed, 1))
        gen = torch.Generator().manual_seed(derive_seed(cfg.seed, 10**9))
        n = cfg.pool_rows
        labels = pool_labels(rng, n, len(self.data.class_names))
        # rows asking for the same classes side by side: the teacher composes one term per class any row of a batch weighs
        labels = labels[np.argsort((labels != 0) @ (1 << np.arange(labels.shape[1])), kind="stable")]
        seeds = rng.integers(0, 2**31 - 1, n)
        spread_trained = teacher.config.leader_noise
        base = teacher.guidance
        rows_made: list[dict] = []  # one per pool row: canonical (T, D) arrays and its scalars
        windows: list[dict] = []
        for start in tqdm(range(0, n, POOL_BATCH), disable=not progress, desc="teacher reactions", unit="batch"):
            rows = np.arange(start, min(n, start + POOL_BATCH))
            idx = torch.as_tensor(self.train_idx)[torch.randint(len(self.train_idx), (len(rows),), generator=gen)]
            leader, _, length, _ = self.augment(self.padded, idx, gen)
            spread = 0.0
            if spread_trained:
                spread = base.leader_noise if rng.random() < DEFAULT_SPREAD_SHARE else float(rng.uniform(0, 1))
            teacher.guidance = replace(base, leader_noise=spread)
            level = schedule_step(spread, self.model_cfg.diffusion_steps)
            canon = [leader[k, : int(length[k])].numpy().reshape(int(length[k]), -1, 3) for k in range(len(rows))]
            followers = teacher._sample(canon, labels[rows], seeds[rows].tolist())
            batch = [{"leader": canon[k].reshape(len(canon[k]), d), "target": followers[k].reshape(len(canon[k]), d),
                      "noise": initial_noise(int(seeds[row]), len(canon[k]), d),
                      "leader_noise": leader_noise(int(seeds[row]), len(canon[k]), d),
                      "label": labels[row], "seed": seeds[row], "level": level, "known": 0} for k, row in enumerate(rows)]
            rows_made += batch
            cut = []  # this batch's windows
            for k, row in enumerate(batch):
                if rng.random() < cfg.window_share:
                    a, b, known = window_bounds(rng, len(row["leader"]))
                    cut.append({key: row[key][a:b] for key in ("leader", "noise", "leader_noise")}
                               | {"given": row["target"][a:b], "label": row["label"], "seed": row["seed"],
                                  "level": level, "known": known, "source": int(rows[k]), "offset": a})
            for w, made in zip(cut, self.continue_windows(cut, spread), strict=True):
                w["target"] = made
            windows += cut
        teacher.guidance = base
        rows_made += windows
        self.seeds = np.array([row["seed"] for row in rows_made])
        w = teacher.weights
        lengths = np.array([len(row["leader"]) for row in rows_made])

        def padded(key: str, mean=0.0, std=1.0) -> torch.Tensor:
            out = np.zeros((len(rows_made), int(lengths.max()), d), np.float32)
            for i, row in enumerate(rows_made):
                if key in row:
                    out[i, : lengths[i]] = (row[key] - mean) / std
            return torch.as_tensor(out)

        target = padded("target", w["follower_mean"], w["follower_std"])
        if not torch.isfinite(target).all():
            raise TrainingError(f"{self.teacher_path}: the teacher's reactions are not finite")
        known = np.array([row["known"] for row in rows_made])
        steps_total = self.model_cfg.diffusion_steps
        self.pool = {"leader": padded("leader", w["leader_mean"], w["leader_std"]), "target": target,
                     "given": padded("given", w["follower_mean"], w["follower_std"]),
                     "noise": padded("noise"), "leader_noise": padded("leader_noise"), "length": torch.as_tensor(lengths),
                     "level": torch.as_tensor(np.array([row["level"] for row in rows_made])),
                     "label": torch.as_tensor(np.stack([row["label"] for row in rows_made])),
                     "known": torch.as_tensor(known),
                     # a window's clip row and the frame it starts at in it (a clip: -1, 0): `refresh_windows`
                     "source": torch.as_tensor(np.array([row.get("source", -1) for row in rows_made])),
                     "offset": torch.as_tensor(np.array([row.get("offset", 0) for row in rows_made])),
                     # the step each row's sampler starts at: a window's from its given frames, a clip's as the guidance's
                     "start": torch.as_tensor(np.where(known > 0, schedule_step(CONTINUE_LEVEL, steps_total),
                                                       schedule_step(self.guidance.memory_level, steps_total)))}

    def continue_windows(self, windows: list[dict], spread: float) -> list[np.ndarray]:
        """The teacher's reaction to windows of a long take (dicts of canonical (T, D) "leader", "given", "noise",
        "leader_noise", and "label", "seed", "known"), each continuing its first `known` given frames as windows.py's
        `window_follower` continues them, at leader spread `spread` -> canonical (T, D) followers."""
        if not windows:
            return []
        teacher, base = self.teacher, self.teacher.guidance
        teacher.guidance = replace(base, leader_noise=spread)
        try:
            made = teacher._sample([w["leader"].reshape(len(w["leader"]), -1, 3) for w in windows],
                                   np.stack([w["label"] for w in windows]), [int(w["seed"]) for w in windows],
                                   [w["noise"] for w in windows], [w["leader_noise"] for w in windows],
                                   [(w["given"].reshape(len(w["given"]), -1, 3), w["known"]) for w in windows], CONTINUE_LEVEL)
        finally:
            teacher.guidance = base
        return [m.reshape(len(m), -1) for m in made]

    def refresh_windows(self) -> None:
        """The window rows given the student's own reaction to their clip (the EMA's, as it samples) instead of the
        teacher's, and the teacher's continuation of that as their target: a long take's windows continue what the
        student made, and a student taught only to continue the teacher's frames drifts from its own (exposure bias;
        the DAgger remedy, Ross et al. 2011)."""
        p, w = self.pool, self.teacher.weights
        rows = torch.nonzero(p["known"] > 0)[:, 0]
        if not len(rows):
            return
        sources = p["source"][rows]
        own = torch.zeros_like(p["target"])
        with torch.no_grad():
            for chunk in torch.unique(sources).split(POOL_BATCH):
                x0, _ = self.student_sample(self.ema, chunk)
                own[chunk, : x0.shape[1]] = x0
        steps_total = self.model_cfg.diffusion_steps
        for level in torch.unique(p["level"][rows]).tolist():
            at_level = rows[p["level"][rows] == level]
            for chunk in at_level.split(POOL_BATCH):
                windows = []
                for r in chunk.tolist():
                    t, a, src = int(p["length"][r]), int(p["offset"][r]), int(p["source"][r])
                    p["given"][r, :t] = own[src, a:a + t]
                    windows.append({"leader": p["leader"][r, :t].numpy() * w["leader_std"] + w["leader_mean"],
                                    "given": p["given"][r, :t].numpy() * w["follower_std"] + w["follower_mean"],
                                    "noise": p["noise"][r, :t].numpy(), "leader_noise": p["leader_noise"][r, :t].numpy(),
                                    "label": p["label"][r].numpy(), "seed": self.seeds[r], "known": int(p["known"][r])})
                for r, made in zip(chunk.tolist(), self.continue_windows(windows, level / (steps_total - 1)), strict=True):
                    p["target"][r, : len(made)] = torch.as_tensor((made - w["follower_mean"]) / w["follower_std"])

    # ---- one step -------------------------------------------------------------------------
    def student_sample(self, net: ReactionDenoiser, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The student's own DDIM steps on pool rows, as the sampler takes them (sampler.py `ddim`, eta 0; a window's
        given frames held at every step, as `keeping` holds them, and its start noised from them as model.py
        `_sample` does) -> (x0 (B, T, D) normalized, mask (B, T))."""
        p, g = self.pool, self.guidance
        length = p["length"][rows]
        t = int(length.max())
        mask = torch.arange(t)[None] < length[:, None]
        m = mask[..., None].float()
        leader = p["leader"][rows, :t] * m
        level = p["level"][rows]
        a_level = self.alpha_bar[level][:, None, None]
        noisy = (a_level.sqrt() * leader + (1 - a_level).sqrt() * p["leader_noise"][rows, :t]) * m
        noisy = torch.where((level > 0)[:, None, None], noisy, leader)  # spread 0: the clean leader (model.py)
        label = p["label"][rows]
        on = torch.ones(len(rows), dtype=torch.bool)
        steps_total = self.model_cfg.diffusion_steps
        steps = torch.as_tensor(np.linspace(p["start"][rows].numpy(), 0, g.sample_steps).round().astype(int))  # (S, B)
        known = p["known"][rows]
        given = p["given"][rows, :t]
        where = (torch.arange(t)[None] < known[:, None])[..., None]
        held = torch.where(where, given, given[torch.arange(len(rows)), (known - 1).clamp(min=0)][:, None])
        a_start = self.alpha_bar[steps[0]][:, None, None]
        x = torch.where((known > 0)[:, None, None], a_start.sqrt() * held + (1 - a_start).sqrt() * p["noise"][rows, :t],
                        p["noise"][rows, :t]) * m
        for i, step in enumerate(steps):
            read = torch.where((step > 0)[:, None, None], noisy, leader)  # the last step reads the clean leader (model.py)
            leader_on = step <= g.leader_below * (steps_total - 1)
            x0 = net(x, step, read, leader_on, label, on, mask,
                     leader_level=level.float() * (step > 0)).clamp(-g.clip, g.clip) * m
            x0 = torch.where(where, given, x0)
            if i + 1 == len(steps):
                return x0, mask
            a, a_next = self.alpha_bar[step][:, None, None], self.alpha_bar[steps[i + 1]][:, None, None]
            eps = (x - a.sqrt() * x0) / (1 - a).sqrt()
            x = (a_next.sqrt() * x0 + (1 - a_next).sqrt() * eps) * m
        raise AssertionError("unreachable: sample_steps >= 1")

    def train_step(self) -> dict[str, float]:
        cfg, net = self.cfg, self.net
        gen = torch.Generator().manual_seed(derive_seed(cfg.seed, self.step))
        rows = torch.randint(len(self.pool["length"]), (cfg.batch_size,), generator=gen)
        x0, mask = self.student_sample(net, rows)
        target = self.pool["target"][rows, : x0.shape[1]]
        m = mask[..., None].float()
        made = (mask & (torch.arange(x0.shape[1])[None] >= self.pool["known"][rows][:, None]))[..., None].float()
        x0_loss = ((x0 - target) ** 2 * made).sum() / (made.sum() * x0.shape[-1])
        mv = m[:, 1:] * m[:, :-1] * torch.maximum(made[:, 1:], made[:, :-1])  # a window's seam counts, its given frames not
        vel_loss = (((x0[:, 1:] - x0[:, :-1]) - (target[:, 1:] - target[:, :-1])) ** 2 * mv).sum() / (mv.sum() * x0.shape[-1])
        loss = x0_loss + cfg.lambda_velocity * vel_loss
        label = self.pool["label"][rows]
        adversarial = critic_loss = torch.zeros(())
        if self.critic is not None:
            leader = self.pool["leader"][rows, : x0.shape[1]] * m
            self.critic.requires_grad_(False)
            adversarial = -self.critic(leader, x0, label, mask).mean()  # hinge loss, the generator's side
            loss = loss + cfg.lambda_adversarial * adversarial
        label_loss = torch.zeros(())
        if self.label_critic is not None:
            label_loss = self.label_loss(x0, mask, label)
            loss = loss + cfg.lambda_label * label_loss
        lr = optimizer_step(cfg, self.opt, net, self.ema, loss, self.step)
        if self.critic is not None:
            self.critic.requires_grad_(True)
            critic_loss = (F.relu(1 - self.critic(leader, target * m, label, mask)).mean()
                           + F.relu(1 + self.critic(leader, x0.detach(), label, mask)).mean())
            self.critic_opt.zero_grad(set_to_none=True)
            critic_loss.backward()
            self.critic_opt.step()
        self.step += 1
        return {"loss": loss.item(), "x0": x0_loss.item(), "velocity": vel_loss.item(), "adversarial": adversarial.item(),
                "critic": critic_loss.item(), "label": label_loss.item(), "lr": lr}

    def label_loss(self, x0: torch.Tensor, mask: torch.Tensor, label: torch.Tensor) -> torch.Tensor:
        """The label critic's cross-entropy for the classes each row performs (its positive values, as shares), weighed
        by how much it performs them (their sum, up to 1); rows that perform nothing add nothing."""
        performed = label.clamp(min=0)
        amount = performed.sum(-1)
        rows = amount > 0
        if not rows.any():
            return torch.zeros(())
        follower = x0[rows] * self.follower_scale["follower_std"] + self.follower_scale["follower_mean"]
        return self.label_critic.loss(follower, mask[rows].sum(-1), performed[rows] / amount[rows, None], amount[rows].clamp(max=1))

    # ---- the run --------------------------------------------------------------------------
    def fit(self, progress: bool = True) -> Path:
        from tqdm import tqdm

        self.out.mkdir(parents=True, exist_ok=True)
        self.draw_pool(progress)
        t0 = time.time()
        totals: dict[str, float] = {}
        count = 0
        with open(self.out / "log.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=LOG_FIELDS)
            writer.writeheader()
            bar = tqdm(total=self.cfg.steps, disable=not progress, desc=f"student {self.subject or 'none'}", unit="step",
                       mininterval=2.0)
            while self.step < self.cfg.steps:
                if self.cfg.window_refresh and self.step and self.step % self.cfg.window_refresh == 0:
                    self.refresh_windows()
                self.net.train()
                parts = self.train_step()
                for k in ("loss", "x0", "velocity", "adversarial", "critic", "label"):
                    totals[k] = totals.get(k, 0.0) + parts[k]
                count += 1
                bar.update(1)
                if self.step % 100 == 0 or self.step == self.cfg.steps:
                    row = {k: v / count for k, v in totals.items()} | {"lr": parts["lr"]}
                    writer.writerow({"step": self.step, **{k: f"{v:.5g}" for k, v in row.items()},
                                     "seconds": f"{time.time() - t0:.1f}"})
                    fh.flush()
                    bar.set_postfix(loss=f"{row['loss']:.4f}")
                    totals, count = {}, 0
            bar.close()
        final = self.out / "final.safetensors"
        save_checkpoint(final, {f"denoiser.{k}": v.detach().cpu() for k, v in self.ema.state_dict().items()}, self.meta())
        return final

    def meta(self) -> dict:
        return {
            "kind": "final",
            "family": FAMILY,
            "code_version": imm_model.__version__,
            "model_config": self.model_cfg.to_dict(),
            "guidance": self.guidance.to_dict(),
            "train_config": self.cfg.to_dict(),
            **data_meta(self.data, self.subject, self.train_idx),
            "follower_bone_lengths": self.teacher.info["follower_bone_lengths"],
            # which model it drafts for (ReactionModel.attach_draft matches this digest against the model's own) and
            # where that model is, from the student's folder: it makes the student's long takes (model.py teacher_for_takes)
            "teacher": {"path": os.path.relpath(self.teacher_path.resolve(), self.out.resolve()), DIGEST: self.teacher.info.get(DIGEST)},
            "training": {"fold": f"loso-{self.subject}" if self.subject else "all", "step": self.step,
                         "train_sequences": len(self.train_idx), "seed": self.cfg.seed, "pool_rows": self.cfg.pool_rows},
        }


def distill(cfg: DiffusionTrainConfig, data: InteractionDataset, subject: str | None, out_dir: Path, device="cpu",
            progress: bool = True) -> Trained:
    """One fold's student, from its teacher's reactions to the end (a student is short: it is not resumed)."""
    final = StudentTrainer(cfg, data, subject, out_dir, device).fit(progress=progress)
    return Trained(f"{cfg.steps} steps from {cfg.pool_rows} teacher reactions -> {final}", {"steps": cfg.steps})
