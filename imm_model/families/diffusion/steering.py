"""What every live reaction shares (windows.py `OnlineReactor`, live.py `LiveReactor`): a label and a scale that may
change between pushes, reached over LABEL_RAMP frames from the values in use, and a pushed leader frame checked."""

from __future__ import annotations

import numpy as np

from imm_model.data.sequence import check_world_positions
from imm_model.errors import DataFormatError

LABEL_RAMP = 8  # frames over which a label changed live moves from the old values to the new (0.53 s at 15 fps)


class SteeredReaction:
    """A reaction to a leader streamed frame by frame, steered while it plays (`ReactionModel.online`'s API).

    `push(frame)` takes the leader's next world frame (J, 3) and returns the follower's frame `lookahead` frames behind
    it (J, 3), or None while the first `lookahead` frames come in; `flush()` returns the frames still owed at the end
    of the take. A subclass sets `model` and `lookahead` before calling this __init__ and says what its network reads
    of a label (`_label_input`), how it keeps a pushed frame (`_take`) and how it makes the next n frames (`_emit`,
    counting them in `frames_out`, each sampled with `_current()` and counted in `_ramped`)."""

    def __init__(self, label, scale: float):
        self._scale, self._label = float(scale), label
        self._vector = self._label_input(label, scale)
        self._ramp_from, self._ramped = self._vector, LABEL_RAMP  # the values a label change moves from, frames since
        self.frames_in = 0  # leader frames pushed
        self.frames_out = 0  # follower frames returned

    def _label_input(self, label, scale: float) -> np.ndarray:
        raise NotImplementedError

    def _take(self, frame: np.ndarray) -> None:
        raise NotImplementedError

    def _emit(self, n: int) -> np.ndarray:
        raise NotImplementedError

    def push(self, frame) -> np.ndarray | None:
        """The leader's next world frame (J, 3) metres -> the follower's frame `lookahead` frames behind it (J, 3)
        float32 world, or None while the first `lookahead` frames come in."""
        self._take(self._checked(frame))
        self.frames_in += 1
        if self.frames_in - self.frames_out <= self.lookahead:
            return None
        return self._emit(1)[0]

    def flush(self) -> np.ndarray:
        """The follower frames still owed at the end of the take, (n, J, 3) float32 world (n <= lookahead)."""
        owed = self.frames_in - self.frames_out
        if owed == 0:
            return np.zeros((0, self.model.skeleton.num_joints, 3), np.float32)
        return self._emit(owed)

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

    def _checked(self, frame) -> np.ndarray:
        """A pushed leader frame -> (J, 3) float64, else DataFormatError (one line; nothing taken)."""
        joints = self.model.skeleton.num_joints
        try:
            frame = np.asarray(frame, np.float64)
        except (TypeError, ValueError):
            raise DataFormatError(f"leader frame must be a numeric ({joints}, 3) array") from None
        if frame.shape != (joints, 3):
            raise DataFormatError(f"leader frame has shape {frame.shape}; expected ({joints}, 3)")
        check_world_positions(frame, f"leader frame {self.frames_in}")
        return frame
