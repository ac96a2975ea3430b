"""The Sequence drawer and the Upload: which leader is on screen, a dataset's sequence (filtered by class, subject pair
and held out / seen) or a leader file from the page."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from explorer.rendering.palette import display_name
from explorer.session.session import SequenceRow

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.model_switch import ModelSwitch
    from explorer.ui.panel_api import Page


class SequencePicker:
    def __init__(self, page: Page, scene: Scene, model_switch: ModelSwitch, *, write_label_state: Callable[[], None],
                 show_review: Callable[[], None]):
        """`write_label_state()` puts the session's mix on the sliders; `show_review()` the review panels' state for the
        new follower (inside the caller's state batch)."""
        self.page, self.scene, self.model_switch = page, scene, model_switch
        self.write_label_state, self.show_review = write_label_state, show_review
        s = page.state
        s.change("class_filter", "pair_filter", "held_filter")(self.on_filter_change)
        s.change("sequence_index")(page.guarded(self.on_sequence_picked))
        s.change("upload_file")(page.guarded(self.on_leader_uploaded))
        self.load_sequence = page.guarded(self._load_sequence)

    def filtered_indices(self) -> list[int]:
        s = self.page.state
        held = {"all": None, "held": True, "seen": False}[s.held_filter or "all"]
        return SequenceRow.matching(self.page.session.data, s.class_filter or None, s.pair_filter or None, held)

    def _items(self) -> list[dict]:
        rows = SequenceRow.all_of(self.page.session.data)
        return [{"title": rows[i].title, "value": i} for i in self.filtered_indices()]

    def on_filter_change(self, **_):
        """The filters narrow the sequence list; when they leave out the sequence on screen, the first one they keep
        opens: under its own class when a class filter picked it (another class's mix would not be what was asked
        for), else with the user's mix as it is."""
        items = self._items()
        self.page.state.sequence_items = items
        values = [it["value"] for it in items]
        ses = self.page.session
        if values and (ses.upload is not None or ses.index not in values):
            self.load_sequence(values[0], keep_mix=not self.page.state.class_filter)

    def on_sequence_picked(self, sequence_index, **_):
        ses = self.page.session
        if sequence_index is None or (int(sequence_index) == ses.index and ses.upload is None):
            return
        self.load_sequence(int(sequence_index))

    def _load_sequence(self, index: int, keep_mix: bool = False) -> None:
        """Pick a sequence: its own class becomes the label ("match"; `keep_mix`: the sliders stay as they are),
        playback restarts at frame 0."""
        ses, s = self.page.session, self.page.state
        ses.select(index, match_label=not keep_mix)
        with s:
            s.sequence_index = index
            s.sequence_items = self._items()
            row = SequenceRow.all_of(ses.data)[index]
            if index not in [it["value"] for it in s.sequence_items]:
                s.sequence_items = [{"title": row.title, "value": index}] + s.sequence_items
            s.sequence_title = f"{row.sequence_id} · {display_name(row.class_name)}"
            s.sequence_held_out = row.held_out
            s.sequence_uploaded = False
            self._show_leader()
        self.page.ctrl.view_update()

    def on_leader_uploaded(self, upload_file, **_):
        """A leader file dropped or chosen in the page: it replaces the view's sequence (no ground truth).
        A bad file leaves everything as it was and says why in one line."""
        from trame.app.file_upload import ClientFile

        if not upload_file:
            return
        file = ClientFile(upload_file[0] if isinstance(upload_file, list) else upload_file)
        ses, s = self.page.session, self.page.state
        try:
            ses.load_upload(file.name or "upload", file.content or b"")
        finally:
            s.upload_file = None  # the same file can be chosen again
        with s:
            s.sequence_title = f"uploaded: {ses.upload.name} · {ses.num_frames} fr"
            s.sequence_uploaded, s.sequence_held_out = True, False
            s.sequence_index = None  # the picker shows no bundled sequence: none is on screen
            self._show_leader()
            # an uploaded leader has no class to match: the mix on the sliders carries over, and the page says so
            s.notice = f"{ses.upload.name}: reacting with the mix on the sliders ({ses.label_text() or 'neutral'})"
        self.page.ctrl.view_update()

    def _show_leader(self) -> None:
        """The new leader on screen from its first frame, with its follower, the sliders and the panels."""
        ses, s = self.page.session, self.page.state
        s.num_frames, s.frame = ses.num_frames, 0
        self.write_label_state()
        self.scene.set_sequence(ses.leader, ses.ground_truth, ses.synth, 0)
        self.scene.set_pinned(ses.pinned.follower)
        self.model_switch.show_variations()
        self.scene.camera.set(self.scene.camera.preset)
        self.show_review()
        s.error = ""
