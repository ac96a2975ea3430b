"""The Label mix drawer: one slider per class (a class's parts set apart: its upper and lower body's), and a scale,
onto the session's label (imm_model/data/labels.py) and back. A slider's message re-synthesizes at once: the latest
mix wins, at most one synthesis is in flight, and the review panels follow the picture."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from trame.app import asynchronous

from imm_model.data.labels import Label, number
from imm_model.errors import LabelError

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.model_switch import ModelSwitch
    from explorer.ui.panel_api import Page

PICTURE_S = 0.04  # after a new mix, the time its picture takes to leave (the next mix waits for it)
REVIEW_DELAY_S = 0.1  # ... and the time until the 'reads as' panel, distance chart, AFD and latent star follow it


class LabelMixer:
    def __init__(self, page: Page, scene: Scene, model_switch: ModelSwitch, *, update_review: Callable[[], None]):
        """`update_review()` redraws the panels that read the follower (after the picture)."""
        self.page, self.scene, self.model_switch, self.update_review = page, scene, model_switch, update_review
        self._pending = False
        self._task = None
        s, n = page.state, len(page.session.class_names)
        for i in range(n):  # a class's slider (the whole body; with its parts apart, the upper body) and its lower body's
            s[f"w_{i}"] = s[f"lower_{i}"] = 0.0
            s[f"apart_{i}"] = False
        s.change(*[f"{k}_{i}" for k in ("w", "lower", "apart") for i in range(n)], "scale", "spread")(self.on_mix_change)
        page.ctrl.match_label = self.match
        page.ctrl.reset_label = self.reset
        self.apply_mix = page.guarded(self._apply_mix)
        self.settle_draft = page.guarded(self._settle_draft)
        self.show_settled = page.guarded(self._show_settled)
        self._settling: asyncio.Task | None = None  # the model's own reaction being made to replace the draft's

    def write_state(self) -> None:
        """The sliders onto the session's mix: a class whose parts differ shows them apart."""
        s, ses = self.page.state, self.page.session
        upper, lower = ses.label.parts
        for i, (u, lo) in enumerate(zip(upper, lower, strict=True)):
            s[f"w_{i}"], s[f"lower_{i}"] = round(float(u), 3), round(float(lo), 3)
            s[f"apart_{i}"] = bool(u != lo)
        s.scale = ses.scale

    def slider_mix(self) -> Label:
        """The sliders' mix: each class's slider for the whole body, or its upper and lower body's while its parts are
        apart (linked again, both take the class's slider), and the scale. A part mix stays one whatever the models
        drawing: the session refuses it where one cannot draw it, rather than this dropping a part unasked."""
        s, names = self.page.state, self.page.session.class_names
        upper = [number(s[f"w_{i}"] or 0.0, name) for i, name in enumerate(names)]
        lower = [number(s[f"lower_{i}"] or 0.0, f"lower:{name}") if s[f"apart_{i}"] else upper[i] for i, name in enumerate(names)]
        return Label.of_parts(upper, lower, names, number(s.scale if s.scale is not None else 1.0, "scale"))

    def on_mix_change(self, **_):
        """Coalesce slider messages: the latest mix wins, at most one synthesis in flight, no fixed
        debounce delay (that would be added to every slider's latency)."""
        self._pending = True
        if self._task is None or self._task.done():
            self._task = asynchronous.create_task(self._mix_loop())

    async def _mix_loop(self):
        review_due = False
        while self._pending or review_due:
            if self._pending:
                await asyncio.sleep(0)  # let already-queued slider messages land first
                self._pending = False
                await self.model_switch.announce()  # a slow model's "computing" reaches the page before its synthesis
                review_due = bool(self.apply_mix()) or review_due
                if self._settling is None or self._settling.done():  # else the page still waits for the model's own
                    self.model_switch.settle()
                await asyncio.sleep(PICTURE_S)  # the picture is rendered, encoded and sent before anything else
                if not self._pending:  # the sliders rest: the model's own follower replaces its draft's
                    self.settle_draft()
                continue
            # The panels change once the page has shown the picture: their state messages, processed by the page
            # while it decodes the picture, delayed it by ~30 ms at p95 (docs/experiments/studio-performance.md).
            await asyncio.sleep(REVIEW_DELAY_S - PICTURE_S)
            if not self._pending:
                review_due = False
                self.update_review()

    def _apply_mix(self) -> bool:
        """Synthesize with the sliders' mix and push the new picture; True when the mix changed."""
        s, ses = self.page.state, self.page.session
        try:
            label = self.slider_mix()
        except LabelError:
            with s:  # a slider value that is no number: the sliders show the mix drawn
                self.write_state()
            raise
        spread = float(s.spread or 0.0) if ses.spread is not None else None
        if (np.allclose(label.parts, ses.label.parts) and abs(label.scale - ses.scale) < 1e-9
                and spread == ses.spread and ses.synth is not None and s.mix_count):
            return False
        if spread is not None:
            ses.set_spread(spread, synthesize=False)
        try:
            ses.set_label(label, variations=False, draft=True)  # the variations follow with the review; the model's
            # draft, if it has one, draws the picture while the sliders move (`_mix_loop` settles it)
        except Exception:
            with s:  # refused (a part mix beside a model without part labels): the sliders show the mix drawn
                self.write_state()
            raise
        self.scene.set_synthesized(ses.synth)
        self.model_switch.show_variations()
        self.page.ctrl.view_update(draft=True)  # the picture first: it is what the user is watching; the panels follow it
        return True

    def _settle_draft(self) -> None:
        """Before the view's still picture (0.17 s after the last change): what rests on screen and in the panels is
        the model's own reaction, the draft only what moved. It is made on a worker thread (a long take's takes
        seconds), the page answering meanwhile: a slider moved before it is done draws its draft at once, and the
        reaction made for the mix before it is dropped (Session.settle). One at a time: the one running makes the
        current mix's next, if the mix moved meanwhile."""
        if self._settling is None or self._settling.done():
            self._start_settling()

    def _start_settling(self) -> None:
        made = self.page.session.own_reaction()
        if made is not None:
            with self.page.state:
                self.page.state.computing = True
            self._settling = asynchronous.create_task(self._settle(*made))

    async def _settle(self, draws: int, make) -> None:
        try:
            follower = await asyncio.to_thread(make)
        except Exception as err:  # shown in the page's alert, as a handler's error is
            follower = err
        self.show_settled(draws, follower)
        if not isinstance(follower, Exception) and self.page.session.drafted and not self._pending:
            self._start_settling()  # it was made for a mix moved on from, and the sliders rest: the current one's
        else:
            self.model_switch.settle()

    def _show_settled(self, draws: int, follower) -> None:
        if isinstance(follower, Exception):
            raise follower
        if self.page.session.settle(follower, draws):
            self.scene.set_synthesized(self.page.session.synth)
            self.page.ctrl.view_update()  # full size: the sliders rest
            if self._task is None or self._task.done():  # the mix's panels were drawn for the draft: again, for this
                self.update_review()

    def match(self):
        if self.page.session.own_class is not None:  # an uploaded leader has no class to match
            self.set_label(np.eye(len(self.page.session.class_names))[self.page.session.own_class])

    def reset(self):
        self.set_label(np.zeros(len(self.page.session.class_names)))

    def set_label(self, weights, scale: float = 1.0) -> None:
        """Move the sliders (the mix follows them, as when the user drags): one weight per class, or per class and part
        (the upper body's, then the lower body's)."""
        s, n = self.page.state, len(self.page.session.class_names)
        upper, lower = (float(w) for w in weights[:n]), (float(w) for w in weights[-n:])
        with s:
            for i, (u, lo) in enumerate(zip(upper, lower, strict=True)):
                s[f"w_{i}"], s[f"lower_{i}"], s[f"apart_{i}"] = u, lo, u != lo
            s.scale = float(scale)
