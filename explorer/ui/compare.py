"""A/B compare: pin the current mix, move the sliders, and see both followers (the pinned one in purple, where
the synthesized one is) with the per-frame distance between them. "What does adding hugging change?"
"""

from __future__ import annotations


class Compare:
    def __init__(self, studio):
        self.studio = studio
        studio.ctrl.pin_mix = studio.guarded(self.pin)
        studio.ctrl.swap_mix = studio.guarded(self.swap)
        studio.ctrl.clear_pin = studio.guarded(self.clear)

    def pin(self) -> None:
        self.studio.session.pin()
        self.show()

    def swap(self) -> None:
        """The pinned mix goes back on the sliders and the current one is pinned in its place."""
        ses = self.studio.session
        if ses.pinned_weights is None:
            return
        weights, scale = ses.pinned_weights.copy(), ses.pinned_scale
        ses.pin()
        self.show()
        self.studio.set_label(weights, scale)  # re-synthesizes as a slider move does

    def clear(self) -> None:
        self.studio.session.clear_pin()
        self.show()

    def show(self) -> None:
        """Scene, label text and distance line after a pin, swap, clear or a new leader."""
        studio, ses = self.studio, self.studio.session
        studio.scene.set_pinned(ses.pinned)
        studio.state.pinned_text = ses.pinned_text()
        studio.update_review()
        studio.ctrl.view_update()
