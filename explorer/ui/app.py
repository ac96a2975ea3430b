"""The studio's page: trame + Vuetify 3 layout, state and controllers for one user.

One process serves one user (see explorer/serving/launcher.py), so trame's shared state is that user's state.
State keys and controllers are named for what the user does (play, scrub, mix, pick, export).
"""

from __future__ import annotations

import asyncio
import functools
from pathlib import Path

import numpy as np
from trame.app import asynchronous

from explorer.rendering import charts
from explorer.rendering.palette import CHARACTER_TITLES, class_color, display_name
from explorer.rendering.scene import CHARACTER_KEYS, COMPARED_KEYS, Scene, floor_height
from explorer.session.files import FPS
from explorer.session.latent import LatentMap
from explorer.session.session import SequenceRow, Session
from explorer.session.words import one_line
from explorer.trame_adapter import attachment
from explorer.ui.compare import Compare
from explorer.ui.exports import Exports
from explorer.ui.keys import press
from explorer.ui.latent_panel import LatentPanel
from explorer.ui.layout import LayoutParts, build_layout
from explorer.ui.model_switch import ModelSwitch
from explorer.ui.panel_api import Page
from explorer.ui.playback import PLAYBACK_SCALE, play, playback_scale
from explorer.ui.reads_as_panel import part_rows, reads_as_rows, unread_note
from explorer.ui.review_panel import ReviewPanel
from explorer.ui.url_state import apply_view, current_view, view_query
from imm_model.data.labels import Label, number
from imm_model.errors import LabelError

PICTURE_S = 0.04  # after a new mix, the time its picture takes to leave (the next mix waits for it)
REVIEW_DELAY_S = 0.1  # ... and the time until the 'reads as' panel, distance chart, AFD and latent star follow it


class Studio:
    def __init__(
        self, server, session: Session, latent: LatentMap, *, export_dir: Path, start_index: int | None = None, render: str = "remote"
    ):
        self.server = server
        self.render_mode = render
        self.session = session
        data = session.data
        self.scene = Scene(data.skeleton, floor_height(data.leader, data.follower, data.skeleton))
        # each panel gets the page and the few callbacks it calls, never the Studio (explorer/ui/panel_api.py)
        page = Page(session, server.state, server.controller, server.trigger, self.guarded)
        self.exports = Exports(page, self.scene, export_dir, attach=functools.partial(attachment, server))
        self.compare = Compare(page, self.scene, set_label=self.set_label, update_review=self.update_review)
        self.model_switch = ModelSwitch(page, self.scene, show_review=self.show_review)
        self.latent_panel = LatentPanel(page, latent, open_sequence=self.load_sequence)
        # a row of the review opens its sequence under its own class, or under the mix of a table of the mix
        self.review = ReviewPanel(page, open_sequence=lambda index, keep_mix: self.load_sequence(index, keep_mix=keep_mix))
        self._view = None  # the 3D view widget, made by the layout (attach_view)
        self._mix_pending = False
        self._mix_task = None
        self._play_task = None
        self._distances = np.zeros(1)
        self._ab_distances = np.zeros(0)
        self._closest = np.zeros(0)
        self._contact_changed = False
        self._url_opened = False  # the page's own address applied (open_url_view): the address bar may follow the view
        self._init_state()
        self._bind()
        self.ui = self._build_ui()
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
                "scale": 1.0,
                "label_text": "",
                "reads_as": [],  # explorer/ui/reads_as_panel.py
                "reads_as_note": "",
                "reads_as_parts": [],  # the body-part judges' readings while the mix's parts differ
                "part_labels": False,  # the models drawing read a label per body part: the drawer offers part mixes
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
                "follow_camera": False,  # the camera moves with the pair (scene.set_follow)
                "joint_hover": None,  # the joint under the mouse: {text, x, y} (x, y: % of the view), None when none
                "pinned_text": "",  # A/B (explorer/ui/compare.py): the pinned mix in words, "" when none
                "ab_text": "",
                "contact_text": "",  # interpenetration of the two bodies (explorer/rendering/charts.py contact_text)
                "held_out_subject": d.info.get("held_out_subject", ""),
            }
        )
        for i in range(len(names)):  # a class's slider (the whole body; with its parts apart, the upper body) and its lower body's
            s[f"w_{i}"] = s[f"lower_{i}"] = 0.0
            s[f"apart_{i}"] = False

    def _pair_held_out(self, pair: str) -> bool:
        d = self.session.data
        return any(h for p, h in zip(d.subject_pairs, d.held_out, strict=True) if p == pair)

    def _bind(self) -> None:
        s, c = self.state, self.ctrl
        s.change("class_filter", "pair_filter", "held_filter")(self.on_filter_change)
        s.change("sequence_index")(self.on_sequence_picked)
        s.change("upload_file")(self.on_leader_uploaded)
        s.change("frame")(self.on_frame_change)
        n = len(self.session.class_names)
        s.change(*[f"{k}_{i}" for k in ("w", "lower", "apart") for i in range(n)], "scale", "spread")(self.on_mix_change)
        s.change("scene_layout")(self.on_layout_change)
        s.change("show_leader", "show_ground_truth", "show_synthesized")(self.on_visibility_change)
        s.change("playing")(self.on_playing_change)
        s.change("clean_up")(self.on_cleanup_toggled)
        s.change("trails", "follow_camera")(self.on_viewer_aids)
        c.match_label = self.match_label
        c.reset_label = self.reset_label
        c.set_camera = self.set_camera
        c.step_frame = self.step_frame
        self.server.trigger("key_pressed")(self.guarded(lambda key: press(self, str(key)[:20])))
        self.server.trigger("open_url_view")(self.open_url_view)
        self.server.trigger("hover_joint")(self.guarded(self.hover_joint))
        s.change("scene_layout", "projection", "frame", "playing", "mix_count")(self.write_url)

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

    def _guard(fn):  # noqa: N805 - decorator for the methods below
        def wrapper(self, *args, **kwargs):
            return self.guarded(functools.partial(fn, self))(*args, **kwargs)

        wrapper.__name__ = fn.__name__
        return wrapper

    # ---- sequences -----------------------------------------------------------------------
    def filtered_indices(self) -> list[int]:
        s = self.state
        held = {"all": None, "held": True, "seen": False}[s.held_filter or "all"]
        return SequenceRow.matching(self.session.data, s.class_filter or None, s.pair_filter or None, held)

    def _sequence_items(self) -> list[dict]:
        rows = SequenceRow.all_of(self.session.data)
        return [{"title": rows[i].title, "value": i} for i in self.filtered_indices()]

    def on_filter_change(self, **_):
        """The filters narrow the sequence list; when they leave out the sequence on screen, the first one they keep
        opens: under its own class when a class filter picked it (another class's mix would not be what was asked
        for), else with the user's mix as it is."""
        items = self._sequence_items()
        self.state.sequence_items = items
        values = [it["value"] for it in items]
        if values and (self.session.upload is not None or self.session.index not in values):
            self.load_sequence(values[0], keep_mix=not self.state.class_filter)

    @_guard
    def on_sequence_picked(self, sequence_index, **_):
        if sequence_index is None or (int(sequence_index) == self.session.index and self.session.upload is None):
            return
        self.load_sequence(int(sequence_index))

    @_guard
    def load_sequence(self, index: int, keep_mix: bool = False) -> None:
        """Pick a sequence: its own class becomes the label ("match"; `keep_mix`: the sliders stay as they are),
        playback restarts at frame 0."""
        ses, s = self.session, self.state
        ses.select(index, match_label=not keep_mix)
        with s:
            s.sequence_index = index
            s.sequence_items = self._sequence_items()
            if index not in [it["value"] for it in s.sequence_items]:
                s.sequence_items = [{"title": SequenceRow.all_of(ses.data)[index].title, "value": index}] + s.sequence_items
            row = SequenceRow.all_of(ses.data)[index]
            s.sequence_title = f"{row.sequence_id} · {display_name(row.class_name)}"
            s.sequence_held_out = row.held_out
            s.sequence_uploaded = False
            s.num_frames = ses.num_frames
            s.frame = 0
            self._write_label_state()
            self.scene.set_sequence(ses.leader, ses.ground_truth, ses.synth, 0)
            self.scene.set_pinned(ses.pinned.follower)
            self.model_switch.show_variations()
            self.scene.set_camera(self.scene.camera_preset)
            self._after_mix()
            s.error = ""
        self.ctrl.view_update()

    @_guard
    def on_leader_uploaded(self, upload_file, **_):
        """A leader file dropped or chosen in the page: it replaces the view's sequence (no ground truth).
        A bad file leaves everything as it was and says why in one line."""
        from trame.app.file_upload import ClientFile

        if not upload_file:
            return
        file = ClientFile(upload_file[0] if isinstance(upload_file, list) else upload_file)
        ses, s = self.session, self.state
        try:
            ses.load_upload(file.name or "upload", file.content or b"")
        finally:
            s.upload_file = None  # the same file can be chosen again
        with s:
            s.sequence_title = f"uploaded: {ses.upload.name} · {ses.num_frames} fr"
            s.sequence_uploaded, s.sequence_held_out = True, False
            s.sequence_index = None  # the picker shows no bundled sequence: none is on screen
            s.num_frames, s.frame = ses.num_frames, 0
            self._write_label_state()
            self.scene.set_sequence(ses.leader, None, ses.synth, 0)
            self.scene.set_pinned(ses.pinned.follower)
            self.model_switch.show_variations()
            self.scene.set_camera(self.scene.camera_preset)
            self._after_mix()
            s.error = ""
        self.ctrl.view_update()

    # ---- label mixing --------------------------------------------------------------------
    def _write_label_state(self) -> None:
        """The sliders onto the session's mix: a class whose parts differ shows them apart."""
        upper, lower = self.session.label.parts
        for i, (u, lo) in enumerate(zip(upper, lower, strict=True)):
            self.state[f"w_{i}"], self.state[f"lower_{i}"] = round(float(u), 3), round(float(lo), 3)
            self.state[f"apart_{i}"] = bool(u != lo)
        self.state.scale = self.session.scale

    def slider_mix(self) -> Label:
        """The sliders' mix: each class's slider for the whole body, or its upper and lower body's while its parts are
        apart (linked again, both take the class's slider), and the scale. A part mix stays one whatever the models
        drawing: the session refuses it where one cannot draw it, rather than this dropping a part unasked."""
        s, names = self.state, self.session.class_names
        upper = [number(s[f"w_{i}"] or 0.0, name) for i, name in enumerate(names)]
        lower = [number(s[f"lower_{i}"] or 0.0, f"lower:{name}") if s[f"apart_{i}"] else upper[i] for i, name in enumerate(names)]
        return Label.of_parts(upper, lower, names, number(s.scale if s.scale is not None else 1.0, "scale"))

    def on_mix_change(self, **_):
        """Coalesce slider messages: the latest mix wins, at most one synthesis in flight, no fixed
        debounce delay (that would be added to every slider's latency)."""
        self._mix_pending = True
        if self._mix_task is None or self._mix_task.done():
            self._mix_task = asynchronous.create_task(self._mix_loop())

    async def _mix_loop(self):
        review_due = False
        while self._mix_pending or review_due:
            if self._mix_pending:
                await asyncio.sleep(0)  # let already-queued slider messages land first
                self._mix_pending = False
                await self.model_switch.announce()  # a slow model's "computing" reaches the page before its synthesis
                review_due = bool(self.apply_mix()) or review_due
                self.model_switch.settle()
                await asyncio.sleep(PICTURE_S)  # the picture is rendered, encoded and sent before anything else
                continue
            # The panels change once the page has shown the picture: their state messages, processed by the page
            # while it decodes the picture, delayed it by ~30 ms at p95 (docs/experiments/studio-performance.md).
            await asyncio.sleep(REVIEW_DELAY_S - PICTURE_S)
            if not self._mix_pending:
                review_due = False
                self.update_review()

    @_guard
    def apply_mix(self) -> bool:
        """Synthesize with the sliders' mix and push the new picture; True when the mix changed."""
        s, ses = self.state, self.session
        try:
            label = self.slider_mix()
        except LabelError:
            with s:  # a slider value that is no number: the sliders show the mix drawn
                self._write_label_state()
            raise
        spread = float(s.spread or 0.0) if ses.spread is not None else None
        if (np.allclose(label.parts, ses.label.parts) and abs(label.scale - ses.scale) < 1e-9
                and spread == ses.spread and ses.synth is not None and s.mix_count):
            return False
        if spread is not None:
            ses.set_spread(spread, synthesize=False)
        try:
            ses.set_label(label, variations=False)  # the side-by-side variations follow with the review
        except Exception:
            with s:  # refused (a part mix beside a model without part labels): the sliders show the mix drawn
                self._write_label_state()
            raise
        self.scene.set_synthesized(ses.synth)
        self.model_switch.show_variations()
        self.ctrl.view_update(draft=True)  # the picture first: it is what the user is watching; the panels follow it
        return True

    @_guard
    def update_review(self) -> None:
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
        s.part_labels = ses.part_labels
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
        s.afd_text = ("uploaded leader: no ground truth to compare with, so no error chart" if afd is None
                      else f"AFD {afd:.3f} (SBU units) · joints {self._distances.mean():.2f} m apart on average")
        self._update_time()
        s.distance_chart = charts.distance_chart(self._distances, FPS, self._ab_distances, self._closest)
        self.latent_panel.redraw()
        self.review.follow()
        s.export_stem = self.exports.file_stem()
        s.mix_count = (s.mix_count or 0) + 1

    def show_review(self) -> bool:
        """The review panels' state for the current follower (inside the caller's state batch); True when the view's
        contact limbs changed, so that it needs one more picture."""
        self._after_mix()
        return self._contact_changed

    def match_label(self):
        if self.session.own_class is not None:  # an uploaded leader has no class to match
            self.set_label(np.eye(len(self.session.class_names))[self.session.own_class])

    def reset_label(self):
        self.set_label(np.zeros(len(self.session.class_names)))

    def set_label(self, weights, scale: float = 1.0) -> None:
        """Move the sliders (the mix follows them, as when the user drags): one weight per class, or per class and part
        (the upper body's, then the lower body's)."""
        n = len(self.session.class_names)
        upper, lower = (float(w) for w in weights[:n]), (float(w) for w in weights[-n:])
        with self.state:
            for i, (u, lo) in enumerate(zip(upper, lower, strict=True)):
                self.state[f"w_{i}"], self.state[f"lower_{i}"], self.state[f"apart_{i}"] = u, lo, u != lo
            self.state.scale = float(scale)

    # ---- playback ------------------------------------------------------------------------
    def _update_time(self) -> None:
        s = self.state
        f, n = int(s.frame or 0), self.session.num_frames
        s.time_text = f"frame {f + 1}/{n} · {f / FPS:.2f} s / {(n - 1) / FPS:.2f} s"

    def on_frame_change(self, frame, **_):
        self.scene.set_frame(int(frame or 0))
        # playback's pictures at PLAYBACK_SCALE of the view's size; the still one is full size
        self.ctrl.view_update(draft=bool(self.state.playing), scale=playback_scale(self.state.playback_scale))
        self._update_time()

    async def picture_encoded(self) -> bool:
        """Wait until the picture asked for last is encoded (a streamed view's) -> True; False at once for vtk.js
        drawing in the page (--render local), which cannot tell."""
        wait = getattr(self._view, "wait_encoded", None)
        if wait is None:
            return False
        await wait()
        return True

    def step_frame(self, delta: int):
        n = self.session.num_frames
        self.state.frame = int(np.clip(int(self.state.frame or 0) + int(delta), 0, n - 1))

    def on_playing_change(self, playing, **_):
        if playing and (self._play_task is None or self._play_task.done()):
            if int(self.state.frame or 0) >= self.session.num_frames - 1:
                self.state.frame = 0
            self._play_task = asynchronous.create_task(play(self))

    @_guard
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

    # ---- view ----------------------------------------------------------------------------
    def on_layout_change(self, scene_layout, **_):
        self.scene.set_layout(scene_layout)
        self.state.view_captions = self.scene.captions_shown()
        self.ctrl.view_update()

    def hover_joint(self, where) -> None:
        """The mouse rests at `where` ([x, y], fractions of the view from its top left; None: it left the view): the joint
        drawn there, named with its figure and its speed at this frame, or nothing."""
        s, scene = self.state, self.scene
        found = None
        if isinstance(where, list | tuple) and len(where) == 2:
            x, y = (float(v) for v in where)
            if 0.0 <= x <= 1.0 and 0.0 <= y <= 1.0:
                found = scene.joint_at(x, y)
        if found is None:
            if s.joint_hover is not None:
                s.joint_hover = None
            return
        key, j = found
        seq, f = scene.sequences[key], scene.frame
        before, after = max(0, f - 1), min(len(seq) - 1, f + 1)
        speed = float(np.linalg.norm(seq[after, j] - seq[before, j])) * FPS / max(1, after - before)
        # another model's follower is named as its caption names it ("the diffusion model · seed 7")
        figure = (scene.captions[key].input.replace("\n", " · ") if key in COMPARED_KEYS
                  else CHARACTER_TITLES.get(key, key.replace("_", " ")))
        joint = self.session.data.skeleton.joint_names[j].replace("_", " ")
        s.joint_hover = {"text": f"{figure} · {joint} · {speed:.2f} m/s", "x": round(100 * x, 2), "y": round(100 * y, 2)}

    def on_viewer_aids(self, trails, follow_camera, **_):
        self.scene.set_trails(bool(trails))
        if bool(follow_camera) != self.scene.follow:
            self.scene.set_follow(bool(follow_camera))
        self.ctrl.view_update()

    def on_visibility_change(self, show_leader, show_ground_truth, show_synthesized, **_):
        for key, on in zip(CHARACTER_KEYS, (show_leader, show_ground_truth, show_synthesized), strict=True):
            self.scene.set_visible(key, bool(on))
        self.ctrl.view_update()

    def set_camera(self, preset: str):
        self.scene.set_camera(preset)
        self.ctrl.view_update()
        self.write_url()

    def open_url_view(self, query) -> None:
        """The page has loaded: the view its address names (if any) opens, and from then on the address bar is the
        view's link (before, writing it would overwrite the link being opened)."""
        try:
            self.guarded(apply_view)(self, str(query))
        finally:
            self._url_opened = True
            self.write_url()

    def write_url(self, **_):
        """The page keeps its address bar on what it shows (not during playback: every frame would be a write)."""
        if self._url_opened and not self.state.playing:
            self.state.url_query = view_query(current_view(self))

    def push_view(self, draft: bool = False, **kwargs):
        """Send a new picture (moving points or toggling actors does not touch the render window, which the local
        view's geometry export checks: mark it); `draft`: a streamed view's first picture at reduced size, `scale` of
        it (the local view, vtk.js, ignores both)."""
        self.scene.render_window.Modified()
        self._view.update(draft=draft, **kwargs)

    # ---- layout --------------------------------------------------------------------------
    def attach_view(self, view) -> None:
        """The 3D view widget the layout made: every new picture goes through it (ctrl.view_update)."""
        self._view = view
        self.ctrl.view_update = self.push_view

    def _build_ui(self):
        return build_layout(LayoutParts(self.server, self.session, self.scene, self.render_mode, attach_view=self.attach_view))
