"""The label, one value from where a user gives it to where a sampler reads it.

A label is signed and multi-hot: one value per class (+1 perform, 0 neutral, -1 avoid, fractions blend, beyond 1
exaggerates) for the upper body (trunk and arms) and one for the lower body (legs and where the follower stands), and a
scale every value is multiplied by. A class named alone is the whole body, "upper:<class>" or "lower:<class>" one part;
a part key overrides that part of its class. A label whose parts agree is a whole-body label: its vector is (C,); a
label per part is (2C,), the upper body's values, then the lower body's.

`Label` is parsed once at each edge, from what that edge holds, and passed as itself after:
- `Label.parse(text, names)`: `imm generate --label` ("kicking=1,upper:hugging=0.5", "1,0,0,0,0.5,0" or a class name);
- `Label.parse(text, names, value_sep=":")`: the studio's link (`mix=kicking:1,upper:hugging:0.5`);
- `Label.of(value, names)`: the API ({name: value}, a (C,) or (2C,) sequence, or a Label);
- `Label.of_parts(upper, lower, names, scale)`: the studio's sliders.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from imm_model.errors import LabelError, quoted

PARTS = ("upper", "lower")  # a part label's prefixes, in the order of a (2C,) label vector's halves
MAX_ITEMS = 512  # items in a label's text (a class and two parts each, for up to this many classes' worth)


@dataclass(frozen=True, eq=False)
class Label:
    """A signed multi-hot label per body part, unscaled, and its scale (see the module's docstring)."""

    class_names: tuple[str, ...]
    parts: np.ndarray = field(repr=False)  # (2, C) float64: the upper body's values, then the lower body's
    scale: float = 1.0

    def __post_init__(self) -> None:
        parts = np.array(self.parts, np.float64).reshape(2, len(self.class_names))
        parts.setflags(write=False)
        object.__setattr__(self, "parts", parts)
        object.__setattr__(self, "scale", number(self.scale, "scale"))
        if not (np.isfinite(parts).all() and np.isfinite(self.scale)):
            raise LabelError("label values must be finite (no NaN or infinity)")

    # ---- the edges ------------------------------------------------------------------------
    @classmethod
    def neutral(cls, class_names: Sequence[str]) -> Label:
        return cls(tuple(class_names), np.zeros((2, len(class_names))))

    @classmethod
    def of_parts(cls, upper: Sequence[float], lower: Sequence[float], class_names: Sequence[str], scale: float = 1.0) -> Label:
        """One value per class for each part (the studio's sliders)."""
        return cls(tuple(class_names), np.stack([_values(upper, "upper body"), _values(lower, "lower body")]), scale)

    @classmethod
    def of(cls, value: Label | Mapping | Sequence[float] | np.ndarray, class_names: Sequence[str], scale: float = 1.0) -> Label:
        """The API's label: a Label (its scale times `scale`), {class or part:class: value} (missing classes 0), or one
        value per class, (C,), or per class and part, (2C,)."""
        names = tuple(class_names)
        if isinstance(value, Label):
            if value.class_names != names:
                raise LabelError(f"the label's classes ({', '.join(value.class_names)}) are not the model's ({', '.join(names)})")
            return cls(names, value.parts, value.scale * number(scale, "scale"))
        if isinstance(value, Mapping):
            return cls._of_items(list(value.items()), names, scale)
        if isinstance(value, str | bytes):
            raise LabelError("a label is a mapping {class: value} or a sequence of numbers, not a string")
        vec = _values(value, "label")
        c = len(names)
        if vec.ndim != 1 or len(vec) not in (c, 2 * c):
            raise LabelError(f"label has shape {vec.shape}; expected {c} values ({', '.join(names)}), "
                             f"or {2 * c} (upper body's, then lower body's)")
        return cls(names, np.stack([vec[:c], vec[-c:]]), scale)

    @classmethod
    def parse(cls, text: str, class_names: Sequence[str], value_sep: str = "=") -> Label:
        """A label's text: comma-separated `key<value_sep>value` items (a key is a class, or upper:/lower: a class), or,
        with "=", one plain value per class (or per class and part) or a class name alone (at +1)."""
        names = tuple(class_names)
        items = [p.strip() for p in str(text).split(",") if p.strip()]
        if not items:
            raise LabelError("empty label: give class=value items (e.g. kicking=1), one value per class, or a class name")
        if len(items) > MAX_ITEMS:
            raise LabelError(f"label has {len(items)} items; at most {MAX_ITEMS}")
        if value_sep == "=" and not any("=" in p or ":" in p for p in items):
            if len(items) == 1:  # a class name alone (at +1), or a lone value
                try:
                    float(items[0])
                except ValueError:
                    return cls._of_items([(items[0], 1.0)], names, 1.0)
            return cls.of([number(p, f"value {i + 1}") for i, p in enumerate(items)], names)
        pairs = []
        for item in items:
            key, sep, value = item.rpartition(value_sep) if value_sep == ":" else item.partition(value_sep)
            if not sep or not key.strip() or (value_sep == "=" and key.count(":") > 1) or (value_sep == ":" and not value):
                raise LabelError(f"{quoted(item)} is not a label item: write class{value_sep}value, "
                                 f"upper:class{value_sep}value or lower:class{value_sep}value (e.g. kicking{value_sep}1)")
            pairs.append((key.strip(), value.strip()))
        return cls._of_items(pairs, names, 1.0)

    @classmethod
    def _of_items(cls, items: list[tuple], names: tuple[str, ...], scale: float) -> Label:
        """(key, value) pairs -> the label; every key once, a part key overriding one part of its class at most."""
        c = len(names)
        whole: dict[str, float] = {}
        per_part: dict[tuple[str, str], float] = {}
        for key, value in items:
            part, sep, name = key.partition(":") if isinstance(key, str) and ":" in key else ("", "", key)
            if not isinstance(name, str) or name not in names or (sep and part not in PARTS):
                raise LabelError(f"unknown class {quoted(key)}; classes: {', '.join(names)}, each alone or after "
                                 f"{' or '.join(p + ':' for p in PARTS)}")
            slot = (part, name) if sep else name
            if slot in per_part or slot in whole:
                raise LabelError(f"the label gives {key} twice; give each class (and part) once")
            (per_part if sep else whole)[slot] = number(value, str(key))
        for name in whole:
            if all((p, name) in per_part for p in PARTS):
                raise LabelError(f"{name} is given for the whole body and then for both parts apart; give {name} once, "
                                 "or each part")
        parts = np.zeros((2, c))
        for name, v in whole.items():
            parts[:, names.index(name)] = v
        for (part, name), v in per_part.items():
            parts[PARTS.index(part), names.index(name)] = v
        return cls(names, parts, scale)

    # ---- what it gives --------------------------------------------------------------------
    @property
    def parts_differ(self) -> bool:
        """True: a class weighs differently on the upper and the lower body (a label per part)."""
        return not np.array_equal(self.parts[0], self.parts[1])

    @property
    def mix(self) -> np.ndarray:
        """The values unscaled: (C,) when both parts agree, else (2C,) (upper's, lower's); float64."""
        return self.parts.reshape(-1).copy() if self.parts_differ else self.parts[0].copy()

    def vector(self) -> np.ndarray:
        """The values times the scale, as a model reads them: (C,) or (2C,) as `mix`; float64."""
        with np.errstate(all="ignore"):
            vec = self.mix * self.scale
        if not np.isfinite(vec).all():
            raise LabelError("label values times the scale must be finite")
        return vec

    def whole_body(self) -> np.ndarray:
        """(C,) one value per class, unscaled: where the parts differ, their mean."""
        return self.parts.mean(0)

    def scaled(self, scale: float) -> Label:
        """The same values under another scale."""
        return Label(self.class_names, self.parts, scale)

    def keys(self) -> dict[str, float]:
        """The nonzero values unscaled, as one spells them: a class where both parts agree, then "upper:<class>" and
        "lower:<class>" where they differ."""
        upper, lower = self.parts
        out = {n: float(u) for n, u, lo in zip(self.class_names, upper, lower, strict=True) if u == lo and u}
        for part, values in zip(PARTS, self.parts, strict=True):
            out |= {f"{part}:{n}": float(v) for n, v, u, lo in zip(self.class_names, values, upper, lower, strict=True)
                    if u != lo and v}
        return out

    def text(self, value_sep: str = "=") -> str:
        """"upper:shaking_hands=1,lower:pushing=-1" as `parse` reads it back (unscaled); "" when all zero."""
        return ",".join(f"{k}{value_sep}{v:g}" for k, v in self.keys().items())

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Label) and self.class_names == other.class_names
                and np.array_equal(self.parts, other.parts) and self.scale == other.scale)

    __hash__ = None  # a value compared by content, never a dict key


def label_text(vector: np.ndarray, class_names: Sequence[str]) -> str:
    """A label vector, (C,) or (2C,), -> its text (`Label.text`); "" when all zero."""
    return Label.of(np.asarray(vector, np.float64).reshape(-1), class_names).text()


def whole_body(labels: np.ndarray, num_classes: int) -> np.ndarray:
    """(N, C) or (N, 2C) label vectors -> (N, C): a part label as the mean of its two parts."""
    labels = np.asarray(labels)
    return labels if labels.shape[-1] == num_classes else 0.5 * (labels[..., :num_classes] + labels[..., num_classes:])


def number(value, name: str) -> float:
    """A label value (or the scale) -> float; LabelError naming it when it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise LabelError(f"value for {quoted(name)} is not a number: {quoted(value)}") from None


def _values(values, what: str) -> np.ndarray:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise LabelError(f"{what} values must be numbers") from None
