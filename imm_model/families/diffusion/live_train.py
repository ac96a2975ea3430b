"""Training the live reactor (live.py) of a clip model: the teacher's own reactions as the pool, then the causal network
learnt on them frame by frame (teacher forcing through noise). `imm train --config imm-diffusion-live --fold S`.

The pool (`teacher_pool`): every training leader `live_pool` times, each under a label drawn as the distilled
student's are (distill.py `pool_labels`: one class, a signed value, two-class mixes, A and -B, three signed classes; a
`live_part_share` of them differing per body part) and a seed, the clip sampled whole; and `live_takes` long takes (a
training leader played 2-4 times in a row, repeated or forwards then backwards) made as the studio makes a long take's
reaction (windows.py `take_windows`). Leader and label disagree there as users make them disagree, a seed's variation
is in the targets, and the network sees reactions that stay engaged past a clip's length.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

import imm_model
from imm_model.checkpoint import DIGEST, load_checkpoint, save_checkpoint
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError
from imm_model.families.base import Trained
from imm_model.families.diffusion.denoiser import sinusoid
from imm_model.families.diffusion.live import KIND, LEVEL_FEATURES, LiveConfig, leader_windows
from imm_model.families.diffusion.sampler import cosine_alpha_bar

PAST_NOISE = 1.0  # the largest noise (training stds) on the follower's past frames: its own errors are no surprise
HEAD_ROWS = 8  # frames of each training row the head learns from at a step, on average (the head is the costly part)
POOL_BATCH = 64  # teacher reactions drawn per sampler call


class CausalConv(nn.Module):
    """A residual block of a causal temporal convolution: frame t reads frames t - 2 * dilation .. t."""

    def __init__(self, width: int, dilation: int):
        super().__init__()
        self.pad = 2 * dilation
        self.conv = nn.Conv1d(width, width, 3, dilation=dilation)
        self.mix = nn.Conv1d(width, width, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:  # (B, W, T)
        return x + self.mix(nn.functional.silu(self.conv(nn.functional.pad(x, (self.pad, 0)))))


class LiveNet(nn.Module):
    """live.py `LiveNet` in torch, for training: the same weights' names."""

    def __init__(self, cfg: LiveConfig):
        super().__init__()
        d, c, w, h = cfg.pose_dim, 2 * cfg.num_classes, cfg.width, cfg.head_width
        self.cfg = cfg
        self.inp = nn.Linear((cfg.lookahead + 1) * d + 1 + d + 1 + c + 1, w)
        self.convs = nn.Sequential(*(CausalConv(w, k) for k in cfg.dilations))
        self.label = nn.Linear(c, h)
        self.absent = nn.Parameter(torch.zeros(h))
        self.level = nn.Sequential(nn.Linear(LEVEL_FEATURES, h), nn.SiLU(), nn.Linear(h, h))
        self.head_in = nn.Linear(cfg.chunk * d + w, h)
        self.blocks = nn.ModuleList(nn.Sequential(nn.LayerNorm(h), nn.Linear(h, 2 * h), nn.SiLU(), nn.Dropout(0.1),
                                                  nn.Linear(2 * h, h)) for _ in range(cfg.head_blocks))
        self.out = nn.Sequential(nn.LayerNorm(h), nn.Linear(h, cfg.chunk * d))
        for name in ("leader_mean", "leader_std", "follower_mean", "follower_std"):
            self.register_buffer(name, torch.zeros(d) if name.endswith("mean") else torch.ones(d))

    def context(self, windows, past, past_on, label, label_on):
        """(B, T, (L+1) D), (B, T, D), (B, T, 1), (B, 2C), (B,) -> every frame's context (B, T, width)."""
        b, t, _ = windows.shape
        on = label_on.float()[:, None]
        labels = torch.cat([label * on, on], -1)[:, None].expand(b, t, -1)
        x = self.inp(torch.cat([windows, torch.ones(b, t, 1), past * past_on, past_on, labels], -1)).transpose(1, 2)
        return nn.functional.silu(self.convs(x)).transpose(1, 2)

    def denoise(self, x_t, level, h, label, label_on):
        cond = self.level(sinusoid(level, LEVEL_FEATURES)) + torch.where(label_on[:, None], self.label(label), self.absent)
        z = self.head_in(torch.cat([x_t, h], -1)) + cond
        for block in self.blocks:
            z = z + block(z)
        return self.out(z)


def with_parts(rng: np.random.Generator, labels: np.ndarray, share: float) -> np.ndarray:
    """(N, C) -> (N, 2C), upper then lower: the same on both parts but for a `share` of rows, whose lower body gets
    another drawn label."""
    from imm_model.families.diffusion.distill import pool_labels

    lower = labels.copy()
    differ = rng.random(len(labels)) < share
    lower[differ] = pool_labels(rng, int(differ.sum()), labels.shape[1])
    return np.concatenate([labels, lower], 1)


def long_leader(rng: np.random.Generator, clips: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A long take's leader drawn from `clips`: one of them 2-4 times in a row, repeated or forwards then backwards
    (half each); and the clip."""
    clip = clips[int(rng.integers(len(clips)))]
    copies, repeat = int(rng.integers(2, 5)), rng.random() < 0.5
    return np.concatenate([clip if repeat or c % 2 == 0 else clip[::-1] for c in range(copies)]), clip


def teacher_pool(teacher, data: InteractionDataset, train_idx: np.ndarray, per_leader: int, takes: int,
                 part_share: float, seed: int, log=print) -> tuple[list, list, np.ndarray]:
    """The teacher's reactions (module docstring): canonical leaders and followers (T, D) and labels (N, 2C)."""
    from imm_model.families.diffusion.distill import pool_labels
    from imm_model.families.diffusion.windows import take_windows

    rng = np.random.default_rng((seed, 7))
    classes = len(data.class_names)
    canon = [data.canonical(int(i))[0].astype(np.float32) for i in train_idx]
    which = np.repeat(np.arange(len(canon)), per_leader)
    labels = with_parts(rng, pool_labels(rng, len(which), classes), part_share)
    # rows asking for the same terms side by side: the sampler composes one term per class any row of a batch weighs
    order = np.argsort((labels != 0) @ (1 << np.arange(labels.shape[1])), kind="stable")
    which, labels = which[order], labels[order]
    seeds = rng.integers(0, 2**31 - 1, len(which))
    leaders, followers = [], []
    t0 = time.perf_counter()
    for start in range(0, len(which), POOL_BATCH):
        rows = list(range(start, min(len(which), start + POOL_BATCH)))
        made = teacher._sample([canon[which[r]] for r in rows], teacher._label_input(labels[rows]), [int(seeds[r]) for r in rows])
        leaders += [canon[which[r]].reshape(len(canon[which[r]]), -1) for r in rows]
        followers += [f.reshape(len(f), -1).astype(np.float32) for f in made]
        log(f"teacher reactions {start + len(rows)}/{len(which)}, {time.perf_counter() - t0:.0f} s")
    take_labels = with_parts(rng, pool_labels(rng, takes, classes), part_share)
    for n in range(takes):
        leader, _ = long_leader(rng, canon)
        made = take_windows(teacher, leader, teacher._label_input(take_labels[n:n + 1])[0], int(rng.integers(2**31 - 1)))
        leaders.append(leader.reshape(len(leader), -1))
        followers.append(made.reshape(len(made), -1).astype(np.float32))
        if n % 20 == 0 or n == takes - 1:
            log(f"teacher long takes {n + 1}/{takes}, {time.perf_counter() - t0:.0f} s")
    return leaders, followers, np.concatenate([labels, take_labels])


def fit(cfg: LiveConfig, leaders: list, followers: list, labels: np.ndarray, steps: int, seed: int, batch: int = 32,
        lr: float = 5e-4, warmup: int = 200, weight_decay: float = 1e-4, label_drop: float = 0.15,
        lambda_velocity: float = 1.0, log=print, learn_from: list[int] | None = None) -> LiveNet:
    """Canonical leaders and followers (T, D), labels (N, 2C) -> the trained network. Rows are drawn by their
    length (every frame alike); each sees its follower's past through noise of a random size up to PAST_NOISE.
    `learn_from`: per row, the first frame whose plan is learnt (the frames before are only read as the past)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    d, chunk = cfg.pose_dim, cfg.chunk
    net = LiveNet(cfg)
    stats = {}
    for who, frames in (("leader", np.concatenate(leaders)), ("follower", np.concatenate(followers))):
        stats[who] = frames.mean(0), np.maximum(frames.std(0), 0.01)
        getattr(net, f"{who}_mean").copy_(torch.as_tensor(stats[who][0]))
        getattr(net, f"{who}_std").copy_(torch.as_tensor(stats[who][1]))
    rows = []
    for n, (a, b) in enumerate(zip(leaders, followers, strict=True)):
        a, b = (a - stats["leader"][0]) / stats["leader"][1], (b - stats["follower"][0]) / stats["follower"][1]
        idx = np.arange(len(b))[:, None] + np.arange(chunk)[None]
        target, present = b[np.minimum(idx, len(b) - 1)].reshape(len(b), -1), idx < len(b)
        if learn_from is not None:
            present[:learn_from[n]] = False
        rows.append((leader_windows(a, cfg.lookahead), np.concatenate([np.zeros((1, d)), b[:-1]]), target, present))
    lengths = np.array([len(a) for a in leaders], float)
    alpha_bar = torch.as_tensor(cosine_alpha_bar(cfg.diffusion_steps), dtype=torch.float32)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: min(1.0, (s + 1) / max(warmup, 1)) * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * s / steps))))
    t0 = time.perf_counter()
    for step in range(steps):
        pick = rng.choice(len(rows), batch, p=lengths / lengths.sum())
        tmax = int(lengths[pick].max())

        def padded(k, width, pick=pick, tmax=tmax):
            out = np.zeros((batch, tmax, width), np.float32)
            for j, i in enumerate(pick):
                out[j, :len(rows[i][k])] = rows[i][k]
            return torch.as_tensor(out)

        windows, past, target, present = padded(0, rows[0][0].shape[1]), padded(1, d), padded(2, chunk * d), padded(3, chunk)
        valid = present[..., 0] > 0
        past_on = torch.ones(batch, tmax, 1)
        past_on[:, 0] = 0
        sigma = torch.as_tensor(rng.uniform(0, PAST_NOISE, (batch, 1, 1)), dtype=torch.float32)
        past = past + sigma * torch.randn_like(past)
        row_labels = torch.as_tensor(labels[pick])
        row_on = torch.as_tensor(rng.random(batch) >= label_drop)
        h = net.context(windows, past, past_on, row_labels, row_on)
        chosen = valid & (torch.rand(valid.shape) < HEAD_ROWS / valid.sum(1, keepdim=True).clamp(min=1))
        x0, hv, pv = target[chosen], h[chosen], present[chosen]
        n = len(x0)
        level = torch.randint(0, cfg.diffusion_steps, (n,))
        ab = alpha_bar[level][:, None]
        x_t = ab.sqrt() * x0 + (1 - ab).sqrt() * torch.randn_like(x0)
        per_row = chosen.sum(1)
        pred = net.denoise(x_t, level, hv, row_labels.repeat_interleave(per_row, 0), row_on.repeat_interleave(per_row, 0))
        w = pv.repeat_interleave(d, -1)
        err = ((pred - x0) ** 2 * w).sum() / w.sum()
        wv = (pv[:, 1:] * pv[:, :-1])[..., None]
        moved = pred.view(n, chunk, d).diff(dim=1) - x0.view(n, chunk, d).diff(dim=1)
        verr = (moved ** 2 * wv).sum() / (wv.sum() * d).clamp(min=1)
        loss = err + lambda_velocity * verr
        opt.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        sched.step()
        if step % 500 == 0 or step == steps - 1:
            log(f"step {step}: loss {loss.item():.4f} (x0 {err.item():.4f}, velocity {verr.item():.4f}), "
                f"{time.perf_counter() - t0:.0f} s")
    return net.eval()


def save_live(path: Path, net: LiveNet, meta: dict) -> None:
    save_checkpoint(path, {f"live.{k}": v.detach().cpu().contiguous() for k, v in net.state_dict().items()},
                    meta | {"kind": KIND, "live_config": net.cfg.to_dict()})


def train_live(cfg, data: InteractionDataset, subject: str | None, out_dir: Path | str, device: str = "cpu",
               progress: bool = True) -> Trained:
    """One fold's live reactor from its teacher (cfg.teacher, "{fold}" the held-out subject) -> out_dir/final.safetensors,
    to be put beside the teacher as <its stem>_live.safetensors (live.py `live_for`)."""
    from imm_model.families.diffusion.model import DiffusionReactionModel
    from imm_model.training.data import data_meta

    out = Path(out_dir)
    teacher_path = Path(cfg.teacher.format(fold=subject or "all"))
    if not teacher_path.is_file():
        raise CheckpointError(f"{teacher_path}: the live reactor's teacher not found (train it first: imm train "
                              f"--config imm-diffusion --fold {subject or 'none'})")
    arrays, meta = load_checkpoint(teacher_path, framework="np")
    if meta.get("family") != "diffusion" or meta.get("kind") == KIND:
        raise CheckpointError(f"{teacher_path}: not a diffusion clip model, which a live reactor's teacher must be")
    teacher = DiffusionReactionModel.from_checkpoint(arrays, meta, teacher_path)
    train_idx = np.arange(len(data)) if subject is None else loso_fold(data.subject_pairs, subject).train
    log = print if progress else (lambda *_: None)
    live_cfg = LiveConfig.from_dict(cfg.live | {"num_joints": data.skeleton.num_joints, "num_classes": len(data.class_names)})
    pool = teacher_pool(teacher, data, train_idx, cfg.live_pool, cfg.live_takes, cfg.live_part_share, cfg.seed, log)
    net = fit(live_cfg, *pool, cfg.steps, cfg.seed, cfg.batch_size, cfg.lr, cfg.warmup_steps, cfg.weight_decay,
              cfg.label_drop, cfg.lambda_velocity, log)
    out.mkdir(parents=True, exist_ok=True)
    final = out / "final.safetensors"
    save_live(final, net, {
        "family": "diffusion", "code_version": imm_model.__version__, "train_config": cfg.to_dict(),
        **data_meta(data, subject, train_idx),
        "teacher": {"path": os.path.relpath(teacher_path.resolve(), out.resolve()), DIGEST: teacher.info.get(DIGEST)},
        "training": {"fold": f"loso-{subject}" if subject else "all", "step": cfg.steps, "seed": cfg.seed,
                     "pool_rows": len(pool[0])}})
    return Trained(f"{cfg.steps} steps from {len(pool[0])} teacher reactions -> {final} (put it beside its teacher as "
                   f"{teacher_path.stem}_live.safetensors to react live with it)", {"steps": cfg.steps})
