"""The 3D view in the page: the server renders the scene and streams it as JPEG pictures (trame-rca).

Why trame-rca and not trame-vtk's VtkRemoteView: the page then loads 0.09 MB of JavaScript for the view instead of
trame-vtk's 1.8 MB (all of vtk.js, which remote rendering does not use), and a picture goes out as soon as it is
rendered and encoded (Pillow, ~2-3 ms for the view), where trame-vtk's image delivery encoded asynchronously and
polled for the result. Measured in docs/explorer.md. `--render local` (vtk.js in the browser) still uses trame-vtk.

Each render is sent at INTERACTIVE_QUALITY at once, then, when no new picture was asked for during five frame
periods, again at STILL_QUALITY: a slider move or a drag shows at once, and what the user stops on is sharp.
"""

from __future__ import annotations

from trame.widgets import rca

TARGET_FPS = 30  # renders per second at most (playback asks for fewer on a small machine: playback.py)
INTERACTIVE_QUALITY = 70
STILL_QUALITY = 85


class ViewStream:
    def __init__(self, server, render_window, name: str = "view"):
        self.render_window = render_window
        self.handler = None  # created when the server runs: its render loop is an asyncio task
        # the view's size goes to the server 16 ms after a change (trame-rca's default, 100 ms, delayed the first picture)
        self.area = rca.RemoteControlledArea(name=name, display="image", style="width: 100%; height: 100%", resize_throttle_ms=16)
        server.controller.on_server_ready.add(self._start)

    def _start(self, **_) -> None:
        self.handler = self.area.create_view_handler(
            self.render_window, encoder="jpeg", target_fps=TARGET_FPS, interactive_quality=INTERACTIVE_QUALITY,
            still_quality=STILL_QUALITY,
        )  # fmt: skip
        forward = self.handler.on_interaction

        def mouse_and_touch_only(origin, event):
            # trame-rca also forwards the page's keys, and VTK's default key bindings would act on them ('r' resets
            # the camera, 'w' draws wireframes, 'e' ends the interactor); the studio's keys are its own (keys.py)
            if not str(event.get("type", "")).startswith("Key"):
                forward(origin, event)

        self.handler.on_interaction = mouse_and_touch_only
        self.handler.update()

    def update(self) -> None:
        """Render and send a new picture (nothing before the server runs: the page asks for one when it opens)."""
        if self.handler is not None:
            self.handler.update()
