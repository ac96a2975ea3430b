"""How the studio puts a session's labels and errors into words."""

from __future__ import annotations

from collections.abc import Sequence

from explorer.rendering.palette import display_name
from imm_model.data.labels import Label
from imm_model.errors import LabelError


def one_line(err: BaseException) -> str:
    """An error's message as the page and the launcher show it: its first line (a KeyError's key, not its repr)."""
    text = str(err.args[0] if isinstance(err, KeyError) and err.args else err) or type(err).__name__
    return text.strip().splitlines()[0]


def label_words(weights: Sequence[float], class_names: Sequence[str], scale: float = 1.0) -> str:
    """[0, 0, 1, 1, 0, 0] -> 'shaking hands +1, hugging +1' (scale shown when it is not 1)."""
    parts = [f"{display_name(n)} {w:+.2g}" for n, w in zip(class_names, weights, strict=True) if abs(w) > 1e-6]
    text = ", ".join(parts) if parts else "neutral (all classes 0)"
    if abs(scale - 1.0) > 1e-6:
        text += f"  × {scale:.2g}"
    return text


PART_WORDS = {"upper": "trunk and arms", "lower": "legs"}  # the body parts as the drawer names them


def mix_words(label: Label) -> str:
    """A mix in words: `label_words` for a whole-body mix; where the parts differ, the classes both parts share, then
    each part's own ("kicking +1 · trunk and arms: shaking hands +1 · legs: pushing -1  × 2")."""
    if not label.parts_differ:
        return label_words(label.parts[0], label.class_names, label.scale)
    upper, lower = label.parts
    shared = [u if u == lo else 0.0 for u, lo in zip(upper, lower, strict=True)]
    pieces = [label_words(shared, label.class_names)] if any(shared) else []
    for part, values in zip(PART_WORDS.values(), label.parts, strict=True):
        own = [v if u != lo else 0.0 for v, u, lo in zip(values, upper, lower, strict=True)]
        if any(own):
            pieces.append(f"{part}: {label_words(own, label.class_names)}")
    return " · ".join(pieces) + (f"  × {label.scale:.2g}" if abs(label.scale - 1.0) > 1e-6 else "")


def no_parts(title: str) -> LabelError:
    """Why a model (its title) without part labels cannot draw a part mix, in one line (and the way out)."""
    return LabelError(f"{title} takes no label per body part: link each class's parts (or reset the mix) first")
