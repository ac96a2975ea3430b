"""A reaction model that is causal by construction, trained and scored against the shipped live reactor on a LOSO fold.

The live reactor samples the clip denoiser in overlapping windows and averages them (imm_model/families/diffusion/
windows.py); the denoiser never learnt to continue a given past, and the live reaction stays further from the leader
and reads as asked less often than the clip sampled whole (docs/experiments/long-takes.md, "What limits it"). This
model predicts each follower frame from the leader up to LOOKAHEAD frames ahead and the follower's own past, as
Ready-to-React (ICLR 2025) and ARMFlow (CVPR 2026) do:

- causal temporal convolutions (the context) read, at frame t, the leader's frames t .. t + LOOKAHEAD and the label,
  and the same of the RECEPTIVE - 1 frames before (a GRU carrying everything before trained 4 x slower on one CPU
  thread); with --past-in-context they also read the follower's frame t - 1 at each frame;
- the follower's past is its own output when it reacts; in training, the recorded one through noise of a random size
  per row, so that its own errors are no surprise;
- a small diffusion head draws the follower's next CHUNK frames (t .. t + CHUNK - 1, its plan) from the context, the
  label and (unless --past-in-context) the follower's last PAST_FRAMES frames, in SAMPLE_STEPS DDIM steps starting
  from the last push's plan (CARRY_LEVEL); frame t is emitted;
- the signed label is composed at every head step as the clip sampler composes it (`Guidance.label_scale`):
  x0 = x0(no label) + s * sum_c v_c * (x0(c) - x0(no label)), the label-free term learnt by dropping the label.

So the reaction it makes offline is the one it makes live, for a take of any length. Scored here like
`online_fold.py` scores the shipped reactor (AFD single and best of 5, FID, off-label, limbs, jitter, feet,
variations; the fold's own judges) and, leader by leader with a seed each, the closest hands and the torso distance
against the clip model's offline reaction (the live engagement bar: hands <= + 0.05 m, torso <= + 0.08 m).

    OMP_NUM_THREADS=1 python docs/experiments/scripts/causal_reactor.py --fold s04 \\
        --clip-model sample_data/imm_diffusion.safetensors [--past-in-context] [--leader-drop 0.25] \\
        --variant NAME --out docs/experiments/data/causal-reactor.jsonl

Record: docs/experiments/causal-reactor.md.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from imm_model.families.diffusion.denoiser import sinusoid
from imm_model.families.diffusion.live_train import CausalConv
from imm_model.families.diffusion.sampler import cosine_alpha_bar

LOOKAHEAD = 4  # leader frames beyond the one a follower frame answers (the live reactor's)
CHUNK = 8  # follower frames the head draws at once (its plan); the first is emitted
DIFFUSION_STEPS = 100  # the forward process's steps (cosine schedule)
SAMPLE_STEPS = 4  # DDIM steps a frame takes
LABEL_DROP = 0.15  # training rows that see no label (the label-free term)
# training rows that see no leader (a learnt "absent" input), so that the label alone must say what the reaction is:
# SBU's leader shows its class, and a network that always sees it has no use for the label
LEADER_DROP = 0.0
PAST_NOISE = 1.0  # the largest noise (training stds) on the follower's past frames in training
# the follower's own frames before t that the network reads: by default only the head, and only the last PAST_FRAMES
# (continuity); with PAST_IN_CONTEXT the context reads its past over the whole receptive field too (which class it is
# performing shows there, and the network learns to read the class from it instead of the label)
PAST_FRAMES = 2
PAST_IN_CONTEXT = False
# each push starts its plan from the last push's, one frame on, noised to this level (t / T) and denoised in
# SAMPLE_STEPS steps: the reaction keeps to the plan it drew (the first push starts from pure noise)
CARRY_LEVEL = 0.6
# the frame emitted is the mean of what the last ENSEMBLE plans drew for it (temporal ensembling, as ACT, Zhao et al.
# 2023, smooths overlapping action chunks; 1: the newest plan's alone)
ENSEMBLE = 1
# the plan's noise drawn once per frame of the take, not once per push: successive pushes noise a frame alike, so
# their plans agree where the noise alone made them differ
FRAME_NOISE = False
HEAD_ROWS = 8  # frames of each training row the diffusion head learns from at a step (on average)
CLIP = 6.0  # x0 predictions clamped to this many training stds, as the clip sampler does


DILATIONS = (1, 2, 4, 8, 16)  # the context's causal convolutions: it reads the last RECEPTIVE frames
RECEPTIVE = 1 + 2 * sum(DILATIONS)


class CausalReactor(nn.Module):
    def __init__(self, dims: int, classes: int, hidden: int = 128, head: int = 384):
        super().__init__()
        self.dims, self.classes, self.hidden = dims, classes, hidden
        past_in = (dims + 1) if PAST_IN_CONTEXT else 0
        self.inp = nn.Linear((LOOKAHEAD + 1) * dims + 1 + past_in + classes + 1, hidden)
        self.convs = nn.Sequential(*(CausalConv(hidden, d) for d in DILATIONS))
        self.label = nn.Linear(classes, head)
        self.absent = nn.Parameter(torch.zeros(head))
        self.level = nn.Sequential(nn.Linear(64, head), nn.SiLU(), nn.Linear(head, head))
        self.head_in = nn.Linear(CHUNK * dims + hidden + PAST_FRAMES * (dims + 1), head)
        self.blocks = nn.ModuleList(nn.Sequential(nn.LayerNorm(head), nn.Linear(head, 2 * head), nn.SiLU(),
                                                  nn.Dropout(0.1), nn.Linear(2 * head, head)) for _ in range(3))
        self.out = nn.Sequential(nn.LayerNorm(head), nn.Linear(head, CHUNK * dims))
        for name in ("leader_mean", "leader_std", "follower_mean", "follower_std"):
            self.register_buffer(name, torch.zeros(dims) if name.endswith("mean") else torch.ones(dims))

    def context(self, leader_windows, past, past_on, label, label_on, leader_on=None):
        """(B, T, (L+1) D), (B, T, D), (B, T, 1), label (B, C), label_on (B,), leader_on (B,) -> (B, T, H): frame t's
        context, from frames <= t of each and the row's label (or none), the leader (or none; default: there)."""
        b, t, _ = leader_windows.shape
        on = label_on.float()[:, None]
        labels = torch.cat([label * on, on], -1)[:, None].expand(b, t, -1)
        lead = torch.ones(b, 1, 1) if leader_on is None else leader_on.float()[:, None, None]
        leaders = [leader_windows * lead, lead.expand(b, t, 1)]
        pasts = [past * past_on, past_on] if PAST_IN_CONTEXT else []
        x = self.inp(torch.cat([*leaders, *pasts, labels], -1)).transpose(1, 2)
        return nn.functional.silu(self.convs(x)).transpose(1, 2)

    def denoise(self, x_t, level, h, recent, label, label_on):
        """x_t (N, CHUNK*D), level (N,), h (N, H), recent (N, PAST_FRAMES*(D+1)): the follower's last frames, each with
        a flag that it exists; label (N, C), label_on (N,) -> x0 (N, CHUNK*D)."""
        cond = self.level(sinusoid(level, 64)) + torch.where(label_on[:, None], self.label(label), self.absent)
        z = self.head_in(torch.cat([x_t, h, recent], -1)) + cond
        for block in self.blocks:
            z = z + block(z)
        return self.out(z)


def leader_windows(leader: np.ndarray) -> np.ndarray:
    """(T, D) -> (T, (L+1) D): frame t's leader frames t .. t + L, the last frame repeated past the end."""
    idx = np.minimum(np.arange(len(leader))[:, None] + np.arange(LOOKAHEAD + 1)[None], len(leader) - 1)
    return leader[idx].reshape(len(leader), -1)


def recent_frames(follower: np.ndarray) -> np.ndarray:
    """(T, D) -> (T, PAST_FRAMES*(D+1)): for frame t, frames t-1 .. t-PAST_FRAMES with a flag each (zeros before the
    first frame, flag 0)."""
    t, d = follower.shape
    out = np.zeros((t, PAST_FRAMES, d + 1), np.float32)
    for k in range(1, PAST_FRAMES + 1):
        out[k:, k - 1, :d] = follower[:-k] if k < t else 0
        out[k:, k - 1, d] = 1
    return out.reshape(t, -1)


def chunks(follower: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, D) -> targets (T, CHUNK*D) of frames t .. t + CHUNK - 1, and which of them exist (T, CHUNK)."""
    t = len(follower)
    idx = np.arange(t)[:, None] + np.arange(CHUNK)[None]
    return follower[np.minimum(idx, t - 1)].reshape(t, -1), idx < t


def recorded_rows(data, train_idx) -> tuple[list, list, np.ndarray]:
    """The fold's recorded training pairs: canonical leaders and followers (T, D) and their one-hot labels (N, C)."""
    pairs = [data.canonical(int(i)) for i in train_idx]
    leaders = [a.reshape(len(a), -1).astype(np.float32) for a, _ in pairs]
    followers = [b.reshape(len(b), -1).astype(np.float32) for _, b in pairs]
    return leaders, followers, np.eye(len(data.class_names), dtype=np.float32)[data.actions[train_idx]]


def train(leaders, followers, labels, steps: int, seed: int, batch: int = 32, lr: float = 5e-4,
          log=print) -> CausalReactor:
    """Canonical leaders and followers (T, D) with their label vectors (N, C) -> the trained network."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    d = leaders[0].shape[1]
    net = CausalReactor(d, labels.shape[1])
    stats = {}
    for who, frames in (("leader", np.concatenate(leaders)), ("follower", np.concatenate(followers))):
        stats[who] = frames.mean(0), np.maximum(frames.std(0), 0.01)
        getattr(net, f"{who}_mean").copy_(torch.as_tensor(stats[who][0]))
        getattr(net, f"{who}_std").copy_(torch.as_tensor(stats[who][1]))
    norm = lambda x, who: (x - stats[who][0]) / stats[who][1]  # noqa: E731
    rows = []
    for a, b in zip(leaders, followers, strict=True):
        a, b = norm(a, "leader"), norm(b, "follower")
        target, present = chunks(b)
        past = np.concatenate([np.zeros((1, d), np.float32), b[:-1]])
        rows.append((leader_windows(a), past, target, present, recent_frames(b)))
    alpha_bar = torch.as_tensor(cosine_alpha_bar(DIFFUSION_STEPS), dtype=torch.float32)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    # a linear warm-up over 200 steps, then a cosine down to a tenth, as the clip model's recipe
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: min(1.0, (s + 1) / 200) * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * s / steps))))
    t0 = time.perf_counter()
    for step in range(steps):
        pick = rng.choice(len(rows), batch)
        tmax = max(len(rows[i][0]) for i in pick)

        def padded(k, width, pick=pick, tmax=tmax):
            out = np.zeros((batch, tmax, width), np.float32)
            for j, i in enumerate(pick):
                out[j, :len(rows[i][k])] = rows[i][k]
            return torch.as_tensor(out)

        lw, past, target = padded(0, rows[0][0].shape[1]), padded(1, d), padded(2, CHUNK * d)
        present = padded(3, CHUNK)
        recent = padded(4, PAST_FRAMES * (d + 1)).view(batch, tmax, PAST_FRAMES, d + 1)
        valid = present[..., 0] > 0  # (B, T) frames that exist
        past_on = torch.ones(batch, tmax, 1)
        past_on[:, 0] = 0
        sigma = torch.as_tensor(rng.uniform(0, PAST_NOISE, (batch, 1, 1)), dtype=torch.float32)
        past = past + sigma * torch.randn_like(past)
        recent[..., :d] = (recent[..., :d] + sigma[..., None] * torch.randn_like(recent[..., :d])) * recent[..., d:]
        recent = recent.flatten(2)
        row_labels = torch.as_tensor(labels[pick])
        row_on = torch.as_tensor(rng.random(batch) >= LABEL_DROP)
        h = net.context(lw, past, past_on, row_labels, row_on, torch.as_tensor(rng.random(batch) >= LEADER_DROP))
        # the head learns from HEAD_ROWS frames of each row (the GRU reads them all): the head is the costly part
        chosen = valid & (torch.rand(valid.shape) < HEAD_ROWS / valid.sum(1, keepdim=True).clamp(min=1))
        x0, hv, pv, rv = target[chosen], h[chosen], present[chosen], recent[chosen]  # (N, ...)
        n = len(x0)
        level = torch.randint(0, DIFFUSION_STEPS, (n,))
        noise = torch.randn_like(x0)
        ab = alpha_bar[level][:, None]
        x_t = ab.sqrt() * x0 + (1 - ab).sqrt() * noise
        per_row = chosen.sum(1)
        lab = row_labels.repeat_interleave(per_row, 0)
        label_on = row_on.repeat_interleave(per_row, 0)
        pred = net.denoise(x_t, level, hv, rv, lab, label_on)
        w = pv.repeat_interleave(d, -1)
        err = ((pred - x0) ** 2 * w).sum() / w.sum()
        wv = (pv[:, 1:] * pv[:, :-1])[..., None]
        moved = pred.view(n, CHUNK, d).diff(dim=1) - x0.view(n, CHUNK, d).diff(dim=1)
        verr = (moved ** 2 * wv).sum() / (wv.sum() * d).clamp(min=1)
        loss = err + verr
        opt.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        sched.step()
        if step % 500 == 0 or step == steps - 1:
            log(f"step {step}: loss {loss.item():.4f} (x0 {err.item():.4f}, velocity {verr.item():.4f}), {time.perf_counter() - t0:.0f} s")
    return net.eval()


class Streamer:
    """`synthesize_batch_canonical` as the evaluation calls it: every leader streamed frame by frame in lockstep, each
    frame knowing the leader up to LOOKAHEAD ahead and its own past only; then the online clean-up."""

    def __init__(self, net: CausalReactor, skeleton, bone_lengths, label_scale: float, composed: bool = True):
        """`composed`: the signed label composed from one term per class it names, as the clip sampler composes it (a
        network trained on recorded pairs, which saw one-hot labels); else the label vector is read whole (a student
        of the clip model's composed reactions), guided around the label-free term by `label_scale` (1: not guided,
        one network call a step)."""
        self.net, self.skeleton, self.bone_lengths, self.label_scale = net, skeleton, bone_lengths, label_scale
        self.composed = composed
        self.raw = False  # the network's own frames, without the clean-up
        self.alpha_bar = cosine_alpha_bar(DIFFUSION_STEPS)

    def terms(self, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Labels (N, C) -> per network row: its leader, its label input, whether it has one, its weight in the
        guided sum. Each leader's label-free row comes first, unless the label is read whole and not guided."""
        free_row = self.composed or self.label_scale != 1
        owner, inputs, on, weight = [], [], [], []
        for i, label in enumerate(labels):
            terms = [(np.eye(len(label))[c], label[c]) for c in np.flatnonzero(label)] if self.composed else [(label, 1.0)]
            for vector, w in ([(np.zeros_like(label), 0.0)] if free_row else []) + terms:
                owner.append(i)
                inputs.append(vector)
                on.append(w != 0 or not free_row)
                weight.append(w)
        return (np.asarray(owner), np.asarray(inputs, np.float32), np.asarray(on, bool),
                np.asarray(weight, np.float32))

    @torch.inference_mode()
    def synthesize_batch_canonical(self, leaders, labels, seeds=None):
        from imm_model.cleanup import OnlineCleanup

        net, d = self.net, self.net.dims
        n = len(leaders)
        seeds = [0] * n if seeds is None else [int(s) for s in seeds]
        lengths = [len(a) for a in leaders]
        lm, ls = net.leader_mean.numpy(), net.leader_std.numpy()
        fm, fs = net.follower_mean.numpy(), net.follower_std.numpy()
        windows = [leader_windows((a.reshape(len(a), -1) - lm) / ls).astype(np.float32) for a in leaders]
        # FRAME_NOISE: one draw per frame of the take (each push's plan noises frame t + k with frame t + k's draw)
        shape = (lambda t: (t + CHUNK, d)) if FRAME_NOISE else (lambda t: (t, CHUNK * d))
        noises = [np.random.default_rng(s).standard_normal(shape(t)).astype(np.float32) for s, t in zip(seeds, lengths, strict=True)]
        labels = np.asarray(labels, np.float32)
        if labels.shape[1] * 2 == net.classes:  # a whole-body label to a network that reads one per part: on both
            labels = np.concatenate([labels, labels], 1)
        owner, onehots, label_on, weight = self.terms(labels)
        guided_terms = self.composed or self.label_scale != 1
        out = [np.zeros((t, d), np.float32) for t in lengths]
        pasts = [np.zeros((t, d), np.float32) for t in lengths]  # the follower frames made so far, normalized
        plans = np.zeros((n, CHUNK * d), np.float32)  # each leader's last plan (x0 of its chunk)
        history = np.zeros((n, ENSEMBLE, CHUNK * d), np.float32)  # each leader's last ENSEMBLE plans, newest first
        full = np.linspace(DIFFUSION_STEPS - 1, 0, SAMPLE_STEPS).round().astype(int)
        carried = np.linspace(round(CARRY_LEVEL * (DIFFUSION_STEPS - 1)), 0, SAMPLE_STEPS).round().astype(int)
        for t in range(max(lengths)):
            live = np.array([i for i in range(n) if t < lengths[i]])
            rows = np.flatnonzero(np.isin(owner, live))
            first = max(0, t + 1 - RECEPTIVE)  # the frames the context reads; before them, the zeros it was trained on
            span = t + 1 - first
            lw = np.stack([windows[i][first:t + 1] for i in live])
            prev = np.zeros((len(live), span, d), np.float32)
            on = np.ones((len(live), span, 1), np.float32)
            for k, i in enumerate(live):
                prev[k, 1:] = pasts[i][first:t]
                if first > 0:
                    prev[k, 0] = pasts[i][first - 1]
                else:
                    on[k, 0] = 0
            at = np.searchsorted(live, owner[rows])  # each term row's leader among the live ones
            h = net.context(torch.as_tensor(lw[at]), torch.as_tensor(prev[at]), torch.as_tensor(on[at]),
                            torch.as_tensor(onehots[rows]), torch.as_tensor(label_on[rows]))[:, -1]
            noise = np.stack([noises[i][t:t + CHUNK].reshape(-1) if FRAME_NOISE else noises[i][t] for i in live])
            if t == 0:
                steps, x = full, noise
            else:  # the last plan one frame on (its last frame held), noised to CARRY_LEVEL
                plan = plans[live].reshape(len(live), CHUNK, d)
                plan = np.concatenate([plan[:, 1:], plan[:, -1:]], 1).reshape(len(live), -1)
                steps, a = carried, self.alpha_bar[carried[0]]
                x = (math.sqrt(a) * plan + math.sqrt(1 - a) * noise).astype(np.float32)
            recent = np.zeros((len(live), PAST_FRAMES, d + 1), np.float32)
            for k, i in enumerate(live):
                for back in range(1, min(PAST_FRAMES, t) + 1):
                    recent[k, back - 1, :d], recent[k, back - 1, d] = pasts[i][t - back], 1
            recent = torch.as_tensor(recent.reshape(len(live), -1)[at])
            free = ~label_on[rows] if guided_terms else np.ones(len(rows), bool)
            for j, step in enumerate(steps):
                pred = net.denoise(torch.as_tensor(x[at]), torch.full((len(rows),), int(step)), h, recent,
                                   torch.as_tensor(onehots[rows]), torch.as_tensor(label_on[rows])).numpy()
                base = pred[free]  # one per live leader, in live's order
                guided = base.copy()
                for k in np.flatnonzero(~free):
                    guided[at[k]] += self.label_scale * weight[rows[k]] * (pred[k] - base[at[k]])
                x0 = np.clip(guided, -CLIP, CLIP)
                if j + 1 < len(steps):
                    a, a_next = self.alpha_bar[step], self.alpha_bar[steps[j + 1]]
                    eps = (x - math.sqrt(a) * x0) / math.sqrt(1 - a)
                    x = (math.sqrt(a_next) * x0 + math.sqrt(1 - a_next) * eps).astype(np.float32)
            plans[live] = x0
            history[live] = np.roll(history[live], 1, axis=1)
            history[live, 0] = x0
            for i in live:
                # frame t as the last ENSEMBLE plans drew it (the plan made k frames ago: its frame k)
                votes = [history[i, back, back * d:(back + 1) * d] for back in range(min(ENSEMBLE, t + 1))]
                pasts[i][t] = np.mean(votes, 0)
                out[i][t] = pasts[i][t] * fs + fm
        j = len(self.skeleton.joint_names)
        if self.raw:
            return [o.reshape(len(o), j, 3) for o in out]
        return [OnlineCleanup(self.skeleton, self.bone_lengths)(o.reshape(len(o), j, 3)).astype(np.float32) for o in out]


def engagement(data, judges, streamer, clip_model, bases, windows: bool = True) -> dict:
    """Per leader and seed: closest hands and torso distance of the causal reaction and of the shipped live reactor
    (the clip model's windows, `online_fold.online_followers`), each minus the clip model's offline reaction with the
    same seed; means with 95 % t intervals over the takes (`live_engagement_folds.minus_offline`)."""
    from live_engagement_folds import minus_offline
    from online_fold import online_followers

    labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[judges.test]]
    makers = {"causal": lambda seeds: streamer.synthesize_batch_canonical(judges.leaders, labels, seeds)}
    if windows:  # the windows' live reaction too (live_engagement_folds.py measures it alone)
        makers["shipped_live"] = lambda seeds: online_followers(clip_model, judges.leaders, labels, seeds)
    return minus_offline(judges.leaders, labels, clip_model, makers, data.skeleton, bases)


def long_takes(data, judges, streamer, repeats=(1, 4, 8)) -> dict:
    """Each held-out leader played k times in a row (copies joined end to end), true class, seed 0: per copy the closest
    hands and the torso distance averaged over leaders (`long_takes.py`'s "repeat" takes)."""
    from long_takes import copy_figures, take

    y = data.actions[judges.test]
    labels = np.eye(len(data.class_names), dtype=np.float32)[y]
    out = {}
    for k in repeats:
        leaders = [take(a, k, "repeat") for a in judges.leaders]
        followers = streamer.synthesize_batch_canonical(leaders, labels)
        per = [copy_figures(a, f, data.skeleton, k) for a, f in zip(leaders, followers, strict=True)]
        for key in ("hands", "torso"):
            out[f"repeat{k}_{key}_per_copy"] = [round(float(np.mean([p[c][key] for p in per])), 4) for c in range(k)]
    return out


def causality_gap(streamer, leader: np.ndarray, label: np.ndarray, cut: int) -> float:
    """The largest change (m) of the follower's frames 0 .. cut - LOOKAHEAD - 1 when the leader's frames from `cut` on
    are replaced by others: 0 for a reaction that reads no further ahead than its lookahead."""
    other = leader.copy()
    other[cut:] = leader[::-1][: len(leader) - cut]
    keep = cut - LOOKAHEAD
    one, two = (streamer.synthesize_batch_canonical([a], label[None], [0])[0] for a in (leader, other))
    return float(np.abs(one[:keep] - two[:keep]).max())


def push_ms(streamer, leaders, labels, count: int = 8) -> float:
    """Median milliseconds a frame takes for one leader streamed alone (as the studio's live mode streams)."""
    times = []
    for a, lab in zip(leaders[:count], labels[:count], strict=True):
        start = time.perf_counter()
        streamer.synthesize_batch_canonical([a], lab[None], [0])
        times.append((time.perf_counter() - start) / len(a) * 1000)
    return float(np.median(times))


def joined_takes(teacher, data, train_idx, count: int, part_share: float, seed: int) -> tuple[list, list, np.ndarray]:
    """`count` more long takes for the pool, each 2-4 training leaders one after another, every one going on where the
    one before ended (canonical.py `joined`), reacted to by the teacher's windows as `teacher_pool`'s long takes are."""
    from imm_model.data.canonical import joined
    from imm_model.families.diffusion.distill import pool_labels
    from imm_model.families.diffusion.live_train import with_parts
    from imm_model.families.diffusion.windows import take_windows

    rng = np.random.default_rng((seed, 11))
    canon = [data.canonical(int(i))[0] for i in train_idx]
    labels = with_parts(rng, pool_labels(rng, count, len(data.class_names)), part_share)
    leaders, followers = [], []
    for n in range(count):
        picks = rng.integers(len(canon), size=int(rng.integers(2, 5)))
        (leader,), _ = joined([(canon[int(i)],) for i in picks], data.skeleton)
        made = take_windows(teacher, leader, teacher._label_input(labels[n:n + 1])[0], int(rng.integers(2**31 - 1)))
        leaders.append(leader.reshape(len(leader), -1).astype(np.float32))
        followers.append(made.reshape(len(made), -1).astype(np.float32))
    return leaders, followers, labels


def dagger_rows(net, teacher, data, train_idx, count: int, part_share: float, seed: int) -> tuple[list, list, np.ndarray, list]:
    """`count` long takes (a training leader 2-4 times in a row, repeated or forwards then backwards) reacted to by the
    network itself, each continued by the teacher's windows from a frame drawn between the middle of the first copy and
    the take's end: rows whose past is the network's own frames and whose targets are what the teacher would make from
    there (DAgger, Ross et al. 2011); and the frame each row's learning starts at."""
    from imm_model.families.diffusion.distill import pool_labels
    from imm_model.families.diffusion.live_train import long_leader, with_parts
    from imm_model.families.diffusion.windows import take_windows

    rng = np.random.default_rng((seed, 13))
    canon = [data.canonical(int(i))[0] for i in train_idx]
    labels = with_parts(rng, pool_labels(rng, count, len(data.class_names)), part_share)
    leaders, cuts = [], []
    for _ in range(count):
        leader, clip = long_leader(rng, canon)
        leaders.append(leader)
        cuts.append(int(rng.integers(len(clip) // 2, len(leaders[-1]) - CHUNK)))
    streamer = Streamer(net, data.skeleton, None, 1.0, composed=False)
    streamer.raw = True
    own = streamer.synthesize_batch_canonical(leaders, labels, rng.integers(0, 2**31 - 1, count))
    followers = []
    for n, (leader, mine, cut) in enumerate(zip(leaders, own, cuts, strict=True)):
        made = take_windows(teacher, leader, teacher._label_input(labels[n:n + 1])[0], int(rng.integers(2**31 - 1)),
                            given=mine[:cut])
        followers.append(made.reshape(len(made), -1).astype(np.float32))
    return [a.reshape(len(a), -1).astype(np.float32) for a in leaders], followers, labels, cuts


def save_live_reactor(path: Path, live_net, clip_model, args, pool_rows: int) -> None:
    """The trained live reactor as the product loads it beside its clip model (live.py `live_for`)."""
    import os

    import imm_model
    from imm_model.checkpoint import DIGEST
    from imm_model.families.diffusion.live_train import save_live

    save_live(path, live_net, {
        "family": "diffusion", "code_version": imm_model.__version__,
        "teacher": {"path": os.path.relpath(Path(args.clip_model).resolve(), Path(path).resolve().parent),
                    DIGEST: clip_model.info.get(DIGEST)},
        "training": {"fold": f"loso-{args.fold}", "step": args.steps, "seed": args.seed, "pool_rows": pool_rows,
                     "live_pool": args.teacher_pool, "live_takes": args.long_takes, "live_part_share": args.part_share,
                     "script": "docs/experiments/scripts/causal_reactor.py"}})


def main() -> None:
    from diffusion_fold import record
    from online_fold import table_row

    from imm_model.cleanup import follower_bone_lengths
    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, prepare_model
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--steps", type=int, default=6000, help="optimizer steps")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--label-scale", type=float, nargs="+", default=None,
                    help="label guidance (default: 2.5 composed per class; 1, not guided, for a student of the teacher)")
    ap.add_argument("--teacher-pool", type=int, default=0,
                    help="train the product's live reactor (live_train.py) on this many of the clip model's reactions "
                         "per training leader, the label per part read whole, instead of this network on recorded pairs")
    ap.add_argument("--clip-model", type=Path, required=True, help="the fold's clip diffusion checkpoint (engagement's reference)")
    ap.add_argument("--bases", type=int, nargs="+", default=[0, 1, 2], help="seed bases of the engagement's takes")
    ap.add_argument("--save", type=Path, default=None, help="keep the trained network's weights here")
    ap.add_argument("--load", type=Path, default=None, help="score these weights (from --save) instead of training")
    ap.add_argument("--variant", default="", help="a name recorded with each row")
    ap.add_argument("--leader-drop", type=float, default=0.0, help="share of training rows without their leader (LEADER_DROP)")
    ap.add_argument("--past-in-context", action="store_true",
                    help="the context reads the follower's past, the head none of it (PAST_IN_CONTEXT, PAST_FRAMES 0)")
    ap.add_argument("--long-takes", type=int, default=0,
                    help="with --teacher-pool: also this many of the clip model's long takes (live_train.py)")
    ap.add_argument("--joined-takes", type=int, default=0,
                    help="with --teacher-pool: also this many long takes of training leaders joined (`joined_takes`)")
    ap.add_argument("--dagger-takes", type=int, default=0,
                    help="with --teacher-pool: then this many long takes of the network's own, continued by the teacher "
                         "(`dagger_rows`), and the network trained anew on both")
    ap.add_argument("--part-share", type=float, default=0.0,
                    help="with --teacher-pool: the share of its labels that differ per body part")
    ap.add_argument("--save-live", type=Path, default=None,
                    help="with --teacher-pool: save the network as the clip model's live reactor checkpoint here")
    ap.add_argument("--carry-level", type=float, default=0.6, help="CARRY_LEVEL")
    ap.add_argument("--ensemble", type=int, default=1, help="ENSEMBLE (at most CHUNK)")
    ap.add_argument("--frame-noise", action="store_true", help="FRAME_NOISE")
    ap.add_argument("--no-windows", action="store_true",
                    help="leave the windows' live engagement out (live_engagement_folds.py measures it by fold)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    torch.set_num_threads(1)
    global PAST_IN_CONTEXT, PAST_FRAMES, LEADER_DROP, CARRY_LEVEL, ENSEMBLE, FRAME_NOISE
    LEADER_DROP, CARRY_LEVEL, ENSEMBLE, FRAME_NOISE = args.leader_drop, args.carry_level, args.ensemble, args.frame_noise
    if args.teacher_pool and not args.past_in_context:
        ap.error("--teacher-pool trains the product's live reactor, whose context reads the past: add --past-in-context")
    if args.past_in_context:  # the context reads the past; the head reads none of it
        PAST_IN_CONTEXT, PAST_FRAMES = True, 0
    data = InteractionDataset.load(SAMPLE_DATA)
    train_idx = loso_fold(data.subject_pairs, args.fold).train
    clip_model = ReactionModel.load(args.clip_model)
    composed = args.teacher_pool == 0
    scales = args.label_scale or [2.5 if composed else 1.0]
    t0 = time.perf_counter()
    pool_minutes = 0.0
    if args.load:
        net = CausalReactor(data.canonical(0)[0][0].size, len(data.class_names) * (1 if composed else 2))
        net.load_state_dict(torch.load(args.load, weights_only=True))
        net.eval()
    else:
        if composed:
            net = train(*recorded_rows(data, train_idx), args.steps, args.seed)
        else:  # the product's live reactor (imm_model/families/diffusion/live_train.py), scored here in lockstep
            from imm_model.families.diffusion.live import LiveConfig
            from imm_model.families.diffusion.live_train import fit, teacher_pool

            cfg = LiveConfig(num_joints=data.skeleton.num_joints, num_classes=len(data.class_names),
                             carry_level=CARRY_LEVEL, ensemble=ENSEMBLE)
            pool = teacher_pool(clip_model, data, train_idx, args.teacher_pool, args.long_takes, args.part_share, args.seed)
            if args.joined_takes:
                more = joined_takes(clip_model, data, train_idx, args.joined_takes, args.part_share, args.seed)
                pool = (pool[0] + more[0], pool[1] + more[1], np.concatenate([pool[2], more[2]]))
            pool_minutes = (time.perf_counter() - t0) / 60
            live_net = fit(cfg, *pool, args.steps, args.seed)
            net = CausalReactor(cfg.pose_dim, 2 * cfg.num_classes)
            net.load_state_dict(live_net.state_dict())
            net.eval()
            if args.dagger_takes:
                more = dagger_rows(net, clip_model, data, train_idx, args.dagger_takes, args.part_share, args.seed)
                starts = [0] * len(pool[0]) + more[3]
                pool = (pool[0] + more[0], pool[1] + more[1], np.concatenate([pool[2], more[2]]))
                live_net = fit(cfg, *pool, args.steps, args.seed, learn_from=starts)
                net.load_state_dict(live_net.state_dict())
                net.eval()
            if args.save_live:
                save_live_reactor(args.save_live, live_net, clip_model, args, len(pool[0]))
    minutes = (time.perf_counter() - t0) / 60 - pool_minutes
    if args.save and not args.load:
        torch.save(net.state_dict(), args.save)
    bones = np.asarray(follower_bone_lengths([data.canonical(int(i))[1] for i in train_idx], data.skeleton))
    opts = EvalOptions(baselines=(), progress=False)
    judges = FoldJudges(data, args.fold, opts)
    prepare_model(clip_model, data, args.fold, opts)
    for scale in scales:
        streamer = Streamer(net, data.skeleton, bones, scale, composed)
        row = {"fold": args.fold, "mode": "causal", "variant": args.variant, "label_scale": scale, "steps": args.steps, "seed": args.seed,
               "teacher_pool": args.teacher_pool, "long_takes": args.long_takes, "joined_takes": args.joined_takes,
               "dagger_takes": args.dagger_takes, "part_share": args.part_share, "pool_minutes": round(pool_minutes, 1),
               "train_minutes": round(minutes, 1), "leaders": len(judges.test),
               "settings": {"LOOKAHEAD": LOOKAHEAD, "CHUNK": CHUNK, "SAMPLE_STEPS": SAMPLE_STEPS, "PAST_NOISE": PAST_NOISE,
                            "CARRY_LEVEL": CARRY_LEVEL, "ENSEMBLE": ENSEMBLE, "FRAME_NOISE": FRAME_NOISE,
                            "PAST_FRAMES": PAST_FRAMES,
                            "PAST_IN_CONTEXT": PAST_IN_CONTEXT,
                            "LEADER_DROP": LEADER_DROP}}
        labels = np.eye(len(data.class_names), dtype=np.float32)[data.actions[judges.test]]
        row["causality_gap_m"] = causality_gap(streamer, judges.leaders[0], labels[0], len(judges.leaders[0]) // 2)
        row["push_ms_median"] = push_ms(streamer, judges.leaders, labels)
        row |= table_row(streamer, data, judges)
        row |= long_takes(data, judges, streamer)
        row |= engagement(data, judges, streamer, clip_model, args.bases, not args.no_windows)
        record(row, args.out)


if __name__ == "__main__":
    main()
