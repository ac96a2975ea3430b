"""One user's studio session without any UI: the chosen leader, the mixed label, the model drawing and the synthesized
follower. The page (explorer/ui/app.py) only maps this onto widgets, so all of it is unit-testable without a browser.

The session holds its rooms, each a small object reading the session's current leader, label and models:
`side_by_side` (variations and other models' followers), `pinned` (A/B), `readings` (what the follower reads as, its
distances and contact), `files` (exports) and `live` (the follower made frame by frame as the leader plays).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from explorer.rendering.palette import display_name
from explorer.session.files import FPS, SessionFiles
from explorer.session.live import LiveReaction
from explorer.session.pinned import PinnedMix
from explorer.session.readings import ReaderLike, Readings
from explorer.session.side_by_side import MAX_VARIATIONS, SideBySide
from explorer.session.uploads import Upload, read_upload
from explorer.session.words import mix_words, no_parts, one_line
from imm_model.data.dataset import InteractionDataset
from imm_model.data.labels import Label, whole_body
from imm_model.errors import CheckpointError, LabelError
from imm_model.families.base import Leader, SamplerSettings
from imm_model.inference import check_compatible, check_seeds

__all__ = ["FPS", "Session", "SequenceRow", "load_model", "one_line"]

NEW_SEEDS = 10_000  # "new variation" draws a seed below this: short enough to read, type and share in a link


class ReactionModelLike(Protocol):
    """What the studio needs from `imm_model.inference.ReactionModel`."""

    class_names: Sequence[str]
    skeleton: Any
    raw: bool  # True: the network's own follower, without the clean-up (imm_model/cleanup.py)
    title: str  # how people name the model's family ("the paper's GAN")
    part_labels: bool  # reads a label per body part ("upper:<class>", "lower:<class>"; imm_model/data/labels.py)
    settings: SamplerSettings  # the sampler settings it takes (a seed that picks among reactions, a spread, a memory)
    spread: float | None  # how loosely its sampler follows the leader, 0..1, settable; None: the model has no such setting
    draft: ReactionModelLike | None  # a faster model distilled from it, drawn while a slider moves; None: itself

    def label_vector(self, label: Any, scale: float = 1.0) -> np.ndarray: ...
    def prepare_leader(self, leader_world: np.ndarray) -> Leader: ...
    def provenance(self, seed: int) -> dict[str, Any]: ...
    def synthesize_canonical(self, leader: np.ndarray, label_vector: np.ndarray, seed: int = 0) -> np.ndarray: ...
    def synthesize_batch_canonical(self, leaders: list[np.ndarray], label_vectors: np.ndarray,
                                   seeds: Sequence[int] | None = None) -> list[np.ndarray]: ...
    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray: ...
    def online(self, label: Any, scale: float = 1.0, seed: int = 0) -> Any: ...
    def draft_for(self, frames: int) -> ReactionModelLike | None: ...


def load_model(checkpoint: Path, data: InteractionDataset) -> ReactionModelLike:
    """Load the checkpoint and refuse one that does not fit the data (one-line CheckpointError); a bundled student
    distilled from it becomes its draft (what a moving slider draws)."""
    from imm_model.families import attach_draft
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_STUDENT

    checkpoint = Path(checkpoint)
    if not checkpoint.exists():
        raise CheckpointError(f"{checkpoint}: checkpoint not found")
    model = ReactionModel.load(checkpoint, data=data.path)
    check_compatible(model, data, str(checkpoint))
    attach_draft(model, [SAMPLE_STUDENT])
    return model


@dataclass(frozen=True)
class SequenceRow:
    index: int
    sequence_id: str
    class_name: str
    subject_pair: str
    held_out: bool
    frames: int

    @property
    def title(self) -> str:
        mark = "  [held out]" if self.held_out else ""
        return f"{self.sequence_id} · {display_name(self.class_name)} · {self.frames} fr{mark}"

    @classmethod
    def all_of(cls, d: InteractionDataset) -> list[SequenceRow]:
        return [cls(i, d.sequence_ids[i], d.action_name(i), d.subject_pairs[i], bool(d.held_out[i]), int(d.lengths[i]))
                for i in range(len(d))]

    @classmethod
    def matching(cls, d: InteractionDataset, class_name: str | None = None, subject_pair: str | None = None,
                 held_out: bool | None = None) -> list[int]:
        """The indices of the sequences that pass every filter given."""
        return [r.index for r in cls.all_of(d) if (not class_name or r.class_name == class_name)
                and (not subject_pair or r.subject_pair == subject_pair) and (held_out is None or r.held_out == held_out)]


class Session:
    def __init__(self, data: InteractionDataset, models: Mapping[str, ReactionModelLike], index: int = 0,
                 reader: ReaderLike | None = None, part_readers: Mapping[str, ReaderLike] | None = None) -> None:
        """`models` by name, in the switch's order: the first opens the session (and is the one the latent map is of),
        the others are one switch away. `reader` reads the whole follower, `part_readers` ({"upper": ..., "lower": ...},
        the body-part judges) each part of a mix by body part."""
        if not models:
            raise ValueError("a session needs at least one model")
        self.models: dict[str, ReactionModelLike] = dict(models)
        for name, m in self.models.items():
            check_compatible(m, data, f"model {name!r}")
        for r in (reader, *(part_readers or {}).values()):
            if r is not None and tuple(r.class_names) != tuple(data.class_names):
                raise CheckpointError(f"the 'reads as' classifier's classes {list(r.class_names)} differ from the data's")
        self.data = data
        self.class_names = tuple(data.class_names)
        self.model_name = next(iter(self.models))
        self.model = self.models[self.model_name]
        self.map_model = self.model  # the latent map's embeddings and AFDs are this model's (explorer/session/latent.py)
        self.seed = 0  # the sampler's seed: which variation a seeded model draws
        self._seeds = np.random.default_rng()
        self.upload: Upload | None = None
        # reads an upload out of this process, within a time and memory budget (explorer/serving/upload_reader.py); None: here
        self.upload_reader: Callable[[str, bytes], Leader] | None = None
        # the mix: one weight per class and body part, and the scale (imm_model/data/labels.py); a class with both parts
        # alike is labelled for the whole body
        self.label = Label.neutral(self.class_names)
        self.vector = np.zeros(len(self.class_names), np.float32)  # the mix as the models read it, checked once per change
        self.index = -1
        self.synth: np.ndarray | None = None
        self.drafted = False  # `synth` is the model's draft's, until `settle` draws the model's own
        self.draws = 0  # followers drawn so far: what a follower made off the page's thread (`own_reaction`) replaces
        self.side_by_side = SideBySide(self)
        self.pinned = PinnedMix(self)
        self.readings = Readings(self, reader, dict(part_readers or {}))
        self.files = SessionFiles(self)
        self.live = LiveReaction(self)
        self.select(index)

    # ---- the leader ---------------------------------------------------------------------
    def select(self, index: int, match_label: bool = True) -> None:
        """Load sequence `index`; by default its own class becomes the label (the "match" preset)."""
        if not 0 <= index < len(self.data):
            raise IndexError(f"sequence {index} outside 0..{len(self.data) - 1}")
        self.index = int(index)
        self.upload = None
        self.current = Leader.of_sequence(self.data, self.index)
        self.ground_truth = self.data.canonical(self.index)[1]
        if match_label:
            self.match()
        else:
            self.synthesize()
        self.pinned.redraw()

    def load_upload(self, name: str, content: bytes) -> None:
        """Make an uploaded leader the current one (label kept). On any error nothing changes."""
        reader = self.upload_reader or (lambda n, c: read_upload(n, c, self.model))
        leader = reader(name, content)
        previous = (self.upload, self.current, self.ground_truth, self.synth)
        self.upload, self.current, self.ground_truth = Upload(Path(name).name, leader), leader, None
        try:
            self.synthesize()
        except Exception:
            self.upload, self.current, self.ground_truth, self.synth = previous
            raise
        self.pinned.redraw()

    @property
    def leader(self) -> np.ndarray:
        """The current leader (T, J, 3) in its canonical frame, float32 (what the models read and the view shows)."""
        return self.current.canonical

    @property
    def num_frames(self) -> int:
        return int(self.leader.shape[0])

    @property
    def own_class(self) -> int | None:
        """The current sequence's class (None for an uploaded leader: nobody labelled it)."""
        return None if self.upload else int(self.data.actions[self.index])

    @property
    def frame(self):
        """The current leader's canonical frame (data/canonical.py CanonicalFrame)."""
        return self.current.frame

    def world(self, canonical: np.ndarray) -> np.ndarray:
        """A (T, J, 3) motion of this sequence from the canonical frame back to world metres, float64."""
        return self.current.to_world(canonical, self.data.skeleton)

    # ---- the label ----------------------------------------------------------------------
    def match(self) -> np.ndarray:
        if self.own_class is None:
            return self.synthesize()
        return self.set_label(np.eye(len(self.class_names), dtype=np.float32)[self.own_class], 1.0)

    def reset(self) -> np.ndarray:
        return self.set_label(np.zeros(len(self.class_names), np.float32), 1.0)

    def set_label(self, label: Label | Sequence[float], scale: float | None = None, variations: bool = True,
                  draft: bool = False) -> np.ndarray:
        """The mix -> its follower: a Label, or one weight per class (C,) for the whole body or per class and part (2C,),
        the upper body's then the lower body's, with `scale` (default: the current one). Weights are the sliders',
        -1..1 (beyond is clipped). `variations` False: the side-by-side followers wait for `side_by_side.draw` (a
        slider's picture goes first). `draft`: the model's draft draws it, if it has one (a slider on the move), until
        `settle`. A mix a drawing model cannot read (a part mix beside a model without part labels, NaN) is refused
        (LabelError, one line): nothing changes."""
        if not isinstance(label, Label):
            w = np.asarray(label, np.float64).reshape(-1)
            c = len(self.class_names)
            if len(w) not in (c, 2 * c):
                raise ValueError(f"{len(w)} label weights for {c} classes (or {2 * c}: the upper body's, then the lower body's)")
            label = Label.of(w, self.class_names, self.scale if scale is None else scale)
        elif scale is not None:
            label = label.scaled(scale)
        label = Label(self.class_names, np.clip(label.parts, -1.0, 1.0).astype(np.float32), label.scale)  # the sliders' range and precision
        self.vector, self.label = self.check_label(label), label
        return self.synthesize(variations, draft)

    def check_label(self, label: Label) -> np.ndarray:
        """The label as the current model reads it (its vector), if every model drawing it can: a part mix is refused
        (LabelError, one line) while the current model or a compared one has no part labels."""
        vector = self.model.label_vector(label)
        for name in self.side_by_side.compared_names if label.parts_differ else ():
            if not self.models[name].part_labels:
                raise LabelError(f"compare: {one_line(no_parts(self.models[name].title))}")
        return vector

    @property
    def scale(self) -> float:
        return self.label.scale

    @property
    def weights(self) -> np.ndarray:
        """(C,) the mix as one weight per class: the whole body's (where the parts differ, their mean)."""
        return self.label.whole_body().astype(np.float32)

    @property
    def part_labels(self) -> bool:
        """True: the current model and every compared one read a label per body part (the page offers part mixes)."""
        return all(self.models[n].part_labels for n in (self.model_name, *self.side_by_side.compared_names))

    def label_text(self) -> str:
        return mix_words(self.label)

    def mix_latent(self) -> np.ndarray:
        """The current leader + mix in the latent space of the map's model (the star on the latent map), whichever
        model synthesizes: another model's latents are of another size and meaning. A map model without part labels
        places a part mix as its whole-body mean (the star is a place on the map, not a reaction drawn)."""
        vec = self.vector
        if not self.map_model.part_labels:
            vec = whole_body(vec, len(self.class_names)).astype(np.float32)
        return self.map_model.latent_canonical_batch([self.leader], vec[None, :])[0]

    # ---- the model and its settings -------------------------------------------------------
    @property
    def seeded(self) -> bool:
        """True: a seed picks one of the current model's many reactions (it draws variations)."""
        return self.model.settings.seed

    def model_title(self, name: str | None = None) -> str:
        """How the page names a model of the session (default: the current one): its family's title, and its name
        too when another model of the session has the same title."""
        name = self.model_name if name is None else name
        title = self.models[name].title
        twins = [n for n, m in self.models.items() if m.title == title]
        return f"{title} ({name})" if len(twins) > 1 else title

    def set_model(self, name: str) -> np.ndarray:
        """Synthesize with another of the session's models; the sequence, label, scale, seed, clean-up and pin stay.
        On any error the previous model stays."""
        if name not in self.models:
            raise ValueError(f"no model {name!r}; this studio has {', '.join(self.models)}")
        if name == self.model_name:
            return self.synth
        if self.label.parts_differ and not self.models[name].part_labels:
            # Refused rather than falling back to a whole-body mix: that fallback (each class at the mean of its parts)
            # is a label nobody asked for, which the link, the pin and an export would then carry silently; refused,
            # the part mix stays on the sliders and the message says how to switch.
            raise no_parts(self.models[name].title)
        previous = (self.model, self.model_name, self.synth, self.side_by_side.variations)
        self.models[name].raw = self.model.raw
        self.model, self.model_name = self.models[name], name
        try:
            return self.synthesize()
        except Exception:
            self.model, self.model_name, self.synth, self.side_by_side.variations = previous
            raise

    def set_seed(self, seed: int) -> np.ndarray:
        """Draw the variation `seed` picks (LabelError, one line, for a seed out of range: nothing changes)."""
        check_seeds(seed, MAX_VARIATIONS)  # room for the side-by-side variations after it
        self.seed = int(seed)
        return self.synthesize()

    def new_variation(self) -> np.ndarray:
        """A fresh seed: another reaction for the same leader and mix."""
        seed = self.seed
        while seed == self.seed:
            seed = int(self._seeds.integers(NEW_SEEDS))
        return self.set_seed(seed)

    @property
    def spread(self) -> float | None:
        """How loosely the current model follows the leader (0..1: wider variations as it grows); None: no such setting."""
        return self.model.spread

    def set_spread(self, level: float, synthesize: bool = True) -> None:
        """The current model's spread (LabelError, one line, for a model without one or a value outside 0..1: nothing
        changes); `synthesize` False: the caller draws the follower."""
        if not self.model.settings.spread:
            raise LabelError(f"{self.model_title()} has no spread setting")
        self.model.spread = level
        if synthesize:
            self.synthesize()

    def set_live(self, on: bool) -> None:
        """Live mode on (the follower made frame by frame as the leader plays, from its first frame; LabelError, one
        line, for a model that cannot react online) or off (the offline reaction again)."""
        if on:
            self.live.start()
        else:
            self.live.stop()
            self.synthesize()

    @property
    def cleaned_up(self) -> bool:
        return not self.model.raw

    def set_cleanup(self, on: bool) -> None:
        """Clean-up on (rigid bones, planted feet) or off (the network's own follower); both followers
        re-synthesized."""
        for model in self.models.values():
            model.raw = not on
        self.synthesize()
        self.pinned.redraw()

    # ---- synthesis ----------------------------------------------------------------------
    def synthesize(self, variations: bool = True, draft: bool = False) -> np.ndarray:
        """The follower for the current leader, mix, model and seed, and the followers beside it (`variations` False:
        those of the previous mix stay until `side_by_side.draw`). `draft`: drawn by the model's draft if it has one
        (not in live mode, whose frames are final), until `settle`."""
        drafting = self.model.draft_for(len(self.leader)) if draft and not self.live.on else None
        model = drafting or self.model
        out = self._checked(np.asarray(model.synthesize_canonical(self.leader, self.vector, seed=self.seed), np.float32))
        self.synth = self.live.follow(out) if self.live.on else out
        self.drafted = model is not self.model
        self.draws += 1
        self.side_by_side.follow(variations)  # other models' followers wait with the variations: each costs a reaction
        return out

    def settle(self, follower: np.ndarray | None = None, draws: int | None = None) -> bool:
        """The model's own follower in place of its draft's (the sliders rest), drawn now or given as `own_reaction`'s
        call made it for draw `draws`; False: there was no draft to replace, or another follower was drawn since."""
        if not self.drafted or (draws is not None and draws != self.draws):
            return False
        if follower is None:
            self.synthesize(variations=False)
            return True
        self.synth, self.drafted = self._checked(follower), False
        self.draws += 1
        self.side_by_side.follow(False)
        return True

    def _checked(self, follower: np.ndarray) -> np.ndarray:
        if follower.shape != self.leader.shape:
            raise ValueError(f"model returned shape {follower.shape}, expected {self.leader.shape}")
        return follower

    def own_reaction(self) -> tuple[int, Callable[[], np.ndarray]] | None:
        """What `settle` draws, as a call that reads nothing the session holds later, so that it may run on a worker
        thread (a long take's own reaction takes seconds, and the page answers meanwhile), with the draw it is to
        replace (`settle(follower, draws)`); None: no draft is shown."""
        if not self.drafted:
            return None
        model, leader, vector, seed = self.model, self.leader, self.vector.copy(), self.seed
        return self.draws, lambda: np.asarray(model.synthesize_canonical(leader, vector, seed=seed), np.float32)
