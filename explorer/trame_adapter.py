"""Every place the studio relies on trame, trame-rca or wslink beyond their documented API, in one module.

Written for trame 4.0.0 (trame-server 4.1.0, trame-client 4.1.4), trame-rca 2.11.8 and wslink 2.6.0; pyproject.toml's
studio extra keeps trame and trame-rca in the ranges these were checked on. tests/test_trame_adapter.py checks that
the installed packages still have each thing below, naming the package and its version when one has gone.

1. The page's index.html (trame-client). `trame_client.module.vue3.www` is trame's client folder; its index.html
   loads CLIENT_FIRST_SCRIPT first, and the studio's scripts go in before it (explorer/serving/page_shell.py).
   Enabling `trame_client.module` (which trame-server would enable when it starts, since no page is set), then a
   module whose "www" is the studio's copy, makes trame-server serve that copy: `enable_module` keeps the last "www".
2. The browser side of that page (explorer/static/websocket_bytes.js). trame's client bundle (wslink's JavaScript)
   sets its websocket's binaryType to `blob` and reads each message with `slice` and `arrayBuffer()`; the script
   hands it ArrayBuffers in a wrapper with just those.
3. The picture scheduler (trame-rca). A subclass of `trame_rca.schedulers.RcaImageRenderScheduler` overrides its
   private `_render_frame(quality)` and reads its private `_interactive_quality`, to wrap each interactive render
   (explorer/rendering/view_stream.py renders a label change's first picture smaller).
4. The view handler (trame-rca). Built as `RemoteControlledArea.create_view_handler` builds one
   (`trame_rca.rca.window_wrapper`, `trame_rca.view_adapter.RcaViewAdapter(window, name, scheduler=...)`,
   `area.add_view_handler`), with that scheduler; its `on_interaction(origin, event)` is replaced on the instance
   so that key events never reach VTK's default key bindings; the scheduler's push callback, which the adapter sets
   to its `push(content, meta)`, is set again to hand that push to the caller (explorer/rendering/view_stream.py
   holds a picture back until the page has shown the one before), with the still picture told from an interactive one
   by the encoder's `meta["quality"]`, and its `streamer` (None until a page connects) says whether a push reaches a
   page.
5. Downloads (trame-server + wslink). `server.protocol.addAttachment(bytes)` turns a trigger's return value into a
   binary attachment the page can download (explorer/ui/exports.py).
6. The websocket secret (trame-server + wslink). `server.cli.set_defaults(authKey=...)` sets wslink's `--authKey`
   before the server parses its arguments (explorer/serving/worker.py).
7. wslink's wire format (explorer/serving/proxy.py, which speaks it without importing wslink). Every binary frame
   starts with a WSLINK_HEADER-byte header (message id, offset, total size: uint32 little-endian each,
   wslink/chunking.py), and the browser's first message is the msgpack call WSLINK_HELLO whose first argument
   carries `secret` (wslink/protocol.py).
8. What the zygote imports before forking (PRELOAD): trame's server, trame-rca's image scheduler and wslink's
   websocket protocol, by module path.
9. The page's module scripts and styles (trame-server + trame-client). trame's client loads the URLs in the state's
   ASSET_LISTS (`trame__scripts`, ...: paths relative to the page, each under a folder of `server.serve`) once it has
   the state; rewritten there before the server starts, they load from the launcher's one path for every tab.

Nothing here imports trame, trame-rca or wslink at module level: the launcher reads the wire-format constants
without loading them.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from pathlib import Path

CLIENT_FIRST_SCRIPT = '<script src="vue.global.js"></script>'  # 1: trame's first script; the studio's go before it
WSLINK_HEADER = 12  # 7: bytes of wslink's chunk header
WSLINK_HELLO = "wslink.hello"  # 7: the method of the browser's first message
PRELOAD = ("trame.app", "trame_rca.schedulers.image_scheduler", "wslink.websocket")  # 8
ASSET_LISTS = ("trame__scripts", "trame__module_scripts", "trame__styles")  # 9: URLs trame's client loads


# ---- 1. the page ---------------------------------------------------------------------------------------------------
def client_www() -> Path:
    """trame's client folder (index.html, vue.global.js, assets/)."""
    from trame_client.module import vue3

    return Path(vue3.www)


def serve_page(server, www: Path, serve: dict[str, str]) -> None:
    """Serve the folder `www` as `server`'s page, and `serve` ({url path: folder}) beside it; call once the page's
    modules are enabled, before the server starts."""
    from trame_client import module

    server.enable_module(module)  # trame's client, which the server would enable when it starts; its page is replaced
    server.enable_module({"www": str(www), "serve": serve})


def module_assets(server) -> dict[str, str]:
    """9. {url: folder}: the folders `server` serves that its page's module scripts and styles come from (trame's
    client module enabled first, as serve_page enables it)."""
    from trame_client import module

    server.enable_module(module)
    used = {url.split("/", 1)[0] for key in ASSET_LISTS for url in server.state[key] or [] if "/" in url}
    return {top: str(folder) for top, folder in server.serve.items() if top in used}


def relocate_assets(server, folders: dict[str, str], prefix: str) -> None:
    """9. The page's module scripts and styles under `folders` load from `prefix` + their path instead."""
    for key in ASSET_LISTS:
        server.state[key] = [prefix + url if url.split("/", 1)[0] in folders else url for url in server.state[key] or []]


# ---- 3, 4. the picture stream ---------------------------------------------------------------------------------------
@functools.cache
def _wrapping_scheduler():
    from trame_rca.schedulers import RcaImageRenderScheduler

    class WrappingScheduler(RcaImageRenderScheduler):
        """trame-rca's image scheduler, except that each interactive frame is rendered through
        `wrap_interactive(render)`, which calls `render()` (its own way: resized, say) and returns its result."""

        def __init__(self, window, wrap_interactive: Callable, **kwargs):
            super().__init__(window, **kwargs)
            self.wrap_interactive = wrap_interactive

        def _render_frame(self, quality):
            render = functools.partial(super()._render_frame, quality)
            if quality != self._interactive_quality:
                return render()
            return self.wrap_interactive(render)

    return WrappingScheduler


def stream_view(area, render_window, *, wrap_interactive: Callable, target_fps: float, interactive_quality: int,
                still_quality: int, encoder: str = "jpeg",
                deliver: Callable[[Callable[[], bool], bool], None] = lambda send, still: send()):
    """A view handler streaming `render_window` into the page's RemoteControlledArea `area` (once the server runs: its
    scheduler's loop is an asyncio task), interactive frames rendered through `wrap_interactive`, each encoded picture
    handed to `deliver(send, still)`, which sends it to the page by calling `send()` (now or later; False: no page
    yet); `still`: the picture is the still one, encoded at `still_quality`. Key events dropped (the
    studio's keys are its own: explorer/ui/keys.py; VTK's defaults would act on them, 'r' resetting the camera, 'w'
    drawing wireframes, 'e' ending the interactor). -> the handler (its `update()` asks for a picture)."""
    from trame_rca.rca import window_wrapper
    from trame_rca.view_adapter import RcaViewAdapter

    window = window_wrapper(render_window)
    scheduler = _wrapping_scheduler()(window, wrap_interactive, target_fps=target_fps, rca_encoder=encoder,
                                      interactive_quality=interactive_quality, still_quality=still_quality)
    handler = RcaViewAdapter(window, area.name, scheduler=scheduler)
    push = handler.push

    def send(content, meta) -> bool:
        if handler.streamer is None:  # no page connected yet: push() would drop it
            return False
        push(content, meta)
        return True

    def hand_over(content, meta) -> None:  # was handler.push
        deliver(functools.partial(send, content, meta), meta.get("quality") == still_quality)

    scheduler.set_push_callback(hand_over)
    area.add_view_handler(handler)
    forward = handler.on_interaction

    def mouse_and_touch_only(origin, event):
        if not str(event.get("type", "")).startswith("Key"):
            forward(origin, event)

    handler.on_interaction = mouse_and_touch_only
    return handler


# ---- 5, 6. the server ---------------------------------------------------------------------------------------------
def attachment(server, data: bytes):
    """`data` as a binary attachment: what a trigger returns for the page to download."""
    return server.protocol.addAttachment(memoryview(data))


def set_secret(server, secret: str) -> None:
    """The secret a browser's hello must carry (wslink's default is public: every studio process gets its own)."""
    server.cli.set_defaults(authKey=secret)


# ---- 8. the zygote --------------------------------------------------------------------------------------------------
def preload() -> None:
    """Import trame's, trame-rca's and wslink's serving modules (before forking, so that no child imports them)."""
    for name in PRELOAD:
        importlib.import_module(name)
