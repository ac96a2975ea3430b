"""The figures' captions, shown above them in the side-by-side layout: their text, size and which are on screen."""

from __future__ import annotations

import pyvista as pv

CAPTION_PX = 18  # the captions' text size for up to CAPTION_ROOM figures side by side; smaller with more (caption_px)
CAPTION_ROOM = 4


def caption_px(slots: int) -> int:
    """The captions' text size with `slots` figures side by side: as many captions side by side as fit the view."""
    return max(11, round(CAPTION_PX * CAPTION_ROOM / max(slots, CAPTION_ROOM)))


class Captions(dict):
    """{figure key: its caption, a pv.Label} in one plotter; hidden until the layout places them."""

    def __init__(self, plotter: pv.Plotter) -> None:
        super().__init__()
        self.plotter = plotter

    def add(self, key: str, text: str, color: str) -> None:
        label = pv.Label(text, size=CAPTION_PX)
        label.prop.bold = True
        label.prop.color = color
        label.prop.justification_horizontal = "center"
        label.SetVisibility(False)
        self.plotter.add_actor(label, reset_camera=False, render=False)
        self[key] = label

    def set_text(self, key: str, text: str) -> None:
        if self[key].input != text:  # a new text is rasterized again at the next render
            self[key].input = text

    def shown(self, keys) -> list[str]:
        """The texts of the captions of `keys` on screen, in that order."""
        return [self[k].input for k in keys if self[k].GetVisibility()]
