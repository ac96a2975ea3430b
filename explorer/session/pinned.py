"""A/B: a pinned mix beside the current one. The pinned follower keeps its model, seed and spread, so that A/B can
compare models, and follows the leader (re-synthesized for each new one)."""

from __future__ import annotations

import numpy as np

from explorer.session.readings import mean_joint_distances
from explorer.session.words import mix_words
from imm_model.data.labels import Label


class PinnedMix:
    def __init__(self, session) -> None:  # the Session (session.py) it is a room of
        self.session = session
        self.label: Label | None = None  # the pinned mix (None: nothing pinned)
        self.vector = np.zeros(0, np.float32)  # as its model reads it
        self.model = session.model_name
        self.seed = 0
        self.spread: float | None = None
        self.follower: np.ndarray | None = None  # its follower for the current leader

    def pin(self) -> None:
        """Keep the current mix and its follower, to compare the next mixes with."""
        ses = self.session
        self.label, self.follower, self.vector = ses.label, ses.synth.copy(), ses.vector.copy()
        self.model, self.seed, self.spread = ses.model_name, ses.seed, ses.spread

    def clear(self) -> None:
        self.label = self.follower = None

    def redraw(self) -> None:
        """The pinned mix for a new leader (or clean-up): the comparison follows the sequence."""
        if self.label is None:
            return
        ses = self.session
        model = ses.models[self.model]
        spread = model.spread
        if spread is not None:
            model.spread = self.spread
        try:
            self.follower = np.asarray(model.synthesize_canonical(ses.leader, self.vector, seed=self.seed), np.float32)
        finally:
            if spread is not None:
                model.spread = spread

    def text(self) -> str:
        """The pinned mix in words, and its model (and seed, spread) where they are not the current ones."""
        if self.label is None:
            return ""
        ses = self.session
        text = mix_words(self.label)
        if self.model != ses.model_name:
            text += f" · {ses.model_title(self.model)}"
        if ses.models[self.model].settings.seed and (self.model != ses.model_name or self.seed != ses.seed):
            text += f" · seed {self.seed}"
        if self.spread is not None and (self.model != ses.model_name or self.spread != ses.spread):
            text += f" · spread {self.spread:.2g}"
        return text

    def distances_m(self) -> np.ndarray:
        """(T,) per frame, how far the pinned follower's joints are from the current one's on average, metres (empty
        when none is pinned)."""
        return np.zeros(0) if self.follower is None else mean_joint_distances(self.session.synth, self.follower)
