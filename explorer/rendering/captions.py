"""The figures' captions, shown above them in the side-by-side layout: their text, size and which are on screen, and
how each fits the room between its neighbours (Captions.fit, at every render)."""

from __future__ import annotations

import math

import pyvista as pv
from vtkmodules.vtkRenderingCore import vtkTextProperty, vtkTextRenderer

CAPTION_PX = 18  # the captions' text size for up to CAPTION_ROOM figures side by side; smaller with more (caption_px)
CAPTION_ROOM = 4
MIN_PX = 8  # a caption shrinks to fit down to this size; below it, its lines are cut ("…")
GAP_PX = 8  # between two captions' texts, at the least
SEPARATOR = " · "  # where a caption's line may break when it is too wide
ELLIPSIS = "…"


def caption_px(slots: int) -> int:
    """The captions' text size with `slots` figures side by side: as many captions side by side as fit the view."""
    return max(11, round(CAPTION_PX * CAPTION_ROOM / max(slots, CAPTION_ROOM)))


class Captions(dict):
    """{figure key: its caption, a pv.Label} in one plotter; hidden until the layout places them."""

    def __init__(self, plotter: pv.Plotter) -> None:
        super().__init__()
        self.plotter = plotter
        self.texts: dict[str, str] = {}  # each caption's whole text (the label may show it wrapped or cut: fit)
        self.base = CAPTION_PX  # the size of every caption before it is fitted (set_base)
        self.fitted: dict[str, int] = {}  # the size fit (or set_base) gave each caption

    def add(self, key: str, text: str, color: str) -> None:
        label = pv.Label(text, size=CAPTION_PX)
        label.prop.bold = True
        label.prop.color = color
        label.prop.justification_horizontal = "center"
        label.SetVisibility(False)
        self.plotter.add_actor(label, reset_camera=False, render=False)
        self[key], self.texts[key] = label, text

    def set_text(self, key: str, text: str) -> None:
        self.texts[key] = text
        _show(self[key], text)

    def shown(self, keys) -> list[str]:
        """The texts of the captions of `keys` on screen, in that order (whole, however the view fits them)."""
        return [self.texts[k] for k in keys if self[k].GetVisibility()]

    def set_base(self, size: int) -> None:
        """Every caption back at its size before fitting (caption_px of the figures side by side), but while a picture
        drawn smaller is rendered (playing: the camera refits and places the figures again inside that render): the
        sizes texts_scaled gave, no longer those fit gave, stay."""
        self.base = size
        for k, label in self.items():
            prop = label.GetTextProperty()
            if prop.GetFontSize() == self.fitted.get(k, prop.GetFontSize()):
                prop.SetFontSize(size)
                self.fitted[k] = size

    def fit(self, renderer) -> None:
        """Each caption on screen within the room its neighbours leave it along the picture's width, so that no two
        run into each other at any window size: at the base size if it fits, else with its parts on lines of their own,
        else smaller (fitting). A picture drawn smaller while playing (explorer/rendering/view_stream.py texts_scaled)
        has scaled the sizes given here: its captions stay as scaled, the same size in the picture as when paused."""
        shown, base = [k for k, label in self.items() if label.GetVisibility()], self.base
        if any(self[k].GetTextProperty().GetFontSize() != self.fitted.get(k, base) for k in shown):
            return
        x = {k: _display(renderer, self[k].position)[0] for k in shown}
        order = sorted(shown, key=x.get)
        dpi = renderer.GetRenderWindow().GetDPI()
        for i, k in enumerate(order):
            neighbours = [abs(x[k] - x[j]) for j in (order[i - 1] if i else None, order[i + 1] if i + 1 < len(order) else None) if j]
            text, size = fitting(self[k].GetTextProperty(), self.texts[k], base, min(neighbours, default=math.inf) - GAP_PX, dpi)
            _show(self[k], text)
            self[k].GetTextProperty().SetFontSize(size)
            self.fitted[k] = size

    def boxes(self, renderer) -> dict[str, tuple[float, float, float, float]]:
        """{key: (left, right, bottom, top)} of each caption on screen, in the picture's pixels (as of the last render)."""
        out = {}
        for k, label in self.items():
            if label.GetVisibility():
                box = [0.0] * 4
                label.GetBoundingBox(renderer, box)  # around the caption's anchor
                x, y = _display(renderer, label.position)
                out[k] = (x + box[0], x + box[1], y + box[2], y + box[3])
        return out


def fitting(prop, text: str, base: int, room: float, dpi: int) -> tuple[str, int]:
    """The text and size a caption is drawn with to be at most `room` pixels wide: `text` at `base` size if it fits,
    else broken into lines at its SEPARATORs, else those lines smaller, down to MIN_PX, else those cut with "…"."""
    wrapped = text.replace(SEPARATOR, "\n")
    for shown in dict.fromkeys((text, wrapped)):
        if _width(prop, shown, base, dpi) <= room:
            return shown, base
    size = max(MIN_PX, min(base - 1, math.floor(base * room / _width(prop, wrapped, base, dpi))))
    while size > MIN_PX and _width(prop, wrapped, size, dpi) > room:  # text does not shrink quite in proportion
        size -= 1
    if _width(prop, wrapped, size, dpi) <= room:
        return wrapped, size
    return "\n".join(_cut(prop, line, size, room, dpi) for line in wrapped.split("\n")), size


def _cut(prop, line: str, size: int, room: float, dpi: int) -> str:
    """`line`, or its longest start that fits `room` with "…" after it."""
    while len(line) > 1 and _width(prop, line, size, dpi) > room:
        line = line[:-2].rstrip() + ELLIPSIS
    return line


_SCRATCH = vtkTextProperty()  # measures a text at another size than its caption's


def _width(prop, text: str, size: int, dpi: int) -> int:
    _SCRATCH.ShallowCopy(prop)
    _SCRATCH.SetFontSize(size)
    box = [0] * 4
    vtkTextRenderer.GetInstance().GetBoundingBox(_SCRATCH, text, box, dpi)
    return box[1] - box[0]


def _show(label: pv.Label, text: str) -> None:
    if label.input != text:  # a new text is rasterized again at the next render
        label.input = text


def _display(renderer, point) -> tuple[float, float]:
    renderer.SetWorldPoint(*point, 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    return x, y
