"""Every place the studio relies on trame, trame-rca or wslink beyond their documented API, in one module.

Written for trame 4.0.0 (trame-server 4.1.0, trame-client 4.1.4), trame-rca 2.11.8 and wslink 2.6.0; pyproject.toml's
studio extra admits each one's patch releases of the minor version these were checked on. tests/test_trame_adapter.py
checks that the installed packages still have each thing below, naming the package and its version when one has gone.

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
10. What a client may make a studio process hold (wslink + trame-server). wslink's handler makes one
   `wslink.protocol.UnChunker` per websocket (onConnect), which joins a message's chunks and unpacks it with
   `msgpack.unpackb`: replaced by one that checks the message's shape first (BoundedUnChunker). The handler's
   `WslinkHandler.onMessage(is_binary, msg, client_id)` logs a text frame in full: wrapped to log it capped.
   `trame_server.protocol.CoreServer.update_state(changes)` (the `trame.state.update` call: a list of
   {"key", "value"}) stores any key: wrapped to keep only the keys the state has; `CoreServer.trigger(name, args,
   kwargs)` (`trame.trigger`) logs an unknown name in full: wrapped to refuse it first (`controller.trigger_fn`).
   The frame size a studio accepts is trame's `ws_max_msg_size` option plus wslink's 4 KB of overhead
   (wslink/backends/aiohttp).
11. The page's template (trame-client). `AbstractElement.__exit__` renders the widget's whole subtree at the end of
   every `with` block (a side effect kept for the state defaults it sets), so a nested layout is rendered once per
   level it is nested in: the studio's 518 widgets made 3685 renders, 0.25-0.45 s of every tab's start. Inside
   `rendered_once()` a widget's exit only leaves the element stack (`HTML_CTX.exit`); the layout's own exit
   (`AbstractLayout.__exit__`, then `flush_content`) renders the tree, and sets those defaults, once.

Nothing here imports trame, trame-rca or wslink at module level: the launcher reads the wire-format constants
without loading them.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import logging
from collections.abc import Callable
from pathlib import Path

CLIENT_FIRST_SCRIPT = '<script src="vue.global.js"></script>'  # 1: trame's first script; the studio's go before it
WSLINK_HEADER = 12  # 7: bytes of wslink's chunk header
WSLINK_HELLO = "wslink.hello"  # 7: the method of the browser's first message
PRELOAD = ("trame.app", "trame_rca.schedulers.image_scheduler", "wslink.websocket")  # 8
ASSET_LISTS = ("trame__scripts", "trame__module_scripts", "trame__styles")  # 9: URLs trame's client loads
# 10: the largest websocket frame the proxy relays (a studio process accepts this plus wslink's 4 KB of overhead, so
# every frame the proxy lets through is one the studio takes); the page's client sends chunks of at most 4 MB
MAX_FRAME_BYTES = 10_000_000
# 10: the most one message from a client may unpack to: objects (each a Python object of at most ~100 bytes beyond the
# message's own bytes: 100 k of them is ~10 MB) and nesting levels. The page's messages have a few dozen objects, ~6 deep.
MAX_MESSAGE_OBJECTS = 100_000
MAX_MESSAGE_DEPTH = 64
LOGGED_CHARS = 300  # 10: of a client's text in the log
log = logging.getLogger("imm.studio")


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


def make_server(name: str):
    """10. trame's server for this process, accepting websocket frames of up to MAX_FRAME_BYTES (plus wslink's overhead)."""
    from trame.app import get_server

    return get_server(name, client_type="vue3", ws_max_msg_size=MAX_FRAME_BYTES)


# ---- 10. what a client may send ------------------------------------------------------------------------------------
def capped(text) -> str:
    """A client's text for the log: one line (repr escapes newlines and terminal escape sequences), at most
    LOGGED_CHARS of it, and its full length."""
    text = str(text)
    shown = repr(text[:LOGGED_CHARS])
    return shown if len(text) <= LOGGED_CHARS else f"{shown}... ({len(text)} characters)"


def message_shape_problem(data: bytes, max_objects: int = MAX_MESSAGE_OBJECTS, max_depth: int = MAX_MESSAGE_DEPTH) -> str | None:
    """Why the msgpack message `data` would unpack to too much (more than `max_objects` objects or `max_depth` levels
    of nesting), read from its headers alone without building anything; None if it is within both (or is not
    msgpack at all: msgpack's own error then names that). msgpack's own limits are per container (max_array_len,
    ...), and a 16 MB array of empty maps, or many arrays each under a limit, would build gigabytes."""
    pos, objects, depth = 0, 0, 0
    left = [1]  # objects still to read at each open level
    end = len(data)
    while left:
        if left[-1] == 0:
            left.pop()
            continue
        left[-1] -= 1
        objects += 1
        if objects > max_objects:
            return f"it holds more than {max_objects} values"
        if pos >= end:
            return None
        b = data[pos]
        pos += 1
        if b <= 0x7F or b >= 0xE0 or b in (0xC0, 0xC2, 0xC3):  # fixint, nil, bool
            continue
        if 0x80 <= b <= 0x9F:  # fixmap, fixarray
            children = (b & 0x0F) * (2 if b < 0x90 else 1)
        elif b in _CONTAINER:
            width, per = _CONTAINER[b]
            children = int.from_bytes(data[pos:pos + width], "big") * per
            pos += width
        elif 0xA0 <= b <= 0xBF:  # fixstr
            pos += b & 0x1F
            continue
        elif b in _SIZED:  # str, bin, ext: a length, then (ext) a type byte, then the bytes
            width, extra = _SIZED[b]
            pos += width + extra + int.from_bytes(data[pos:pos + width], "big")
            continue
        else:  # numbers and fixext: a fixed size (0xC1 is never used: msgpack refuses it)
            pos += _FIXED.get(b, 0)
            continue
        if children:
            depth = len(left)
            if depth >= max_depth:
                return f"it is nested more than {max_depth} levels deep"
            left.append(children)
    return None


_CONTAINER = {0xDC: (2, 1), 0xDD: (4, 1), 0xDE: (2, 2), 0xDF: (4, 2)}  # array16/32, map16/32: (length bytes, per entry)
_SIZED = {0xC4: (1, 0), 0xC5: (2, 0), 0xC6: (4, 0), 0xC7: (1, 1), 0xC8: (2, 1), 0xC9: (4, 1),
          0xD9: (1, 0), 0xDA: (2, 0), 0xDB: (4, 0)}  # fmt: skip
_FIXED = {0xCA: 4, 0xCB: 8, 0xCC: 1, 0xCD: 2, 0xCE: 4, 0xCF: 8, 0xD0: 1, 0xD1: 2, 0xD2: 4, 0xD3: 8,
          0xD4: 2, 0xD5: 3, 0xD6: 5, 0xD7: 9, 0xD8: 17}  # fmt: skip


@functools.cache
def _bounded_unchunker():
    import msgpack
    from wslink.chunking import HEADER_LENGTH, UnChunker, _decode_header

    class BoundedUnChunker(UnChunker):
        """wslink's UnChunker (chunks joined by id, a message's claimed size checked before it is allocated), except
        that a whole message is unpacked only within MAX_MESSAGE_OBJECTS and MAX_MESSAGE_DEPTH, and one it refuses
        is logged, dropped (the websocket stays open) and, from a client that has logged in, handed to `refused(why)`."""

        refused: Callable[[str], None] = staticmethod(lambda why: None)
        logged_in = False  # wslink lifts the size limit once a client's hello carried the secret

        def set_max_message_size(self, size):
            super().set_max_message_size(size)
            self.logged_in = True

        def process_chunk(self, chunk: bytes):
            id, offset, total = _decode_header(chunk[:HEADER_LENGTH])
            content = chunk[HEADER_LENGTH:]
            pending = self.pending_messages.get(id)
            if pending is None:
                if total > self.max_message_size:
                    return self.refuse(f"it claims {total} bytes (at most {self.max_message_size})")
                pending = self.pending_messages[id] = {"received_size": 0, "content": bytearray(total)}
            if total != len(pending["content"]) or offset + len(content) > total:
                del self.pending_messages[id]
                return self.refuse("its chunks disagree on its size")
            pending["content"][offset:offset + len(content)] = content
            pending["received_size"] += len(content)
            if pending["received_size"] < total:
                return None
            del self.pending_messages[id]
            message = bytes(pending["content"])
            if (problem := message_shape_problem(message)) is not None:
                return self.refuse(problem)
            try:
                return msgpack.unpackb(message)
            except (ValueError, msgpack.UnpackException) as err:  # ExtraData, FormatError, StackError, ...
                return self.refuse(f"not a msgpack message ({type(err).__name__})")

        def refuse(self, why: str) -> None:
            log.warning("refused a websocket message: %s", why)
            if self.logged_in:  # not a stranger on the loopback port: its page hears why
                type(self).refused(why)

    return BoundedUnChunker


def guard_client_input(server, refused: Callable[[str], None]) -> None:
    """10. Bound what a client can make this process hold or log: each websocket message unpacked within
    MAX_MESSAGE_OBJECTS and MAX_MESSAGE_DEPTH (one that is not is dropped, and `refused(why)` called for a client that
    has logged in), only the state keys the page has set by a client, only the page's triggers called, and its text
    frames and error reports logged capped. Call before the server starts; once per process (it changes wslink's and
    trame-server's classes: one server per studio process)."""
    import wslink.protocol
    from trame_server.protocol import CoreServer

    unchunker = _bounded_unchunker()
    unchunker.refused = staticmethod(refused)
    wslink.protocol.UnChunker = unchunker  # what WslinkHandler.onConnect makes for each websocket

    on_message = wslink.protocol.WslinkHandler.onMessage

    @functools.wraps(on_message)
    async def binary_only(self, is_binary, msg, client_id):
        if not is_binary:  # wslink speaks binary: it would log the whole text
            log.warning("ignored a text websocket message: %s", capped(msg.data))
            return None
        return await on_message(self, is_binary, msg, client_id)

    wslink.protocol.WslinkHandler.onMessage = binary_only

    update_state = CoreServer.update_state

    @functools.wraps(update_state)  # keeps wslink's registration of the call (its __dict__)
    def known_keys_only(self, changes):
        known, others = [], []
        for change in changes if isinstance(changes, list) else [changes]:
            key = change.get("key") if isinstance(change, dict) else change
            if isinstance(key, str) and key in server.state:
                known.append(change)
            else:
                others.append(key)
        if others:
            log.warning("ignored %d state changes for keys the page does not have: %s", len(others), capped(others))
        return update_state(self, known) if known else None

    CoreServer.update_state = known_keys_only

    trigger = CoreServer.trigger

    @functools.wraps(trigger)
    async def known_triggers_only(self, name, args, kwargs):
        if not isinstance(name, str) or server.controller.trigger_fn(name) is None:  # trame would log the whole name
            log.warning("ignored a call of a trigger the page does not have: %s", capped(name))
            return None
        return await trigger(self, name, args, kwargs)

    CoreServer.trigger = known_triggers_only
    server.controller.on_error.add(lambda message: log.warning("error in the page: %s", capped(message)))


# ---- 8. the zygote --------------------------------------------------------------------------------------------------
def preload() -> None:
    """Import trame's, trame-rca's and wslink's serving modules (before forking, so that no child imports them)."""
    for name in PRELOAD:
        importlib.import_module(name)


# ---- 11. the page's template ---------------------------------------------------------------------------------------
@contextlib.contextmanager
def rendered_once():
    """Widgets built inside render when the enclosing layout's `with` ends, not at every nested `with`'s end."""
    from trame_client.widgets.core import HTML_CTX, AbstractElement

    render_on_exit = AbstractElement.__exit__
    AbstractElement.__exit__ = lambda self, *exc: HTML_CTX.exit(self)
    try:
        yield
    finally:
        AbstractElement.__exit__ = render_on_exit
