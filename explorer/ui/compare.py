"""A/B compare: pin the current mix, move the sliders, and see both followers (the pinned one in purple, where
the synthesized one is) with the per-frame distance between them. "What does adding hugging change?"
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.panel_api import Page


class Compare:
    def __init__(self, page: Page, scene: Scene, *, set_label: Callable[..., None], update_review: Callable[[], None]):
        """`set_label(weights, scale)` moves the sliders; `update_review()` redraws the review panels."""
        self.page, self.scene = page, scene
        self.set_label, self.update_review = set_label, update_review
        page.ctrl.pin_mix = page.guarded(self.pin)
        page.ctrl.swap_mix = page.guarded(self.swap)
        page.ctrl.clear_pin = page.guarded(self.clear)

    def pin(self) -> None:
        self.page.session.pinned.pin()
        self.show()

    def swap(self) -> None:
        """The pinned mix goes back on the sliders and the current one is pinned in its place. A pinned mix the models
        drawing now cannot read (a part mix beside a model without part labels) is refused in one line, pin kept."""
        ses = self.page.session
        pinned = ses.pinned.label
        if pinned is None:
            return
        ses.check_label(pinned)
        ses.pinned.pin()
        self.show()
        self.set_label(pinned.mix, pinned.scale)  # re-synthesizes as a slider move does

    def clear(self) -> None:
        self.page.session.pinned.clear()
        self.show()

    def show(self) -> None:
        """Scene, label text and distance line after a pin, swap, clear or a new leader."""
        page, ses = self.page, self.page.session
        self.scene.set_pinned(ses.pinned.follower)
        page.state.pinned_text = ses.pinned.text()
        self.update_review()
        page.ctrl.view_update()
