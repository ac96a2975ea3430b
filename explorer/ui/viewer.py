"""The 3D view and its playback: pictures pushed to the view widget, the layout, camera, figures shown, viewer aids,
the joint under the mouse, and the frame (scrubbed, stepped or played in real time)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from trame.app import asynchronous

from explorer.rendering.palette import CHARACTER_TITLES
from explorer.rendering.scene import CHARACTER_KEYS, COMPARED_KEYS
from explorer.session.files import FPS
from explorer.ui.playback import play, playback_scale

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.panel_api import Page


class Viewer:
    def __init__(self, page: Page, scene: Scene, *, write_url: Callable[[], None], update_review: Callable[[], None]):
        """`write_url()` puts the view into the page's address bar (after a camera preset); `update_review()` redraws
        the review panels (after a live take: the chart and readings of the follower made as it played)."""
        self.page, self.scene, self.write_url, self.update_review = page, scene, write_url, update_review
        self._view = None  # the 3D view widget, made by the layout (attach)
        self._play_task = None
        s, c = page.state, page.ctrl
        s.change("frame")(self.on_frame_change)
        s.change("scene_layout")(self.on_layout_change)
        s.change("show_leader", "show_ground_truth", "show_synthesized")(self.on_visibility_change)
        s.change("playing")(self.on_playing_change)
        s.change("live")(self.on_live_toggled)
        s.change("trails", "follow_camera")(self.on_viewer_aids)
        c.set_camera = self.set_camera
        c.step_frame = self.step_frame
        page.trigger("hover_joint")(page.guarded(self.hover_joint))

    # what playback (explorer/ui/playback.py play) reads
    @property
    def state(self):
        return self.page.state

    @property
    def session(self):
        return self.page.session

    def attach(self, view) -> None:
        """The 3D view widget the layout made: every new picture goes through it (ctrl.view_update). A drag or a zoom
        of the view, once it ends, puts the camera into the address bar (the renderer's interactor reports it)."""
        self._view = view
        self.page.ctrl.view_update = self.push
        interactor = self.scene.render_window.GetInteractor()
        if interactor is not None:
            interactor.AddObserver("EndInteractionEvent", lambda *_: self.on_camera_moved())

    def on_camera_moved(self) -> None:
        self.scene.camera.moved_by_hand()
        with self.page.state:
            self.write_url()

    def push(self, draft: bool = False, **kwargs):
        """Send a new picture (moving points or toggling actors does not touch the render window, which the local
        view's geometry export checks: mark it); `draft`: a streamed view's first picture at reduced size, `scale` of
        it (the local view, vtk.js, ignores both)."""
        self.scene.render_window.Modified()
        self._view.update(draft=draft, **kwargs)

    async def picture_encoded(self) -> bool:
        """Wait until the picture asked for last is encoded (a streamed view's) -> True; False at once for vtk.js
        drawing in the page (--render local), which cannot tell."""
        wait = getattr(self._view, "wait_encoded", None)
        if wait is None:
            return False
        await wait()
        return True

    # ---- the frame -----------------------------------------------------------------------
    def update_time(self) -> None:
        s = self.page.state
        f, n = int(s.frame or 0), self.page.session.num_frames
        s.time_text = f"frame {f + 1}/{n} · {f / FPS:.2f} s / {(n - 1) / FPS:.2f} s"

    def on_frame_change(self, frame, **_):
        live = self.page.session.live
        if live.on and live.reach(int(frame or 0)):
            self.page.state.live_made = live.made
            if live.made == self.page.session.num_frames:
                self.update_review()  # the take made to its end: the chart and readings of what was made
        self.scene.set_frame(int(frame or 0))
        # playback's pictures at PLAYBACK_SCALE of the view's size; the still one is full size
        self.page.ctrl.view_update(draft=bool(self.page.state.playing), scale=playback_scale(self.page.state.playback_scale))
        self.update_time()

    def step_frame(self, delta: int):
        n = self.page.session.num_frames
        self.page.state.frame = int(np.clip(int(self.page.state.frame or 0) + int(delta), 0, n - 1))

    def on_playing_change(self, playing, **_):
        if not playing and self.page.session.live.on:
            self.update_review()  # paused mid-take: the review reads what was made so far
        if playing and (self._play_task is None or self._play_task.done()):
            if int(self.page.state.frame or 0) >= self.page.session.num_frames - 1:
                self.page.state.frame = 0
            self._play_task = asynchronous.create_task(play(self))

    def on_live_toggled(self, live, **_):
        """Live mode switched: the follower made frame by frame from the first frame as it plays, or the offline one."""
        ses = self.page.session
        if bool(live) == ses.live.on:
            return
        self.page.guarded(ses.set_live)(bool(live))
        if bool(live) != ses.live.on:  # refused (the alert says why): the switch shows what holds
            self.page.state.live = ses.live.on
            return
        self.page.state.live_made = ses.live.made
        self.scene.set_synthesized(ses.synth)
        self.update_review()

    # ---- what the view shows and from where ------------------------------------------------
    def on_layout_change(self, scene_layout, **_):
        self.scene.set_layout(scene_layout)
        self.page.state.view_captions = self.scene.captions_shown()
        self.page.ctrl.view_update()

    def hover_joint(self, where) -> None:
        """The mouse rests at `where` ([x, y], fractions of the view from its top left; None: it left the view): the joint
        drawn there, named with its figure and its speed at this frame, or nothing."""
        s, scene = self.page.state, self.scene
        found = None
        if isinstance(where, list | tuple) and len(where) == 2:
            x, y = (float(v) for v in where)
            if 0.0 <= x <= 1.0 and 0.0 <= y <= 1.0:
                found = scene.camera.joint_at(x, y)
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
        joint = self.page.session.data.skeleton.joint_names[j].replace("_", " ")
        s.joint_hover = {"text": f"{figure} · {joint} · {speed:.2f} m/s", "x": round(100 * x, 2), "y": round(100 * y, 2)}

    def on_viewer_aids(self, trails, follow_camera, **_):
        self.scene.set_trails(bool(trails))
        if bool(follow_camera) != self.scene.camera.follow:
            self.scene.camera.set_follow(bool(follow_camera))
        self.page.ctrl.view_update()

    def on_visibility_change(self, show_leader, show_ground_truth, show_synthesized, **_):
        for key, on in zip(CHARACTER_KEYS, (show_leader, show_ground_truth, show_synthesized), strict=True):
            self.scene.set_visible(key, bool(on))
        self.page.ctrl.view_update()

    def set_camera(self, preset: str):
        """A preset's name, or a link's hand-placed camera (explorer/rendering/camera.py `placement`)."""
        self.scene.camera.place(preset)
        self.page.ctrl.view_update()
        self.write_url()
