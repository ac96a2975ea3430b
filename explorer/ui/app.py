"""The studio's page: trame + Vuetify 3 layout, state and controllers for one user.

One process serves one user (see explorer/serving/launcher.py), so trame's shared state is that user's state.
State keys and controllers are named for what the user does (play, scrub, mix, pick, export).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from explorer.rendering import charts
from explorer.rendering.palette import class_color, display_name
from explorer.rendering.scene import Scene, floor_height
from explorer.session.latent import LatentMap
from explorer.session.session import Session
from explorer.session.words import one_line
from explorer.trame_adapter import attachment
from explorer.ui.chart_panel import ChartPanel
from explorer.ui.compare import Compare
from explorer.ui.exports import Exports
from explorer.ui.keys import press
from explorer.ui.label_mixer import LabelMixer
from explorer.ui.latent_panel import LatentPanel
from explorer.ui.layout import LayoutParts, build_layout
from explorer.ui.model_switch import ModelSwitch
from explorer.ui.panel_api import Page
from explorer.ui.playback import PLAYBACK_SCALE, LoopRange
from explorer.ui.reads_as_panel import part_rows, reads_as_rows, unread_note
from explorer.ui.review_panel import ReviewPanel
from explorer.ui.sequence_picker import SequencePicker
from explorer.ui.url_state import apply_view, current_view, view_query
from explorer.ui.viewer import Viewer


class Studio:
    def __init__(
        self, server, session: Session, latent: LatentMap, *, export_dir: Path, start_index: int | None = None, render: str = "remote"
    ):
        self.server = server
        self.session = session
        data = session.data
        self.scene = Scene(data.skeleton, floor_height(data.leader, data.follower, data.skeleton))
        # each panel gets the page and the few callbacks it calls, never the Studio (explorer/ui/panel_api.py)
        page = Page(session, server.state, server.controller, server.trigger, self.guarded)
        self._distances = np.zeros(1)
        self._ab_distances = np.zeros(0)
        self._closest = np.zeros(0)
        self._contact_changed = False
        self._url_opened = False  # the page's own address applied (open_url_view): the address bar may follow the view
        self._init_state()
        self.update_review = self.guarded(self._update_review)
        self.viewer = Viewer(page, self.scene, write_url=self.write_url, update_review=self.update_review)
        self.chart, self.loop_range = ChartPanel(page, write_url=self.write_url), LoopRange(page)
        self.model_switch = ModelSwitch(page, self.scene, show_review=self.show_review)
        self.mixer = LabelMixer(page, self.scene, self.model_switch, update_review=self.update_review)
        self.picker = SequencePicker(page, self.scene, self.model_switch, write_label_state=self.mixer.write_state,
                                     show_review=self._after_mix)
        # what the keys, the link and the panels call (explorer/ui/keys.py, url_state.py)
        self.load_sequence, self.set_camera = self.picker.load_sequence, self.viewer.set_camera
        self.set_label, self.match_label, self.reset_label = self.mixer.set_label, self.mixer.match, self.mixer.reset
        self.exports = Exports(page, self.scene, export_dir, attach=functools.partial(attachment, server))
        self.compare = Compare(page, self.scene, set_label=self.set_label, update_review=self.update_review)
        self.latent_panel = LatentPanel(page, latent, open_sequence=self.load_sequence)
        # a row of the review opens its sequence under its own class, or under the mix of a table of the mix
        self.review = ReviewPanel(page, open_sequence=lambda index, keep_mix: self.load_sequence(index, keep_mix=keep_mix))
        self._bind()
        self.ui = build_layout(LayoutParts(server, session, self.scene, render, attach_view=self.viewer.attach))
        self.load_sequence(session.index if start_index is None else start_index)

    # ---- state ---------------------------------------------------------------------------
    @property
    def state(self):
        return self.server.state

    @property
    def ctrl(self):
        return self.server.controller

    def _init_state(self) -> None:
        s, d = self.state, self.session.data
        names = self.session.class_names
        s.update(
            {
                "class_names": [display_name(n) for n in names],
                "class_colors": [class_color(i) for i in range(len(names))],
                "class_filter_items": [{"title": "all classes", "value": ""}] + [{"title": display_name(n), "value": n} for n in names],
                "pair_filter_items": [{"title": "all subject pairs", "value": ""}]
                + [{"title": p + ("  (held out)" if self._pair_held_out(p) else ""), "value": p} for p in sorted(set(d.subject_pairs))],
                "class_filter": "",
                "pair_filter": "",
                "held_filter": "all",
                "sequence_items": [],
                "sequence_index": 0,
                "sequence_title": "",
                "sequence_held_out": False,
                "sequence_uploaded": False,
                "upload_file": None,
                "frame": 0,
                "num_frames": 1,
                "time_text": "",
                "playing": False,
                "speed": 1.0,
                "playback_scale": PLAYBACK_SCALE,  # the view's size while playing (benchmarks/explorer_latency.py sets it)
                "loop": True,
                "live": False,  # live mode: the follower made frame by frame as the leader plays (explorer/session/live.py)
                "can_go_live": False,  # the current model reacts online
                "live_made": 0,  # live mode: the follower's frames made so far, from the first
                "scale": 1.0,
                "label_text": "",
                "reads_as": [],  # explorer/ui/reads_as_panel.py
                "reads_as_note": "",
                "reads_as_parts": [],  # the body-part judges' readings while the mix's parts differ
                "part_labels": False,  # the models drawing read a label per body part: the drawer offers part mixes
                "parts_apart": False,  # the mix sets a class apart by body part: models without part labels are marked
                "scene_layout": "overlay",
                "show_leader": True,
                "show_ground_truth": True,
                "show_synthesized": True,
                "clean_up": self.session.cleaned_up,  # rigid bones, planted feet (imm_model/cleanup.py)
                "projection": "tsne",
                "projection_busy": False,
                "afd_text": "",
                "distance_chart": "",  # explorer/rendering/charts.py markup; the frame cursor over it follows `frame` in the page
                "error": "",
                "notice": "",
                "mix_count": 0,  # increments after each re-synthesis (tests and benchmarks wait on it)
                "url_query": "",  # the view as a query string (explorer/ui/url_state.py); the page mirrors it in its URL
                "export_stem": "imm",  # what the browser names a download, before its extension (explorer/ui/exports.py)
                "key_slider": 0,  # the class slider the up/down keys move (explorer/ui/keys.py)
                "show_keys": False,
                "show_hints": False,  # the first-use hints (the page shows them until the browser has dismissed them once)
                "trails": False,  # ghosts of the last frames (explorer/rendering/scene.py set_trails)
                "follow_camera": False,  # the camera moves with the pair (scene.camera.set_follow)
                "joint_hover": None,  # the joint under the mouse: {text, x, y} (x, y: % of the view), None when none
                "pinned_text": "",  # A/B (explorer/ui/compare.py): the pinned mix in words, "" when none
                "ab_text": "",
                "contact_text": "",  # interpenetration of the two bodies (explorer/rendering/charts.py contact_text)
                "held_out_subject": d.info.get("held_out_subject", ""),
            }
        )

    def _pair_held_out(self, pair: str) -> bool:
        d = self.session.data
        return any(h for p, h in zip(d.subject_pairs, d.held_out, strict=True) if p == pair)

    def _bind(self) -> None:
        s = self.state
        s.change("clean_up")(self.guarded(self.on_cleanup_toggled))
        self.server.trigger("key_pressed")(self.guarded(lambda key: press(self, str(key)[:20])))
        self.server.trigger("open_url_view")(self.open_url_view)
        s.change("scene_layout", "projection", "playing", "mix_count")(self.write_url)
        s.change("frame")(self.write_still_frame)

    def guarded(self, fn):
        """`fn` with user-facing errors turned into the page's one-line alert (the page never goes blank)."""
        def call(*args, **kwargs):
            try:
                return fn(*args, **kwargs)
            except Exception as err:  # the page must never go blank on a bad input
                self.state.error = f"{type(err).__name__}: {one_line(err)}" if not str(err) else one_line(err)
                return None

        call.__name__ = getattr(fn, "__name__", "call")
        return call

    def _update_review(self) -> None:
        self.model_switch.draw_variations()
        with self.state:
            self._after_mix()
            self.state.error = ""
        if self._contact_changed:  # the orange limbs of the new mix: one more picture only when they differ
            self.ctrl.view_update()

    def _after_mix(self) -> None:
        """Review numbers, distance chart and latent star for the current synthesized follower."""
        s, ses = self.state, self.session
        s.label_text = ses.label_text()
        s.can_go_live, s.live, s.live_made = ses.model.settings.online, ses.live.on, ses.live.made
        s.part_labels, s.parts_apart = ses.part_labels, ses.label.parts_differ
        for i in range(len(ses.class_names)) if not ses.part_labels else ():  # none apart where no part mix can be drawn
            s[f"apart_{i}"] = False
        s.reads_as = reads_as_rows(ses.readings.reads_as(), ses.weights, ses.class_names)
        s.reads_as_parts = part_rows(ses.readings.reads_as_parts(), ses.label.parts, ses.class_names)
        s.reads_as_note = unread_note(s.reads_as, ses.label.parts_differ, s.reads_as_parts)
        self._distances = ses.readings.distances_m()
        self._ab_distances = ses.pinned.distances_m()
        s.ab_text = f"pinned ↔ current: joints {self._ab_distances.mean():.2f} m apart" if len(self._ab_distances) else ""
        self._closest, leader_bones, follower_bones = ses.readings.contact()
        self._contact_changed = self.scene.set_contact(leader_bones, follower_bones)
        s.contact_text = charts.contact_text(self._closest)
        afd = ses.readings.afd()
        s.afd_text = ("uploaded leader: no ground truth to compare with, so no error line (the chart shows contact only)" if afd is None
                      else f"AFD {afd:.3f} (SBU units) · joints {self._distances.mean():.2f} m apart on average")
        self.viewer.update_time()
        self.chart.draw(self._distances, self._ab_distances, self._closest)
        self.latent_panel.redraw()
        self.review.follow()
        s.export_stem = self.exports.file_stem()
        s.mix_count = (s.mix_count or 0) + 1

    def show_review(self) -> bool:
        """The review panels' state for the current follower (inside the caller's state batch); True when the view's
        contact limbs changed, so that it needs one more picture."""
        self._after_mix()
        return self._contact_changed

    def on_cleanup_toggled(self, clean_up, **_):
        """The clean-up switched on or off: the same mix, re-synthesized, and the panels that read it."""
        if bool(clean_up) == self.session.cleaned_up:
            return
        self.session.set_cleanup(bool(clean_up))
        self.scene.set_synthesized(self.session.synth)
        self.scene.set_pinned(self.session.pinned.follower)
        self.model_switch.show_variations()
        with self.state:
            self._after_mix()
        self.ctrl.view_update()

    # ---- the address bar -------------------------------------------------------------------
    def open_url_view(self, query) -> None:
        """The page has loaded: the view its address names (if any) opens, and from then on the address bar is the
        view's link (before, writing it would overwrite the link being opened)."""
        try:
            self.guarded(apply_view)(self, str(query))
        finally:
            self._url_opened = True
            self.write_url()

    def write_url(self, **_):
        """The page keeps its address bar on what it shows, playing or not: a sequence opened from the map or the
        review, a mix or a model changed while it plays is in the link at once (the frame only while paused)."""
        if self._url_opened:
            self.state.url_query = view_query(current_view(self))

    def write_still_frame(self, **_):
        """A frame scrubbed or stepped while paused goes into the link; frames going by in playback do not (each would
        be a write)."""
        if not self.state.playing:
            self.write_url()
