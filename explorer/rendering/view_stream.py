"""The 3D view in the page: the server renders the scene and streams it as JPEG pictures (trame-rca).

Why trame-rca and not trame-vtk's VtkRemoteView: the page then loads 0.09 MB of JavaScript for the view instead of
trame-vtk's 1.8 MB (all of vtk.js, which remote rendering does not use), and a picture goes out as soon as it is
rendered and encoded (Pillow, ~2-3 ms for the view), where trame-vtk's image delivery encoded asynchronously and
polled for the result. Measured in docs/experiments/studio-performance.md. `--render local` (vtk.js in the browser) still uses trame-vtk.

Each render is sent at INTERACTIVE_QUALITY at once, then, when no new picture was asked for during five frame
periods, again at STILL_QUALITY: a slider move or a drag shows at once, and what the user stops on is sharp.
A label change's first picture (`update(draft=True)`) is also rendered at DRAFT_SCALE of the view's width and
height, which the page stretches: on a CPU renderer that is ~5 ms less to render, encode and decode, and the full
picture follows when the sliders rest (docs/experiments/studio-performance.md).
"""

from __future__ import annotations

from trame.widgets import rca

from explorer.trame_adapter import stream_view

TARGET_FPS = 30  # renders per second at most (playback asks for fewer on a small machine: explorer/ui/playback.py)
INTERACTIVE_QUALITY = 70
STILL_QUALITY = 85
DRAFT_SCALE = 0.5


class ViewStream:
    def __init__(self, server, render_window, name: str = "view"):
        self.render_window = render_window
        self.handler = None  # created when the server runs: its render loop is an asyncio task
        self.draft_next = False  # the next interactive picture at DRAFT_SCALE (the still picture after it is full size)
        # the view's size goes to the server 16 ms after a change (trame-rca's default, 100 ms, delayed the first picture)
        self.area = rca.RemoteControlledArea(name=name, display="image", style="width: 100%; height: 100%", resize_throttle_ms=16)
        server.controller.on_server_ready.add(self._start)

    def _start(self, **_) -> None:
        self.handler = stream_view(self.area, self.render_window, wrap_interactive=self._render_interactive,
                                   target_fps=TARGET_FPS, interactive_quality=INTERACTIVE_QUALITY, still_quality=STILL_QUALITY)
        self.handler.update()

    def _render_interactive(self, render):
        """An interactive picture: after `draft_next` was set, rendered at DRAFT_SCALE of the window's size."""
        if not self.draft_next:
            return render()
        self.draft_next = False
        width, height = self.render_window.GetSize()
        self.render_window.SetSize(max(10, round(width * DRAFT_SCALE)), max(10, round(height * DRAFT_SCALE)))
        try:
            return render()  # renders and reads the pixels now; encoding goes on elsewhere
        finally:
            self.render_window.SetSize(width, height)

    def update(self, draft: bool = False) -> None:
        """Render and send a new picture (nothing before the server runs: the page asks for one when it opens);
        `draft`: its first picture at DRAFT_SCALE (a label change, where the time to the picture counts most)."""
        if self.handler is not None:
            self.draft_next = self.draft_next or draft
            self.handler.update()
