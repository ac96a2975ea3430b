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

One picture in flight (PictureGate): a picture encoded while the page has not yet shown the one before is held
back, and sent once the page reports that one shown (the view's image `load`, acknowledged by the trigger
`<name>_shown`) or ACK_TIMEOUT_S later; a newer picture replaces one held back (the latest wins). trame-rca's page
hands each arriving picture to its <img> at once, and a new `src` cancels a load still going: on a busy 2-core machine,
pictures sent at 30/s were mostly cancelled (the page showed 6-8 a second). Playback sets its next frame as soon as
this one's picture is encoded (explorer/ui/playback.py), so the next renders while the page shows this one, and
its pictures are drafts (at explorer/ui/playback.py's PLAYBACK_SCALE, stretched by the page; the still picture
after it stops is full size).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

from trame.widgets import rca

from explorer.trame_adapter import stream_view

TARGET_FPS = 60  # renders per second at most; the page's acknowledgements pace the pictures (PictureGate)
INTERACTIVE_QUALITY = 70
STILL_QUALITY = 85
DRAFT_SCALE = 0.5
ACK_TIMEOUT_S = 0.25  # a picture the page never reports shown (a hidden tab, a lost one) holds the next this long


class PictureGate:
    """At most one picture on its way to the page: `deliver(send, still)` sends an encoded picture (calls `send()`,
    which returns False if no page was there to send it to) at once if none is in flight, else holds it back,
    replacing one held before; on `shown()` (the page showed a picture), or ACK_TIMEOUT_S after a send, the one held
    back goes. `asked()`: a picture was asked of the renderer; `wait_encoded()`: until it is encoded (sent or held);
    `at_rest()`: the view shows what it will until the next change (the still picture, shown)."""

    def __init__(self, timeout_s: float = ACK_TIMEOUT_S):
        self.timeout_s = timeout_s
        self.in_flight = False  # a picture was sent that the page has not reported shown
        self.held: Callable[[], bool | None] | None = None  # the send() of the latest picture encoded meanwhile
        self.pending = False  # a picture was asked for and is not encoded yet
        self.sent = self.shown_count = self.replaced = 0  # since the start
        self.held_still = False  # the picture held back is the still one (the sharper picture after a render)
        self.sent_still = False  # the last picture sent was the still one
        self.shown_since_sent = False  # the page reported a picture shown after the last send
        self._encoded: asyncio.Event | None = None  # made in the server's loop
        self._timer: asyncio.TimerHandle | None = None

    def asked(self) -> None:
        self.pending = True  # until the next picture is encoded (the renderer renders once for any number of asks)
        self._settle()

    def deliver(self, send: Callable[[], bool | None], still: bool = False) -> None:
        self.pending = False
        if self.in_flight:
            self.replaced += self.held is not None
            self.held, self.held_still = send, still
        else:
            self._send(send, still)
        self._settle()

    def shown(self) -> None:
        self.shown_count += 1
        self.shown_since_sent = True
        self.release()

    def release(self) -> None:
        """Nothing in flight any more (shown, or given up on): the picture held back goes."""
        self.in_flight = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        held, self.held = self.held, None
        if held is not None:
            self._send(held, self.held_still)

    async def wait_encoded(self) -> None:
        self._settle()
        await self._encoded.wait()

    def at_rest(self) -> bool:
        """No picture asked for or held back, and the last one sent, the still one, reported shown: what a test waits
        for after an action instead of a fixed time (tests/studio_probe.py, through the trigger `<name>_at_rest`)."""
        return not self.pending and self.held is None and self.sent_still and self.shown_since_sent

    def _send(self, send: Callable[[], bool | None], still: bool) -> None:
        if send() is False:
            return  # no page to show it yet: nothing in flight
        self.sent += 1
        self.sent_still, self.shown_since_sent = still, False
        self.in_flight = True
        self._timer = asyncio.get_running_loop().call_later(self.timeout_s, self.release)

    def _settle(self) -> None:
        if self._encoded is None:
            self._encoded = asyncio.Event()
        if self.pending:
            self._encoded.clear()
        else:
            self._encoded.set()


class ViewStream:
    def __init__(self, server, render_window, name: str = "view"):
        self.render_window = render_window
        self.handler = None  # created when the server runs: its render loop is an asyncio task
        self.draft_next: float | None = None  # the next interactive picture at this fraction of the view's size (the still
        # picture after it is full size); None: full size
        self.gate = PictureGate()
        # the view's size goes to the server 16 ms after a change (trame-rca's default, 100 ms, delayed the first
        # picture); a `load` of the view's image (a capture listener: load does not bubble) acknowledges a picture
        self.area = rca.RemoteControlledArea(name=name, display="image", style="width: 100%; height: 100%", resize_throttle_ms=16,
                                             raw_attrs=[f"@load.capture=\"trigger('{name}_shown')\""])
        server.trigger(f"{name}_shown")(lambda *_: self.gate.shown())
        server.trigger(f"{name}_at_rest")(lambda *_: self.gate.at_rest())
        server.controller.on_server_ready.add(self._start)

    def _start(self, **_) -> None:
        self.handler = stream_view(self.area, self.render_window, wrap_interactive=self._render_interactive,
                                   target_fps=TARGET_FPS, interactive_quality=INTERACTIVE_QUALITY, still_quality=STILL_QUALITY,
                                   deliver=self.gate.deliver)
        self.gate.asked()
        self.handler.update()

    def _render_interactive(self, render):
        """An interactive picture: after `draft_next` was set, rendered at that fraction of the window's size."""
        scale, self.draft_next = self.draft_next, None
        if scale is None or scale >= 1.0:
            return render()
        width, height = self.render_window.GetSize()
        self.render_window.SetSize(max(10, round(width * scale)), max(10, round(height * scale)))
        try:
            with texts_scaled(self.render_window, scale):
                return render()  # renders and reads the pixels now; encoding goes on elsewhere
        finally:
            self.render_window.SetSize(width, height)

    def update(self, draft: bool = False, scale: float = DRAFT_SCALE) -> None:
        """Render and send a new picture (nothing before the server runs: the page asks for one when it opens);
        `draft`: its first picture at `scale` of the view's width and height (a label change, or playback, where the
        time to the picture counts most)."""
        if self.handler is not None:
            if draft:
                self.draft_next = min(scale, self.draft_next or 1.0)
            self.gate.asked()
            self.handler.update()

    async def wait_encoded(self) -> None:
        """Return once the picture asked for last is encoded (sent, or held back until the page shows the one before)."""
        if self.handler is not None:
            await self.gate.wait_encoded()


@contextlib.contextmanager
def texts_scaled(render_window, scale: float):
    """Every text drawn in the window (the figures' captions) at `scale` of its font size: a picture rendered smaller
    and stretched by the page would otherwise show its captions 1/scale times larger than the still picture does."""
    props = []
    for renderer in _renderers(render_window):
        for prop in _items(renderer.GetViewProps()):
            text = getattr(prop, "GetTextProperty", None)
            if text is not None and text() is not None:
                props.append((text(), text().GetFontSize()))
    for text, size in props:
        text.SetFontSize(max(1, round(size * scale)))
    try:
        yield
    finally:
        for text, size in props:
            text.SetFontSize(size)


def _renderers(render_window) -> list:
    return [render_window.GetRenderers().GetItemAsObject(i) for i in range(render_window.GetRenderers().GetNumberOfItems())]


def _items(collection) -> list:
    return [collection.GetItemAsObject(i) for i in range(collection.GetNumberOfItems())]
