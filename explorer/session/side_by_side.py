"""The followers drawn beside the synthesized one: the current model's variations (further seeds) and other models'
followers for the same leader and mix."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from explorer.session.words import no_parts, one_line
from imm_model.errors import LabelError
from imm_model.inference import check_seeds

MAX_VARIATIONS = 4  # followers drawn side by side at once (seeds seed .. seed + 3)
MAX_COMPARED = 3  # other models whose followers are drawn beside the current one's at once


class SideBySide:
    def __init__(self, session) -> None:  # the Session (session.py) it is a room of
        self.session = session
        self.count = 1  # followers drawn at once, seeds seed .. seed + count - 1 (`variations`)
        self.variations: list[np.ndarray] = []  # the first is the session's synthesized follower
        self._drawn_for: np.ndarray | None = None  # the synthesized follower `variations` were drawn with
        self.compared: tuple[str, ...] = ()  # other models drawn beside the current one (`set_compared`), in the switch's order
        self.compared_followers: dict[str, np.ndarray] = {}  # their followers, drawn with the variations

    def set_count(self, n: int) -> None:
        """How many followers the session draws at once (1..MAX_VARIATIONS)."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= MAX_VARIATIONS:
            raise ValueError(f"variations: 1..{MAX_VARIATIONS} at once, not {n!r}")
        self.count = int(n)
        self.session.synthesize()

    def drawn(self, n: int) -> list[np.ndarray]:
        """The current leader and mix drawn with the seeds seed .. seed + n - 1 (the first is the synthesized follower);
        a deterministic model's n are the one reaction it gives."""
        ses = self.session
        if not 1 <= n <= MAX_VARIATIONS:
            raise ValueError(f"variations: 1..{MAX_VARIATIONS} at once, not {n}")
        seeds = check_seeds(ses.seed, n)
        if not ses.seeded or n == 1:
            return [ses.synth] * n
        rest = ses.model.synthesize_batch_canonical([ses.leader] * (n - 1), np.repeat(ses.vector[None], n - 1, 0), seeds[1:])
        return [ses.synth, *(np.asarray(f, np.float32) for f in rest)]

    def seeds(self) -> list[int]:
        return check_seeds(self.session.seed, len(self.variations) or 1)

    def follow(self, draw: bool) -> None:
        """After a new synthesized follower: draw the rest (`draw`, or when nothing waits to be drawn cheaply), or keep
        the previous ones beside the new first until `draw` is called (a slider's picture goes first)."""
        ses = self.session
        if draw or (not self.compared_names and (not ses.seeded or len(self.variations) != self.count)):
            self.draw()
        else:
            self.variations = [ses.synth, *self.variations[1:]]

    @property
    def due(self) -> bool:
        """True while the side-by-side followers are those of an earlier mix (`follow(False)`)."""
        return self._drawn_for is not self.session.synth

    def draw(self) -> None:
        """The followers beyond the synthesized one: the seeded model's variations and the compared models'."""
        ses = self.session
        self.variations = self.drawn(self.count) if ses.seeded else [ses.synth]
        self.compared_followers = self.followers_of(self.compared_names)
        self._drawn_for = ses.synth

    def set_compared(self, names: Sequence[str]) -> None:
        """Draw these models' followers beside the current one's (ValueError, one line, for an unknown name or too
        many: nothing changes). The current model among them is drawn once, as the synthesized follower."""
        models = self.session.models
        names = list(dict.fromkeys(str(n) for n in names))
        unknown = [n for n in names if n not in models]
        if unknown:
            raise ValueError(f"compare: no model {unknown[0]!r}; this studio has {', '.join(models)}")
        if len(names) > MAX_COMPARED:
            raise ValueError(f"compare: at most {MAX_COMPARED} models beside the current one, not {len(names)}")
        for name in names if self.session.label.parts_differ else ():  # as for a switch: a part mix is never approximated
            if not models[name].part_labels:
                raise LabelError(f"compare: {one_line(no_parts(models[name].title))}")
        self.compared = tuple(n for n in models if n in names)
        self.compared_followers = self.followers_of(self.compared_names)

    @property
    def compared_names(self) -> tuple[str, ...]:
        """The compared models but the current one (whose follower is the synthesized one)."""
        return tuple(n for n in self.compared if n != self.session.model_name)

    def followers_of(self, names: Sequence[str]) -> dict[str, np.ndarray]:
        """{name: that model's follower} for the current leader and mix, each with the session's seed where it takes
        one (and its own spread): what the session would draw after `set_model(name)`."""
        ses = self.session
        out = {}
        for name in names:
            follower = np.asarray(ses.models[name].synthesize_canonical(ses.leader, ses.vector, seed=ses.seed), np.float32)
            if follower.shape != ses.leader.shape:
                raise ValueError(f"model {name!r} returned shape {follower.shape}, expected {ses.leader.shape}")
            out[name] = follower
        return out

    def caption(self, name: str) -> str:
        """How the view captions a model's follower: its title, and the seed it was drawn with where it takes one."""
        ses = self.session
        return ses.model_title(name) + (f"\nseed {ses.seed}" if ses.models[name].settings.seed else "")
