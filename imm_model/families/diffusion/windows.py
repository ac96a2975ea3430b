"""Reactions to leaders of any length, offline and live: the take in windows of the trained length.

The denoiser sees every frame of a window at once, with frame positions and a canonical frame it learned on clips of
at most `model.window` frames (the longest training sequence). A longer take is cut into windows of that length,
each standardized in its own canonical frame (data/canonical.py: its first frames' facing and root), so that every
window looks like a training clip wherever in the take it lies. Each window's follower continues the previous one:
the frames they share are given to the sampler, which inpaints the rest around them (sampler.py `sample`'s `known`,
as PriorMDM continues a long sequence). The starting noise (and the leader's noise) is the seed's draw for the whole
take, sliced per window, so that the first window of a take is the reaction to its first `window` frames.

Live, `OnlineReactor` samples one window per leader frame: the last frames it was given, ending `lookahead` frames
after the follower frame it returns, the follower frames it returned before given. A follower frame therefore never
reads a leader frame beyond its lookahead, and a label changed mid-take changes the frames from the next one on,
continuing the past ones.
"""

from __future__ import annotations

import numpy as np

from imm_model.cleanup import OnlineCleanup
from imm_model.data.canonical import CanonicalFrame
from imm_model.data.sequence import check_world_positions
from imm_model.errors import DataFormatError
from imm_model.families.diffusion.sampler import LEADER_NOISE_STREAM, initial_noise, leader_noise

OVERLAP = 16  # frames a window of a long take shares with the one before (given, not sampled): its context
LOOKAHEAD = 4  # leader frames the online reactor reads beyond the follower frame it returns (0.27 s at 15 fps)
ONLINE_WINDOW = 24  # leader frames each online step samples over (the follower's given past is the rest)
LABEL_RAMP = 8  # frames over which a label changed live moves from the old values to the new (0.53 s at 15 fps)


def window_starts(frames: int, window: int, overlap: int = OVERLAP) -> list[int]:
    """The first frame of each window of a take of `frames` frames: a stride of window - overlap, the last window
    ending at the take's end."""
    if frames <= window:
        return [0]
    return list(range(0, frames - window, window - overlap)) + [frames - window]


def window_follower(model, leader: np.ndarray, follower: np.ndarray, known: int, label: np.ndarray, seed: int,
                    noise: np.ndarray, leader_z: np.ndarray) -> np.ndarray:
    """One window: leader (W, J, 3) and follower (W, J, 3) in the take's frame, the follower's first `known` frames
    given -> the window's follower (W, J, 3) in the take's frame, sampled in the window's own canonical frame with
    `label` (the sampler's label input), the seed and the window's slices of the take's noise."""
    skeleton = model.skeleton
    frame = CanonicalFrame.from_leader(np.asarray(leader, np.float64), skeleton, model.canonical_mode)
    given = frame.to_canonical(np.asarray(follower, np.float64), skeleton).astype(np.float32)
    out = model._sample([frame.to_canonical(np.asarray(leader, np.float64), skeleton).astype(np.float32)], label[None],
                        [seed], [noise], [leader_z], [(given, known)])[0]
    return frame.to_world(out, skeleton)


def take_windows(model, leader: np.ndarray, label: np.ndarray, seed: int) -> np.ndarray:
    """A canonical leader (T, J, 3) longer than `model.window` + the sampler's label input (L,) + seed -> the follower
    (T, J, 3) in the same frame, window by window."""
    frames, d = len(leader), model.config.pose_dim
    noise, leader_z = initial_noise(seed, frames, d), leader_noise(seed, frames, d)
    follower = np.zeros(leader.shape, np.float64)
    done = 0
    for a in window_starts(frames, model.window):
        b = a + model.window
        follower[done:b] = window_follower(model, leader[a:b], follower[a:b], done - a, label, seed, noise[a:b],
                                           leader_z[a:b])[done - a:]
        done = b
    return follower.astype(np.float32)


class OnlineReactor:
    """A reaction to a leader streamed frame by frame (`ReactionModel.online`).

    `push(frame)` takes the leader's next world frame (J, 3) and returns the follower's frame `lookahead` frames
    behind it (J, 3), or None while the first `lookahead` frames come in; `flush()` returns the frames still owed
    (n, J, 3) at the end of the take. `label` (and `scale`) may change between pushes: the reaction changes from the
    next frame on. The frames it returns go through a causal clean-up (cleanup.py OnlineCleanup) unless the model is
    `raw`. With the same seed and label, a take no longer than the window gets the reaction of an offline window that
    ends at each frame's lookahead (not the offline clip: every frame is sampled knowing only the frames before it)."""

    def __init__(self, model, label, scale: float = 1.0, seed: int = 0, lookahead: int = LOOKAHEAD,
                 window: int = ONLINE_WINDOW):
        if not 0 <= lookahead < window <= model.window:
            raise ValueError(f"lookahead {lookahead} and window {window}: need 0 <= lookahead < window <= {model.window}")
        self.model, self.seed, self.lookahead, self.window = model, int(seed), int(lookahead), int(window)
        self._scale, self._label = float(scale), label
        self._vector = self._label_input(label, scale)
        self._ramp_from, self._ramped = self._vector, LABEL_RAMP  # the values a label change moves from, frames since
        joints, d = model.skeleton.num_joints, model.config.pose_dim
        self._noise_stream = np.random.default_rng(self.seed)  # initial_noise's stream, drawn a frame at a time
        self._leader_noise_stream = np.random.default_rng((self.seed, LEADER_NOISE_STREAM))  # leader_noise's
        self._leader = np.zeros((0, joints, 3))
        self._follower = np.zeros((0, joints, 3))  # the network's frames returned so far (before the clean-up)
        self._noise = np.zeros((0, d), np.float32)
        self._leader_z = np.zeros((0, d))
        self._first = 0  # the take's frame the buffers start at
        self.frames_in = 0  # leader frames pushed
        self.frames_out = 0  # follower frames returned
        self._clean = None if model.raw else OnlineCleanup(model.skeleton, model.bone_lengths)

    def _label_input(self, label, scale: float) -> np.ndarray:
        return self.model._label_input(self.model.label_vector(label, scale)[None])[0]

    @property
    def label(self):
        return self._label

    @label.setter
    def label(self, label) -> None:
        self._steer(self._label_input(label, self._scale))
        self._label = label

    @property
    def scale(self) -> float:
        return self._scale

    @scale.setter
    def scale(self, scale: float) -> None:
        self._steer(self._label_input(self._label, scale))
        self._scale = float(scale)

    def _steer(self, vector: np.ndarray) -> None:
        """A new label from the next frame on, reached over LABEL_RAMP frames from the values in use now: a reaction
        steered mid-take turns, it does not jump (a step to a far label moved joints up to 1 m in one frame)."""
        self._ramp_from, self._ramped, self._vector = self._current(), 0, vector

    def _current(self) -> np.ndarray:
        """The label values the next frame is sampled with."""
        weight = min(self._ramped / LABEL_RAMP, 1.0)
        return ((1 - weight) * self._ramp_from + weight * self._vector).astype(np.float32)

    def push(self, frame) -> np.ndarray | None:
        """The leader's next world frame (J, 3) metres -> the follower's frame `lookahead` frames behind it (J, 3)
        float32 world, or None while the first `lookahead` frames come in."""
        joints = self.model.skeleton.num_joints
        try:
            frame = np.asarray(frame, np.float64)
        except (TypeError, ValueError):
            raise DataFormatError(f"leader frame must be a numeric ({joints}, 3) array") from None
        if frame.shape != (joints, 3):
            raise DataFormatError(f"leader frame has shape {frame.shape}; expected ({joints}, 3)")
        check_world_positions(frame, f"leader frame {self.frames_in}")
        d = self.model.config.pose_dim
        self._leader = np.concatenate([self._leader, frame[None]])
        self._noise = np.concatenate([self._noise, self._noise_stream.standard_normal((1, d)).astype(np.float32)])
        self._leader_z = np.concatenate([self._leader_z, self._leader_noise_stream.standard_normal((1, d))])
        self.frames_in += 1
        drop = len(self._leader) - self.window
        if drop > 0:  # only the window's frames are kept: a take of any length runs in bounded memory
            self._leader, self._noise, self._leader_z = self._leader[drop:], self._noise[drop:], self._leader_z[drop:]
            self._follower = self._follower[drop:]
            self._first += drop
        if self.frames_in - self.frames_out <= self.lookahead:
            return None
        return self._emit(1)[0]

    def flush(self) -> np.ndarray:
        """The follower frames still owed at the end of the take, (n, J, 3) float32 world (n <= lookahead)."""
        owed = self.frames_in - self.frames_out
        if owed == 0:
            return np.zeros((0, self.model.skeleton.num_joints, 3), np.float32)
        return self._emit(owed)

    def _emit(self, n: int) -> np.ndarray:
        known = self.frames_out - self._first
        follower = np.concatenate([self._follower, np.zeros((len(self._leader) - known, *self._leader.shape[1:]))])
        self._ramped += 1
        out = window_follower(self.model, self._leader, follower, known, self._current(), self.seed, self._noise,
                              self._leader_z)[known:known + n]
        self._follower = np.concatenate([self._follower, out])
        self.frames_out += n
        return (out if self._clean is None else self._clean(out)).astype(np.float32)
