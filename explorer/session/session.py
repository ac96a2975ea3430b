"""One user's studio session without any UI: the chosen sequence, the mixed label, the synthesized
follower and its review numbers. The page (explorer/ui/app.py) only maps this onto widgets, so all of it is
unit-testable without a browser.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from explorer.rendering.palette import display_name
from imm_model.data.dataset import InteractionDataset
from imm_model.data.labels import Label, whole_body
from imm_model.errors import CheckpointError, DataFormatError, IMMError, LabelError
from imm_model.evaluation.metrics import afd
from imm_model.families.base import Leader, SamplerSettings
from imm_model.inference import check_compatible, check_seeds

FPS = 15.0  # SBU's frame rate
MAX_UPLOAD_BYTES = 20_000_000
UPLOAD_SUFFIXES = (".bvh", ".npz", ".txt")
MAX_VARIATIONS = 4  # followers drawn side by side at once (seeds seed .. seed + 3)
MAX_COMPARED = 3  # other models whose followers are drawn beside the current one's at once
NEW_SEEDS = 10_000  # "new variation" draws a seed below this: short enough to read, type and share in a link


def one_line(err: BaseException) -> str:
    """An error's message as the page and the launcher show it: its first line (a KeyError's key, not its repr)."""
    text = str(err.args[0] if isinstance(err, KeyError) and err.args else err) or type(err).__name__
    return text.strip().splitlines()[0]


@dataclass(frozen=True)
class Upload:
    """A leader file from the page: shown with the synthesized follower only (there is no ground truth)."""

    name: str
    leader: Leader


def read_upload(name: str, content: bytes, model: ReactionModelLike) -> Leader:
    """An uploaded .bvh / .npz / SBU .txt -> the leader, checked and standardized by the model (`prepare_leader`).
    Every problem is a one-line IMMError naming it (size, type, content, length)."""
    import tempfile

    from imm_model.data.leader_file import read_leader_file

    suffix = Path(name).suffix.lower()
    if suffix not in UPLOAD_SUFFIXES:
        raise DataFormatError(f"{name}: unsupported file type; upload a {', '.join(UPLOAD_SUFFIXES)} leader")
    if len(content) > MAX_UPLOAD_BYTES:
        raise DataFormatError(f"{name}: {len(content) / 1e6:.0f} MB; uploads up to {MAX_UPLOAD_BYTES / 1e6:.0f} MB are accepted")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"upload{suffix}"
        path.write_bytes(content)
        try:
            return model.prepare_leader(read_leader_file(path))
        except IMMError as err:
            raise DataFormatError(f"{name}: {str(err).replace(str(path), '').lstrip(': ')}") from None


class ReactionModelLike(Protocol):
    """What the studio needs from `imm_model.inference.ReactionModel`."""

    class_names: Sequence[str]
    skeleton: Any
    raw: bool  # True: the network's own follower, without the clean-up (imm_model/cleanup.py)
    title: str  # how people name the model's family ("the paper's GAN")
    part_labels: bool  # reads a label per body part ("upper:<class>", "lower:<class>"; imm_model/data/labels.py)
    settings: SamplerSettings  # the sampler settings it takes (a seed that picks among reactions, a spread, a memory)
    spread: float | None  # how loosely its sampler follows the leader, 0..1, settable; None: the model has no such setting

    def label_vector(self, label: Any, scale: float = 1.0) -> np.ndarray: ...
    def prepare_leader(self, leader_world: np.ndarray) -> Leader: ...
    def provenance(self, seed: int) -> dict[str, Any]: ...
    def synthesize_canonical(self, leader: np.ndarray, label_vector: np.ndarray, seed: int = 0) -> np.ndarray: ...
    def synthesize_batch_canonical(self, leaders: list[np.ndarray], label_vectors: np.ndarray,
                                   seeds: Sequence[int] | None = None) -> list[np.ndarray]: ...
    def latent_canonical_batch(self, leaders: list[np.ndarray], label_vectors: np.ndarray) -> np.ndarray: ...


def load_model(checkpoint: Path, data: InteractionDataset) -> ReactionModelLike:
    """Load the checkpoint and refuse one that does not fit the data (one-line CheckpointError)."""
    from imm_model.inference import ReactionModel

    checkpoint = Path(checkpoint)
    if not checkpoint.exists():
        raise CheckpointError(f"{checkpoint}: checkpoint not found")
    model = ReactionModel.load(checkpoint, data=data.path)
    check_compatible(model, data, str(checkpoint))
    return model


def label_words(weights: Sequence[float], class_names: Sequence[str], scale: float = 1.0) -> str:
    """[0, 0, 1, 1, 0, 0] -> 'shaking hands +1, hugging +1' (scale shown when it is not 1)."""
    parts = [f"{display_name(n)} {w:+.2g}" for n, w in zip(class_names, weights, strict=True) if abs(w) > 1e-6]
    text = ", ".join(parts) if parts else "neutral (all classes 0)"
    if abs(scale - 1.0) > 1e-6:
        text += f"  × {scale:.2g}"
    return text


def mix_words(label: Label) -> str:
    """A mix in words: `label_words` for a whole-body mix, the part keys as `imm generate --label` spells them where the
    parts differ ("upper:shaking_hands=1,lower:pushing=-1  × 2")."""
    if not label.parts_differ:
        return label_words(label.parts[0], label.class_names, label.scale)
    return label.text() + (f"  × {label.scale:.2g}" if abs(label.scale - 1.0) > 1e-6 else "")


def no_parts(model: ReactionModelLike) -> LabelError:
    """Why a model without part labels cannot draw a part mix, in one line (and the way out)."""
    return LabelError(f"{model.title} takes no label per body part: link each class's parts (or reset the mix) first")


def mean_joint_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T, J, 3) twice -> (T,) the mean over joints of the distance between corresponding joints."""
    return np.linalg.norm(np.asarray(a, np.float64) - np.asarray(b, np.float64), axis=-1).mean(-1)


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


class ReaderLike(Protocol):
    """What the studio needs from `imm_model.reads_as.ReadsAs`."""

    class_names: Sequence[str]

    def probabilities(self, follower: np.ndarray) -> np.ndarray: ...


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
        self.model_name = next(iter(self.models))
        self.model = self.models[self.model_name]
        self.map_model = self.model  # the latent map's embeddings and AFDs are this model's (explorer/session/latent.py)
        self.seed = 0  # the sampler's seed: which variation a seeded model draws
        self.variation_count = 1  # followers drawn at once, seeds seed .. seed + count - 1 (`variations`)
        self.variation_followers: list[np.ndarray] = []
        self._variations_of: np.ndarray | None = None  # the follower `variation_followers` were drawn with
        self.compared: tuple[str, ...] = ()  # other models drawn beside the current one (set_compared), in the switch's order
        self.compared_followers: dict[str, np.ndarray] = {}  # their followers, drawn with the variations
        self._seeds = np.random.default_rng()
        self.reader = reader
        self.part_readers = dict(part_readers or {})
        self.upload: Upload | None = None
        # reads an upload out of this process, within a time and memory budget (explorer/serving/upload_reader.py); None: here
        self.upload_reader: Callable[[str, bytes], Leader] | None = None
        self.class_names = tuple(data.class_names)
        # the mix: one weight per class and body part, and the scale (imm_model/data/labels.py); a class with both parts
        # alike is labelled for the whole body
        self.label = Label.neutral(self.class_names)
        self.vector = np.zeros(len(self.class_names), np.float32)  # the mix as the models read it, checked once per change
        self.index = -1
        self.synth: np.ndarray | None = None
        # A/B: a pinned mix and its follower for the current leader (None: nothing pinned)
        self.pinned_label: Label | None = None
        self.pinned_vector = self.vector
        self.pinned_model = self.model_name  # the pinned follower keeps its model, seed and spread: A/B can compare models
        self.pinned_seed = 0
        self.pinned_spread: float | None = None
        self.pinned: np.ndarray | None = None
        self.select(index)

    # ---- sequences ----------------------------------------------------------------------
    def rows(self) -> list[SequenceRow]:
        d = self.data
        return [
            SequenceRow(i, d.sequence_ids[i], d.action_name(i), d.subject_pairs[i], bool(d.held_out[i]), int(d.lengths[i]))
            for i in range(len(d))
        ]

    def filter(self, class_name: str | None = None, subject_pair: str | None = None, held_out: bool | None = None) -> list[int]:
        return [
            r.index
            for r in self.rows()
            if (not class_name or r.class_name == class_name)
            and (not subject_pair or r.subject_pair == subject_pair)
            and (held_out is None or r.held_out == held_out)
        ]

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
        self._synthesize_pinned()

    @property
    def leader(self) -> np.ndarray:
        """The current leader (T, J, 3) in its canonical frame, float32 (what the models read and the view shows)."""
        return self.current.canonical

    @property
    def num_frames(self) -> int:
        return int(self.leader.shape[0])

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
        self._synthesize_pinned()

    @property
    def own_class(self) -> int | None:
        """The current sequence's class (None for an uploaded leader: nobody labelled it)."""
        return None if self.upload else int(self.data.actions[self.index])

    @property
    def frame(self):
        """The current leader's canonical frame (data/canonical.py CanonicalFrame)."""
        return self.current.frame

    # ---- label --------------------------------------------------------------------------
    def match(self) -> np.ndarray:
        if self.own_class is None:
            return self.synthesize()
        w = np.zeros(len(self.class_names), np.float32)
        w[self.own_class] = 1.0
        return self.set_label(w, 1.0)

    def reset(self) -> np.ndarray:
        return self.set_label(np.zeros(len(self.class_names), np.float32), 1.0)

    def set_label(self, label: Label | Sequence[float], scale: float | None = None, variations: bool = True) -> np.ndarray:
        """The mix -> its follower: a Label, or one weight per class (C,) for the whole body or per class and part (2C,),
        the upper body's then the lower body's, with `scale` (default: the current one). Weights are the sliders',
        -1..1 (beyond is clipped). `variations` False: the side-by-side variations wait for `draw_variations` (a
        slider's picture goes first). A mix a drawing model cannot read (a part mix beside a model without part labels,
        NaN) is refused (LabelError, one line): nothing changes."""
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
        return self.synthesize(variations)

    def check_label(self, label: Label) -> np.ndarray:
        """The label as the current model reads it (its vector), if every model drawing it can: a part mix is refused
        (LabelError, one line) while the current model or a compared one has no part labels."""
        vector = self.model.label_vector(label)
        for name in self.compared_names if label.parts_differ else ():
            if not self.models[name].part_labels:
                raise LabelError(f"compare: {one_line(no_parts(self.models[name]))}")
        return vector

    @property
    def scale(self) -> float:
        return self.label.scale

    @property
    def part_weights(self) -> np.ndarray:
        """(2, C) the mix's weights, the upper body's then the lower body's."""
        return self.label.parts

    @property
    def weights(self) -> np.ndarray:
        """(C,) the mix as one weight per class: the whole body's (where the parts differ, their mean)."""
        return self.label.whole_body().astype(np.float32)

    @property
    def parts_differ(self) -> bool:
        """True: a class weighs differently on the upper and the lower body (the mix is a label per part)."""
        return self.label.parts_differ

    @property
    def part_labels(self) -> bool:
        """True: the current model and every compared one read a label per body part (the page offers part mixes)."""
        return all(self.models[n].part_labels for n in (self.model_name, *self.compared_names))

    def mix(self) -> np.ndarray:
        """The mix unscaled, as `set_label` takes it: (C,) when both parts are alike, else (2C,) (upper's, lower's)."""
        return self.label.mix

    def label_keys(self) -> dict[str, float]:
        """The mix unscaled, as one spells it: {"kicking": 1, "upper:shaking_hands": 1, "lower:pushing": -1}."""
        return self.label.keys()

    def label_vector(self) -> np.ndarray:
        """The mix (weights times scale) as every model drawing it reads it: (C,), or (2C,) for a part mix (only part
        models draw one)."""
        return self.vector

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

    # ---- models and variations ------------------------------------------------------------
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
        if self.parts_differ and not self.models[name].part_labels:
            # Refused rather than falling back to a whole-body mix: that fallback (each class at the mean of its parts)
            # is a label nobody asked for, which the link, the pin and an export would then carry silently; refused,
            # the part mix stays on the sliders and the message says how to switch.
            raise no_parts(self.models[name])
        previous = (self.model, self.model_name, self.synth, self.variation_followers)
        self.models[name].raw = self.model.raw
        self.model, self.model_name = self.models[name], name
        try:
            return self.synthesize()
        except Exception:
            self.model, self.model_name, self.synth, self.variation_followers = previous
            raise

    def set_seed(self, seed: int) -> np.ndarray:
        """Draw the variation `seed` picks (LabelError, one line, for a seed out of range: nothing changes)."""
        check_seeds(seed, MAX_VARIATIONS)  # room for the side-by-side variations after it
        self.seed = int(seed)
        return self.synthesize()

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

    def new_variation(self) -> np.ndarray:
        """A fresh seed: another reaction for the same leader and mix."""
        seed = self.seed
        while seed == self.seed:
            seed = int(self._seeds.integers(NEW_SEEDS))
        return self.set_seed(seed)

    def set_variation_count(self, n: int) -> None:
        """How many followers `synthesize` draws at once (1..MAX_VARIATIONS)."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 1 <= n <= MAX_VARIATIONS:
            raise ValueError(f"variations: 1..{MAX_VARIATIONS} at once, not {n!r}")
        self.variation_count = int(n)
        self.synthesize()

    def variations(self, n: int) -> list[np.ndarray]:
        """The current leader and mix drawn with the seeds seed .. seed + n - 1 (the first is `synth`); a deterministic
        model's n are the one reaction it gives."""
        if not 1 <= n <= MAX_VARIATIONS:
            raise ValueError(f"variations: 1..{MAX_VARIATIONS} at once, not {n}")
        seeds = check_seeds(self.seed, n)
        if not self.seeded or n == 1:
            return [self.synth] * n
        rest = self.model.synthesize_batch_canonical([self.leader] * (n - 1), np.repeat(self.vector[None], n - 1, 0), seeds[1:])
        return [self.synth, *(np.asarray(f, np.float32) for f in rest)]

    def variation_seeds(self) -> list[int]:
        return check_seeds(self.seed, len(self.variation_followers) or 1)

    # ---- synthesis and review -----------------------------------------------------------
    def synthesize(self, variations: bool = True) -> np.ndarray:
        """The follower for the current leader, mix, model and seed, and its side-by-side variations (`variations`
        False: those of the previous mix stay until `draw_variations`)."""
        out = np.asarray(self.model.synthesize_canonical(self.leader, self.vector, seed=self.seed), np.float32)
        if out.shape != self.leader.shape:
            raise ValueError(f"model returned shape {out.shape}, expected {self.leader.shape}")
        self.synth = out
        # other models' followers wait with the variations (`variations` False): each costs a reaction
        if variations or (not self.compared_names and (not self.seeded or len(self.variation_followers) != self.variation_count)):
            self.draw_variations()
        else:
            self.variation_followers = [out, *self.variation_followers[1:]]
        return out

    @property
    def variations_due(self) -> bool:
        """True while the side-by-side variations are those of an earlier mix (set_label(..., variations=False))."""
        return self._variations_of is not self.synth

    def draw_variations(self) -> None:
        """The side-by-side followers beyond `synth`: the seeded model's variations and the compared models'."""
        self.variation_followers = self.variations(self.variation_count) if self.seeded else [self.synth]
        self.compared_followers = self.followers_of(self.compared_names)
        self._variations_of = self.synth

    # ---- other models beside the current one ----------------------------------------------------
    def set_compared(self, names: Sequence[str]) -> None:
        """Draw these models' followers beside the current one's (ValueError, one line, for an unknown name or too
        many: nothing changes). The current model among them is drawn once, as the synthesized follower."""
        names = list(dict.fromkeys(str(n) for n in names))
        unknown = [n for n in names if n not in self.models]
        if unknown:
            raise ValueError(f"compare: no model {unknown[0]!r}; this studio has {', '.join(self.models)}")
        if len(names) > MAX_COMPARED:
            raise ValueError(f"compare: at most {MAX_COMPARED} models beside the current one, not {len(names)}")
        for name in names if self.parts_differ else ():  # as for a switch (set_model): a part mix is never approximated
            if not self.models[name].part_labels:
                raise LabelError(f"compare: {one_line(no_parts(self.models[name]))}")
        self.compared = tuple(n for n in self.models if n in names)
        self.compared_followers = self.followers_of(self.compared_names)

    @property
    def compared_names(self) -> tuple[str, ...]:
        """The compared models but the current one (whose follower is `synth`)."""
        return tuple(n for n in self.compared if n != self.model_name)

    def followers_of(self, names: Sequence[str]) -> dict[str, np.ndarray]:
        """{name: that model's follower} for the current leader and mix, each with the session's seed where it takes
        one (and its own spread): what `synthesize` would draw after `set_model(name)`."""
        out = {}
        for name in names:
            model = self.models[name]
            follower = np.asarray(model.synthesize_canonical(self.leader, self.vector, seed=self.seed), np.float32)
            if follower.shape != self.leader.shape:
                raise ValueError(f"model {name!r} returned shape {follower.shape}, expected {self.leader.shape}")
            out[name] = follower
        return out

    def compared_caption(self, name: str) -> str:
        """How the view captions a model's follower: its title, and the seed it was drawn with where it takes one."""
        return self.model_title(name) + (f"\nseed {self.seed}" if self.models[name].settings.seed else "")

    @property
    def cleaned_up(self) -> bool:
        return not self.model.raw

    def set_cleanup(self, on: bool) -> None:
        """Clean-up on (rigid bones, planted feet) or off (the network's own follower); both followers
        re-synthesized."""
        for model in self.models.values():
            model.raw = not on
        self.synthesize()
        self._synthesize_pinned()

    # ---- A/B: a pinned mix beside the current one ---------------------------------------------
    def pin(self) -> None:
        """Keep the current mix and its follower, to compare the next mixes with."""
        self.pinned_label, self.pinned = self.label, self.synth.copy()
        self.pinned_vector = self.vector.copy()
        self.pinned_model, self.pinned_seed, self.pinned_spread = self.model_name, self.seed, self.spread

    def clear_pin(self) -> None:
        self.pinned_label = self.pinned = None

    def _synthesize_pinned(self) -> None:
        """The pinned mix for a new leader (the comparison follows the sequence)."""
        if self.pinned_label is not None:
            model = self.models[self.pinned_model]
            vec = self.pinned_vector
            spread = model.spread
            if spread is not None:
                model.spread = self.pinned_spread
            try:
                self.pinned = np.asarray(model.synthesize_canonical(self.leader, vec, seed=self.pinned_seed), np.float32)
            finally:
                if spread is not None:
                    model.spread = spread

    def pinned_text(self) -> str:
        """The pinned mix in words, and its model (and seed) when they are not the current ones."""
        if self.pinned_label is None:
            return ""
        text = mix_words(self.pinned_label)
        if self.pinned_model != self.model_name:
            text += f" · {self.model_title(self.pinned_model)}"
        if self.models[self.pinned_model].settings.seed and (self.pinned_model != self.model_name or self.pinned_seed != self.seed):
            text += f" · seed {self.pinned_seed}"
        if self.pinned_spread is not None and (self.pinned_model != self.model_name or self.pinned_spread != self.spread):
            text += f" · spread {self.pinned_spread:.2g}"
        return text

    def ab_distances_m(self) -> np.ndarray:
        """(T,) per frame, how far the pinned follower's joints are from the current one's on average, metres (empty
        when none is pinned)."""
        return np.zeros(0) if self.pinned is None else mean_joint_distances(self.synth, self.pinned)

    def contact(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Leader vs synthesized follower -> closest limb distance per frame (T,) in metres, and the leader's and the
        follower's bones (T, K) closer than the evaluation's interpenetration threshold to the other body."""
        from imm_model.evaluation.plausibility import penetrating_bones

        return penetrating_bones(self.leader, self.synth, self.data.skeleton)

    def reads_as(self) -> np.ndarray | None:
        """(C,) the follower-only classifier's class probabilities for the synthesized follower (None without one)."""
        return None if self.reader is None else np.asarray(self.reader.probabilities(self.synth), np.float64)

    def reads_as_parts(self) -> dict[str, np.ndarray]:
        """{"upper": (C,), "lower": (C,)}: each body-part judge's reading of the synthesized follower while the mix's
        parts differ ({} when they do not, or without part judges)."""
        if not self.parts_differ:
            return {}
        return {part: np.asarray(r.probabilities(self.synth), np.float64) for part, r in self.part_readers.items()}

    def distances_m(self) -> np.ndarray:
        """(T,) per frame, how far the synthesized follower's joints are from the ground truth's on average, metres
        (a distance one sees in the view, where the 45-d pose-vector norm of the metrics is ~sqrt(15) times larger)."""
        return np.zeros(0) if self.ground_truth is None else mean_joint_distances(self.synth, self.ground_truth)

    def afd(self) -> float | None:
        """The paper's AFD (SBU normalized units) of the synthesized follower against ground truth."""
        if self.ground_truth is None:
            return None
        return afd(self.synth, self.ground_truth, self.frame, self.data.skeleton, units="normalized")

    def world(self, canonical: np.ndarray) -> np.ndarray:
        """A (T, J, 3) motion of this sequence from the canonical frame back to world metres, float64."""
        return self.current.to_world(canonical, self.data.skeleton)

    def export_npz(self) -> bytes:
        """The synthesized interaction as an .npz file's bytes (imm_model/interaction_file.py, docs/formats.md)."""
        from imm_model.interaction_file import interaction_arrays, interaction_bytes

        path = getattr(self.model, "path", None)
        return interaction_bytes(interaction_arrays(
            self.world(self.leader), self.world(self.synth), self.frame, self.data.skeleton,
            class_names=self.class_names, label=self.vector, scale=self.scale, checkpoint=Path(path).name if path else "",
            fps=FPS, ground_truth=None if self.ground_truth is None else self.world(self.ground_truth),
            sequence_id=None if self.upload else self.data.sequence_ids[self.index], **self.model.provenance(self.seed)))

    def export_bvh(self, character: str = "follower") -> bytes:
        """The synthesized follower (or the leader) as a BVH file's bytes, world metres (imm_model/data/bvh.py)."""
        import tempfile

        from imm_model.data.bvh import write_bvh

        motion = self.world(self.synth if character == "follower" else self.leader)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "x.bvh"
            write_bvh(path, motion, self.data.skeleton, FPS)
            return path.read_bytes()

    def export_name(self, ext: str) -> str:
        sid = Path(self.upload.name).stem if self.upload else self.data.sequence_ids[self.index].replace("/", "-")
        mix = "_".join(f"{k}{w:+g}" for k, w in self.label_keys().items()) or "neutral"
        return f"{sid}_{mix}.{ext}"
