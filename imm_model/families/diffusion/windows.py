"""Reactions to leaders of any length, offline and live: the take in short windows, each continuing the last.

The denoiser sees every frame of a clip at once, with frame positions and a canonical frame it learned on clips of at
most `model.window` frames (the longest training sequence), each from the start of an interaction; sampled whole, a
longer take drifts away from its leader (docs/experiments/long-takes.md). A take longer than that is made `STRIDE`
frames at a time: each time, a window of the last `WINDOW` leader frames up to `TAKE_LOOKAHEAD` frames beyond the new ones,
in a canonical frame of its own (`anchored`: the window before's until the leader has moved away from it), so that it
looks like a training clip wherever in the take it lies. The follower frames already made are given to the sampler,
which inpaints the rest around them (sampler.py `sample`'s `known`, as PriorMDM continues a long sequence), taking
each sampler step `RESAMPLE` more times so that the two settle together (RePaint's resampling), and the window's new
frames are kept; the last `BLEND` frames made are sampled again and crossfaded into the window's, because a window's
first frame does not continue the given ones exactly (the network never learnt to continue a given past).
The starting noise (and the leader's noise) is the seed's draw for the whole take, sliced per window.

Live, `OnlineReactor` does the same one frame at a time, as the leader's frames come, in windows of `ONLINE_WINDOW`
frames, in `LIVE_STEPS` sampler steps each taken once (a push has a frame's time): a frame returned is final, so instead of the
crossfade each frame is the mean of the samples every window up to its return made of it (`Votes`); a follower frame
never reads a leader frame beyond its lookahead, and a label changed mid-take changes the frames from the next one on,
continuing the past ones.
"""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np

from imm_model.cleanup import OnlineCleanup
from imm_model.data.canonical import CanonicalFrame
from imm_model.families.diffusion.sampler import LEADER_NOISE_STREAM, initial_noise, leader_noise
from imm_model.families.diffusion.steering import SteeredReaction

WINDOW = 30  # leader frames each window of a long take reads (the follower's given past, its blend and its new frames)
# leader frames each step of the online reactor reads (the frames before the one it makes given): 16 read as asked
# for 0.53 of off-label leaders, 30 for 0.72, at 1.3-1.4x the push's time (docs/experiments/long-takes.md)
ONLINE_WINDOW = 30
STRIDE = 4  # new follower frames a window of a long take makes (live: 1, a frame per leader frame)
BLEND = 6  # frames made by one window that the next samples again and crossfades into its own (offline only)
LOOKAHEAD = 4  # live: leader frames a window reads beyond the last follower frame it makes (0.27 s at 15 fps)
# offline, where the whole take is known: the same, 0.8 s; a window that sees where the leader's action goes reads as
# its label as a clip does (4 frames: off-label 0.75 against the whole clip's 0.92; docs/experiments/long-takes.md)
TAKE_LOOKAHEAD = 12
# a window continuing given frames starts its sampler at this noise level from them (the last one held), not from pure
# noise: the given frames then hold the follower's placement and pose (from pure noise the 7-step sampler drew each
# window's placement anew, and the follower jumped up to 1 m at a window's first frame)
CONTINUE_LEVEL = 0.6
# a window of a long take takes each sampler step this many times more, noised back in between (RePaint): the frames
# it samples settle with the frames it is given, and the follower stays as near its leader as in a clip (hands per
# copy of a leader played 4 times within 0.00 m of the clip's, against +0.04 m without; docs/experiments/long-takes.md)
RESAMPLE = 3
REANCHOR_M = 0.5  # a window keeps the canonical frame before it until the leader's root is this far from its origin
REANCHOR_DEG = 30.0  # ... or the leader has turned this far from its facing
# live: the sampler steps a push's window takes (at most the model's own), spread from CONTINUE_LEVEL down: a window
# starts from the frames it continues, so it needs fewer than a clip drawn from pure noise (4 against the model's 7:
# a push in 0.6-0.67x the time; on the live LOSO table every figure within the folds' spread of 7's but the jitter,
# +0.035 on the dev folds, still under real followers'; docs/experiments/long-takes.md)
LIVE_STEPS = 4
# live, each follower frame is sampled by every window from the one that first reaches it to the one that returns it
# (up to LOOKAHEAD + 1, each reading the leader no further than its lookahead); the frame returned is their weighted
# mean, the later windows (more of the leader seen) weighing more by this factor each: one window alone made every
# frame a seam (temporal ensembling, as ACT, Zhao et al. 2023, smooths action chunks)
ENSEMBLE_GROWTH = 1.0


def anchored(model, leader: np.ndarray, anchor: CanonicalFrame | None) -> CanonicalFrame:
    """The canonical frame a window is sampled in: the one before (`anchor`, None for the first window) while the
    window's own (its first frames' root and facing) lies within REANCHOR_M and REANCHOR_DEG of it, else its own.
    Standardized anew at every window, the 7-step sampler placed each window's follower where the new frame puts it,
    not where the given frames had it (a jump of 0.17 m at a window's first frame, against 0.05 m in the frame
    before), so a window keeps the frame before it until the leader has moved away from it."""
    own = CanonicalFrame.from_leader(np.asarray(leader, np.float64), model.skeleton, model.canonical_mode)
    if anchor is not None and model.canonical_mode == "first_frame":
        turn = abs((own.yaw[0] - anchor.yaw[0] + np.pi) % (2 * np.pi) - np.pi)
        if np.linalg.norm(own.origin[0] - anchor.origin[0]) <= REANCHOR_M and turn <= np.deg2rad(REANCHOR_DEG):
            return CanonicalFrame(np.full(len(leader), anchor.yaw[0]), np.repeat(anchor.origin[:1], len(leader), 0),
                                  anchor.mode)
    return own


def window_follower(model, leader: np.ndarray, follower: np.ndarray, known: int, label: np.ndarray, seed: int,
                    noise: np.ndarray, leader_z: np.ndarray, frame: CanonicalFrame,
                    resample: tuple[int, list] | None = None) -> np.ndarray:
    """One window: leader (W, J, 3) and follower (W, J, 3) in the take's frame, the follower's first `known` frames
    given -> the window's follower (W, J, 3) in the take's frame, sampled in canonical `frame` (`anchored`) with
    `label` (the sampler's label input), the seed and the window's slices of the take's noise; `resample` = (times,
    [the window's own seed]): each sampler step taken again that many times (sampler.py `ddim`)."""
    skeleton = model.skeleton
    given = frame.to_canonical(np.asarray(follower, np.float64), skeleton).astype(np.float32)
    out = model._sample([frame.to_canonical(np.asarray(leader, np.float64), skeleton).astype(np.float32)], label[None],
                        [seed], [noise], [leader_z], [(given, known)], CONTINUE_LEVEL, resample)[0]
    return frame.to_world(out, skeleton)


def take_windows(model, leader: np.ndarray, label: np.ndarray, seed: int, given: np.ndarray | None = None) -> np.ndarray:
    """A canonical leader (T, J, 3) + the sampler's label input (L,) + seed -> the follower (T, J, 3) in the same
    frame, STRIDE frames at a time. Each window samples the last BLEND frames made again, and those are crossfaded
    from the frames made to the window's: the window's first frame need not continue the last one made exactly.
    `given`: the follower's first frames (G, J, 3), kept as they are and continued."""
    frames, d = len(leader), model.config.pose_dim
    noise, leader_z = initial_noise(seed, frames, d), leader_noise(seed, frames, d)
    follower = np.zeros(leader.shape, np.float64)
    done, frame = 0, None
    if given is not None:
        follower[:len(given)], done = given, len(given)
    kept = done  # the given frames are not blended
    while done < frames:
        end = min(done + STRIDE + TAKE_LOOKAHEAD, frames)
        start = max(0, end - WINDOW)
        keep = STRIDE if end < frames else frames - done
        blend = min(BLEND, done - start, done - kept)
        frame = anchored(model, leader[start:end], frame)
        made = window_follower(model, leader[start:end], follower[start:end], done - start - blend, label, seed,
                               noise[start:end], leader_z[start:end], frame, (model.resample, [(seed, done)]))
        if blend:
            weight = (np.arange(1, blend + 1) / (blend + 1))[:, None, None]
            follower[done - blend:done] = (1 - weight) * follower[done - blend:done] + weight * made[done - start - blend:done - start]
        follower[done:done + keep] = made[done - start:done - start + keep]
        done += keep
    return follower.astype(np.float32)


def live(model):
    """`model` as the live reactor samples with it: the same network and guidance, each window taking LIVE_STEPS
    sampler steps."""
    fast = copy.copy(model)
    fast.guidance = replace(model.guidance, sample_steps=min(LIVE_STEPS, model.guidance.sample_steps))
    return fast


class OnlineReactor(SteeredReaction):
    """A reaction to a leader streamed frame by frame (steering.py `SteeredReaction`), for a model without a live
    reactor (live.py). The frames it returns go through a causal clean-up (cleanup.py OnlineCleanup) unless the model
    is `raw`. It makes the frames a long take's windows make (`take_windows`), one at a time: every frame is sampled
    knowing only the leader up to its lookahead and the follower frames before it, by each window from the one that
    first reaches it to the one that returns it, and returned as their mean (`Votes`)."""

    def __init__(self, model, label, scale: float = 1.0, seed: int = 0):
        self.model, self.seed, self.lookahead, self.window = live(model), int(seed), LOOKAHEAD, min(ONLINE_WINDOW, model.window)
        super().__init__(label, scale)
        joints, d = model.skeleton.num_joints, model.config.pose_dim
        self._noise_stream = np.random.default_rng(self.seed)  # initial_noise's stream, drawn a frame at a time
        self._leader_noise_stream = np.random.default_rng((self.seed, LEADER_NOISE_STREAM))  # leader_noise's
        self._leader = np.zeros((0, joints, 3))
        self._follower = np.zeros((0, joints, 3))  # the network's frames returned so far (before the clean-up)
        self._votes = Votes(joints)  # the windows' samples of the frames not returned yet
        self._noise = np.zeros((0, d), np.float32)
        self._leader_z = np.zeros((0, d))
        self._first = 0  # the take's frame the buffers start at
        self._frame = None  # the canonical frame the last window was sampled in (`anchored`)
        self._clean = None if model.raw else OnlineCleanup(model.skeleton, model.bone_lengths)

    def _label_input(self, label, scale: float) -> np.ndarray:
        return self.model._label_input(self.model.label_vector(label, scale)[None])[0]

    def _take(self, frame: np.ndarray) -> None:
        d = self.model.config.pose_dim
        self._leader = np.concatenate([self._leader, frame[None]])
        self._noise = np.concatenate([self._noise, self._noise_stream.standard_normal((1, d)).astype(np.float32)])
        self._leader_z = np.concatenate([self._leader_z, self._leader_noise_stream.standard_normal((1, d))])
        drop = len(self._leader) - self.window
        if drop > 0:  # only the window's frames are kept: a take of any length runs in bounded memory
            self._leader, self._noise, self._leader_z = self._leader[drop:], self._noise[drop:], self._leader_z[drop:]
            self._follower = self._follower[drop:]
            self._first += drop

    def _emit(self, n: int) -> np.ndarray:
        known = self.frames_out - self._first
        follower = np.concatenate([self._follower, np.zeros((len(self._leader) - known, *self._leader.shape[1:]))])
        self._ramped += 1
        self._frame = anchored(self.model, self._leader, self._frame)
        made = window_follower(self.model, self._leader, follower, known, self._current(), self.seed, self._noise,
                               self._leader_z, self._frame)[known:]
        out = self._votes.add(made).take(n)
        self._follower = np.concatenate([self._follower, out])
        self.frames_out += n
        return (out if self._clean is None else self._clean(out)).astype(np.float32)


class Votes:
    """The samples the live windows make of the follower frames not returned yet, frame by frame: `add` the frames a
    window made from the first one owed on, `take` the first n as each frame's weighted mean (ENSEMBLE_GROWTH)."""

    def __init__(self, joints: int):
        self.sums = np.zeros((0, joints, 3))
        self.weights = np.zeros(0)

    def add(self, frames: np.ndarray) -> Votes:
        """Frames (n, J, 3) of one window, from the first frame owed on."""
        extra = len(frames) - len(self.weights)
        if extra > 0:
            self.sums = np.concatenate([self.sums, np.zeros((extra, *self.sums.shape[1:]))])
            self.weights = np.concatenate([self.weights, np.zeros(extra)])
        # the samples so far weigh 1 / ENSEMBLE_GROWTH as much, the new one 1 (the same ratios as growing weights, bounded)
        self.sums, self.weights = self.sums / ENSEMBLE_GROWTH, self.weights / ENSEMBLE_GROWTH
        self.sums[:len(frames)] += np.asarray(frames, np.float64)
        self.weights[:len(frames)] += 1.0
        return self

    def take(self, n: int) -> np.ndarray:
        """The first n frames owed, (n, J, 3): each its samples' weighted mean; they are owed no more."""
        out = self.sums[:n] / self.weights[:n, None, None]
        self.sums, self.weights = self.sums[n:], self.weights[n:]
        return out
