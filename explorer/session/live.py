"""Live mode: the follower made frame by frame as the leader plays (the model's online reactor), steered while it
plays. A mix changed mid-take changes the reaction from the next frames on; the frames already played stay."""

from __future__ import annotations

import numpy as np

from imm_model.errors import LabelError


class LiveReaction:
    def __init__(self, session) -> None:  # the Session (session.py) it is a room of
        self.session = session
        self.reactor = None  # the current model's online reactor (None: live mode off)
        self.made = 0  # frames of the session's follower made live, from the first (the rest are the offline reaction's)
        self.steered: list[tuple[int, str]] = []  # each label the live frames were made with, from the frame it took effect
        self._for: tuple = ()  # the leader, model, seed, clean-up and spread the reactor reacts with

    @property
    def on(self) -> bool:
        return self.reactor is not None

    def start(self) -> None:
        """Live mode on: the follower is made anew from the first frame as the leader plays (LabelError, one line, for
        a model that cannot react online: nothing changes)."""
        ses = self.session
        if not ses.model.settings.online:
            raise LabelError(f"{ses.model_title()} cannot react live, frame by frame (live mode off to use it)")
        self.reactor = ses.model.online(ses.label, seed=ses.seed)
        self.made, self._for, self.steered = 0, self._key(), [(0, _words(ses.label))]

    def stop(self) -> None:
        self.reactor = None
        self.made = 0

    def _key(self) -> tuple:
        ses = self.session
        return ses.current.canonical, ses.model_name, ses.seed, ses.model.raw, ses.spread

    def _same(self, key: tuple) -> bool:
        return len(key) == len(self._for) and key[0] is self._for[0] and key[1:] == self._for[1:]

    def follow(self, offline: np.ndarray) -> np.ndarray:
        """The session's new follower while live: for a new mix, the frames made so far kept and the reactor steered
        from the next frame on (the offline reaction stands in for the frames to come until they are made); for a new
        leader, model, seed, spread or clean-up, the reactor starts again from the first frame."""
        ses = self.session
        if not self._same(self._key()):
            self.start()
            return offline
        self.reactor.label = ses.label
        if self.steered[-1][0] == self.made:  # moved again before a frame was made with the last one
            self.steered.pop()
        self.steered.append((self.made, _words(ses.label)))
        out = offline.copy()
        out[: self.made] = ses.synth[: self.made]
        return out

    def reach(self, frame: int) -> bool:
        """Make the follower up to `frame` (pushing the leader up to the reactor's lookahead beyond it, or to its end);
        a frame before those made starts the reactor again from the first frame. True: frames were made."""
        ses = self.session
        frame = min(max(int(frame), 0), ses.num_frames - 1)
        if frame == 0 and self.made > 1:  # played again from the start (or looped): made anew
            self.start()
        if frame < self.made:
            return False
        leader, reactor = ses.leader, self.reactor
        made = []
        while reactor.frames_in < min(frame + 1 + reactor.lookahead, len(leader)):
            out = reactor.push(leader[reactor.frames_in])
            if out is not None:
                made.append(out)
        if reactor.frames_in == len(leader) and reactor.frames_out < len(leader):
            made.extend(reactor.flush())
        if made:
            ses.synth[self.made:self.made + len(made)] = np.stack(made)
            self.made += len(made)
        return bool(made)


def _words(label) -> str:
    """A label as `Label.parse` reads it, and its scale where it is not 1: what a live take's file records."""
    return label.text() + (f" (scale {label.scale:g})" if label.scale != 1 else "")
