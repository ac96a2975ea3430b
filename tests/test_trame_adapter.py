"""explorer/trame_adapter.py: every trame, trame-rca and wslink internal it relies on is still there in the installed
packages. Each check fails naming the package, its version and the adapter's numbered patch, so that an upgrade that
drops one is found here rather than as a blank studio page."""

from __future__ import annotations

import asyncio
import importlib
import importlib.metadata
import inspect
import re
from pathlib import Path

import numpy as np
import pytest

from explorer import trame_adapter

pytest.importorskip("trame")
pytest.importorskip("trame_rca")


def where(package: str, patch: int) -> str:
    """'<package> <installed version> (explorer/trame_adapter.py patch N)', the prefix of every failure."""
    return f"{package} {importlib.metadata.version(package)} (explorer/trame_adapter.py patch {patch})"


def params(fn) -> list[str]:
    return list(inspect.signature(fn).parameters)


# ---- 1, 2. the page ------------------------------------------------------------------------------------------------
def test_trames_client_page_still_has_what_the_shell_rewrites():
    www = trame_adapter.client_www()
    index = www / "index.html"
    assert index.is_file(), f"{where('trame-client', 1)}: no index.html in trame_client.module.vue3.www ({www})"
    assert trame_adapter.CLIENT_FIRST_SCRIPT in index.read_text(), (
        f"{where('trame-client', 1)}: index.html no longer loads {trame_adapter.CLIENT_FIRST_SCRIPT} (the studio's scripts go before it)")
    assert (www / "vue.global.js").is_file(), f"{where('trame-client', 1)}: no vue.global.js beside index.html"


def test_the_last_www_enabled_is_the_page_trame_serves(tmp_path):
    from trame.app import get_server
    from trame_server.core import Server

    assert "module" in params(Server.enable_module), f"{where('trame-server', 1)}: Server.enable_module(module) changed"
    server = get_server("trame-adapter-test", client_type="vue3")
    trame_adapter.serve_page(server, tmp_path, {"imm_test": str(tmp_path)})
    assert getattr(server, "_www", None) == str(tmp_path), (
        f"{where('trame-server', 1)}: enable_module no longer keeps the last module's 'www' as the page (Server._www)")
    assert server.serve.get("imm_test") == str(tmp_path), f"{where('trame-server', 1)}: a module's 'serve' is not served"
    source = inspect.getsource(Server)
    assert re.search(r"if self\._www is None:\s*\n\s*from trame_client import module", source), (
        f"{where('trame-server', 1)}: Server no longer enables trame_client's module only when no page is set")


def test_module_scripts_and_styles_are_still_urls_in_the_state_that_the_client_loads(tmp_path):
    """9: a module's scripts and styles land in the state's ASSET_LISTS as page-relative URLs under a folder the server
    serves, and trame's client bundle still loads the state's lists; relocate_assets renames those under `folders`."""
    from trame.app import get_server

    server = get_server("trame-adapter-assets-test", client_type="vue3")
    server.enable_module({"serve": {"__imm_lib": str(tmp_path)}, "scripts": ["__imm_lib/a.js"], "styles": ["__imm_lib/a.css"],
                          "module_scripts": ["__imm_lib/m.js"]})
    folders = trame_adapter.module_assets(server)
    assert folders.get("__imm_lib") == str(tmp_path), f"{where('trame-server', 9)}: a module's scripts are not under server.serve"
    trame_adapter.relocate_assets(server, folders, "../../static/k/")
    lists = {key: server.state[key] for key in trame_adapter.ASSET_LISTS}
    assert lists == {"trame__scripts": ["../../static/k/__imm_lib/a.js"], "trame__module_scripts": ["../../static/k/__imm_lib/m.js"],
                     "trame__styles": ["../../static/k/__imm_lib/a.css"]}, f"{where('trame-server', 9)}: {lists}"
    bundle = "".join(p.read_text() for p in (trame_adapter.client_www() / "assets").glob("index-*.js"))
    for key in trame_adapter.ASSET_LISTS:
        assert key in bundle, f"{where('trame-client', 9)}: the client bundle no longer loads the state's {key}"


def test_trames_client_bundle_reads_binary_messages_as_the_bytes_script_expects():
    bundles = [p.read_text(errors="replace") for p in (trame_adapter.client_www() / "assets").glob("*.js")]
    assert any(re.search(r"binaryType\s*=\s*[`'\"]blob[`'\"]", b) for b in bundles), (
        f"{where('trame-client', 2)}: the client bundle no longer sets binaryType to 'blob' (static/websocket_bytes.js)")
    assert any(".arrayBuffer()" in b and ".slice(" in b for b in bundles), (
        f"{where('trame-client', 2)}: the client bundle no longer reads messages with slice() and arrayBuffer()")


# ---- 3, 4. the picture stream ----------------------------------------------------------------------------------------
class FakeWindow:
    """A remote-controlled area (trame-rca's RemoteControlledAreaProtocol) that counts what it is asked."""

    def __init__(self):
        self.events, self.grabs = [], 0

    @property
    def img_cols_rows(self):
        self.grabs += 1
        return np.zeros((4 * 4 * 3,), np.uint8), 4, 4

    def process_resize_event(self, width, height):
        pass

    def process_interaction_event(self, event):
        self.events.append(event)


class FakeArea:
    name = "view"

    def __init__(self):
        self.handlers = []

    def add_view_handler(self, handler):
        self.handlers.append(handler)


def test_the_image_scheduler_still_has_the_private_render_hook():
    from trame_rca.schedulers import RcaImageRenderScheduler

    assert params(getattr(RcaImageRenderScheduler, "_render_frame", lambda: None)) == ["self", "quality"], (
        f"{where('trame-rca', 3)}: RcaImageRenderScheduler._render_frame(self, quality) is gone or changed")
    init = params(RcaImageRenderScheduler.__init__)
    for name in ("window", "target_fps", "interactive_quality", "still_quality", "rca_encoder"):
        assert name in init, f"{where('trame-rca', 3)}: RcaImageRenderScheduler.__init__ has no {name!r}"
    assert "self._render_frame(interactive)" in inspect.getsource(RcaImageRenderScheduler), (
        f"{where('trame-rca', 3)}: the render loop no longer renders through self._render_frame")


def test_interactive_frames_go_through_the_wrapper_and_keys_never_reach_vtk():
    from trame_rca.rca import RemoteControlledAreaProtocol, window_wrapper  # noqa: F401 - patch 4 uses window_wrapper
    from trame_rca.view_adapter import RcaViewAdapter

    assert {"window", "name", "scheduler"} <= set(params(RcaViewAdapter.__init__)), (
        f"{where('trame-rca', 4)}: RcaViewAdapter(window, name, scheduler=...) changed")
    assert len(params(RcaViewAdapter.on_interaction)) == 3, (
        f"{where('trame-rca', 4)}: RcaViewAdapter.on_interaction(origin, event) changed")
    assert isinstance(FakeWindow(), RemoteControlledAreaProtocol), f"{where('trame-rca', 4)}: RemoteControlledAreaProtocol changed"

    class FakeStreamer:
        pushed = []

        def push_content(self, name, meta, content):
            self.pushed.append((name, content))

    streamer, delivered = FakeStreamer(), []

    async def run():
        window, area, wrapped, after = FakeWindow(), FakeArea(), [], []

        def wrap(render):
            before = window.grabs
            result = render()
            wrapped.append(window.grabs - before)  # the render grabbed the window's pixels once, inside the wrapper
            after.append(window.grabs)
            return result

        handler = trame_adapter.stream_view(area, window, wrap_interactive=wrap, target_fps=30, interactive_quality=70,
                                            still_quality=85, deliver=lambda send, still: delivered.append((send, still)))
        assert area.handlers == [handler]
        handler.set_streamer(streamer)
        handler.update()
        # the scheduler's loop renders the interactive frame, then the still one, and hands each encoded picture over:
        # wait for the second hand-over, not the grab before it (a generous deadline: a busy 2-core machine)
        loop = asyncio.get_running_loop()
        deadline = loop.time() + 60
        while not (after and window.grabs > after[-1] and len(delivered) >= 2):
            if loop.time() > deadline:
                break  # the assertions below say what is missing
            await asyncio.sleep(0.01)
        handler.on_interaction(None, {"type": "KeyPress", "key": "r"})
        handler.on_interaction(None, {"type": "LeftButtonPress", "x": 1, "y": 1})
        await handler.close()
        return window, wrapped, after

    window, wrapped, after = asyncio.run(run())
    assert len(delivered) == 2 and not streamer.pushed, (
        f"{where('trame-rca', 4)}: the encoded pictures did not go through the push callback ({len(delivered)} handed over, "
        f"{len(streamer.pushed)} pushed past it)")
    assert [still for _, still in delivered] == [False, True], (
        f"{where('trame-rca', 4)}: the picture's meta no longer tells the still picture by its quality")
    for send, _ in delivered:
        send()
    assert [name for name, _ in streamer.pushed] == ["view", "view"] and all(len(c) > 0 for _, c in streamer.pushed), (
        f"{where('trame-rca', 4)}: a picture handed over did not reach the page's stream (RcaViewAdapter.push)")
    assert wrapped == [1], f"{where('trame-rca', 3)}: the interactive frame did not render through the wrapper ({wrapped})"
    assert window.grabs > after[-1], f"{where('trame-rca', 3)}: the still frame after it was not rendered (outside the wrapper)"
    assert [e["type"] for e in window.events] == ["LeftButtonPress"], (
        f"{where('trame-rca', 4)}: a key reached the window, or the mouse did not ({window.events})")


# ---- 5, 6. the server ----------------------------------------------------------------------------------------------
def test_attachments_and_the_secret_still_go_where_the_adapter_puts_them():
    from trame.app import get_server
    from trame_server.core import Server
    from wslink.protocol import WslinkHandler
    from wslink.websocket import ServerProtocol

    assert isinstance(inspect.getattr_static(Server, "protocol"), property), f"{where('trame-server', 5)}: Server.protocol"
    assert "addAttachment" in params(ServerProtocol.init), f"{where('wslink', 5)}: ServerProtocol.init(.., addAttachment, ..)"
    assert callable(getattr(WslinkHandler, "addAttachment", None)), f"{where('wslink', 5)}: WslinkHandler.addAttachment"
    server = get_server("trame-adapter-secret", client_type="vue3")
    trame_adapter.set_secret(server, "adapter-test-secret")
    args, _ = server.cli.parse_known_args([])
    assert getattr(args, "authKey", None) == "adapter-test-secret", (
        f"{where('wslink', 6)}: the server's command line has no --authKey default to set")


# ---- 7. wslink's wire format ----------------------------------------------------------------------------------------
def test_wslinks_chunk_header_and_hello_are_what_the_proxy_speaks():
    from wslink import chunking, protocol

    assert getattr(chunking, "HEADER_LENGTH", None) == trame_adapter.WSLINK_HEADER, (
        f"{where('wslink', 7)}: chunk header is {getattr(chunking, 'HEADER_LENGTH', None)} bytes, not {trame_adapter.WSLINK_HEADER}")
    header = (7).to_bytes(4, "little") + (0).to_bytes(4, "little") + (99).to_bytes(4, "little")
    assert chunking._encode_header(7, 0, 99) == header, f"{where('wslink', 7)}: chunk header layout (id, offset, size)"
    source = inspect.getsource(protocol)
    assert f'"{trame_adapter.WSLINK_HELLO}"' in source and '"secret"' in source, (
        f"{where('wslink', 7)}: the hello ({trame_adapter.WSLINK_HELLO} with a 'secret') is not what wslink checks")


# ---- 8. the zygote's preload ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", trame_adapter.PRELOAD)
def test_every_preloaded_module_is_there(name):
    package = {"trame": "trame", "trame_rca": "trame-rca", "wslink": "wslink"}[name.split(".")[0]]
    try:
        importlib.import_module(name)
    except ImportError as err:
        pytest.fail(f"{where(package, 8)}: cannot import {name}: {err}")


# ---- 10. what a client may send ------------------------------------------------------------------------------------
def test_what_guard_client_input_replaces_is_still_there():
    from trame_server.protocol import CoreServer
    from wslink import chunking, protocol
    from wslink.backends import aiohttp as wslink_aiohttp

    assert "UnChunker()" in inspect.getsource(protocol.WslinkHandler.onConnect) and protocol.UnChunker is not None, (
        f"{where('wslink', 10)}: WslinkHandler.onConnect no longer makes wslink.protocol.UnChunker()")
    unchunker = chunking.UnChunker()
    assert isinstance(unchunker.pending_messages, dict) and isinstance(unchunker.max_message_size, int), (
        f"{where('wslink', 10)}: UnChunker's pending_messages / max_message_size")
    assert chunking._decode_header(chunking._encode_header(7, 3, 99)) == (7, 3, 99), f"{where('wslink', 10)}: _decode_header"
    assert params(protocol.WslinkHandler.onMessage) == ["self", "is_binary", "msg", "client_id"], (
        f"{where('wslink', 10)}: WslinkHandler.onMessage(is_binary, msg, client_id) changed")
    assert "MSG_OVERHEAD + MAX_MSG_SIZE" in inspect.getsource(wslink_aiohttp), (
        f"{where('wslink', 10)}: the aiohttp backend's frame limit is no longer MSG_OVERHEAD + MAX_MSG_SIZE")
    uris = [u.get("uri") for u in getattr(CoreServer.update_state, "_wslinkuris", [])]
    assert uris == ["trame.state.update"] and params(CoreServer.update_state) == ["self", "changes"], (
        f"{where('trame-server', 10)}: CoreServer.update_state(changes) is no longer the trame.state.update call")
    assert "on_error" in inspect.getsource(CoreServer.js_error), f"{where('trame-server', 10)}: trame.error.client's on_error"
    uris = [u.get("uri") for u in getattr(CoreServer.trigger, "_wslinkuris", [])]
    assert uris == ["trame.trigger"] and params(CoreServer.trigger) == ["self", "name", "args", "kwargs"], (
        f"{where('trame-server', 10)}: CoreServer.trigger(name, args, kwargs) is no longer the trame.trigger call")
    assert "trigger_fn(name)" in inspect.getsource(CoreServer.trigger), f"{where('trame-server', 10)}: controller.trigger_fn"
    server = trame_adapter.make_server("trame-adapter-frames")
    assert server.options["ws_max_msg_size"] == trame_adapter.MAX_FRAME_BYTES, f"{where('trame-server', 10)}: ws_max_msg_size"
    assert "server.options[\"ws_max_msg_size\"]" in inspect.getsource(CoreServer.bind_server), (
        f"{where('trame-server', 10)}: ws_max_msg_size no longer reaches wslink")


def test_the_bounded_unchunker_joins_chunks_and_refuses_what_would_unpack_to_too_much(monkeypatch):
    import msgpack
    from wslink.chunking import _encode_header

    refused = []
    unchunker_class = trame_adapter._bounded_unchunker()
    monkeypatch.setattr(unchunker_class, "refused", staticmethod(refused.append))
    unchunker = unchunker_class()
    unchunker.set_max_message_size(1 << 30)
    body = msgpack.packb({"method": "trame.state.update", "args": [[{"key": "frame", "value": 3}]]})
    half = len(body) // 2
    assert unchunker.process_chunk(_encode_header(1, half, len(body)) + body[half:]) is None  # in any order, as wslink's
    assert unchunker.process_chunk(_encode_header(1, 0, len(body)) + body[:half]) == msgpack.unpackb(body)
    deep = b"\x91" * 100_000 + b"\xc0"
    assert unchunker.process_chunk(_encode_header(2, 0, len(deep)) + deep) is None
    assert unchunker.process_chunk(_encode_header(3, 0, 4) + b"\xc1\xc1\xc1\xc1") is None
    assert unchunker.process_chunk(_encode_header(4, 0, 2) + b"abc") is None
    assert not unchunker.pending_messages
    assert refused == ["it is nested more than 64 levels deep", "not a msgpack message (FormatError)",
                       "its chunks disagree on its size"], refused
    stranger = unchunker_class()  # no hello with the secret yet: refused and logged, but its words reach no page
    assert stranger.process_chunk(_encode_header(5, 0, 600) + b"x") is None and len(refused) == 3


def test_the_adapter_is_the_only_module_reaching_into_trame_privates():
    """No other studio module names the private attributes the adapter patches."""
    root = Path(trame_adapter.__file__).parent
    names = ("_render_frame", "_interactive_quality", "addAttachment", "authKey", "enable_module", "window_wrapper",
             "onMessage", "update_state", "ws_max_msg_size")
    for path in sorted(root.rglob("*.py")):
        if path.name == "trame_adapter.py":
            continue
        text = path.read_text()
        assert not [n for n in names if n in text], f"{path.relative_to(root.parent)} uses {[n for n in names if n in text]}"


# ---- 11. the page's template ---------------------------------------------------------------------------------------
def _nested_page(name: str):
    """A small layout nested five levels deep, with a state default and an inline style -> (template, the default)."""
    from trame.app import get_server
    from trame.ui.vuetify3 import VAppLayout
    from trame.widgets import client, html
    from trame.widgets import vuetify3 as v3

    server = get_server(name, client_type="vue3")
    with VAppLayout(server) as layout:
        with html.Div(classes="a"), html.Div(classes="b"), html.Div(classes="c"):
            v3.VSlider(v_model=("nested_value", 0.5), min=0, max=1)
            client.Style(".x { color: red; }")
    # the widgets' running ids (`w123-`) and the inline styles' state keys count across servers: compared by shape
    template = re.sub(r"w\d+-|trame__inline_style_\d+", "#", layout.html)
    return template, server.state.nested_value


def test_a_template_rendered_once_is_the_template_rendered_at_every_exit(monkeypatch):
    from trame_client.widgets import core, vue

    exit_before = core.AbstractElement.__exit__
    renders = []
    render = vue.HtmlElement.render  # what a widget's `html` calls (trame-client's Vue implementation)
    monkeypatch.setattr(vue.HtmlElement, "render", lambda self: renders.append(1) or render(self))
    every_exit, default_every_exit = _nested_page("trame-adapter-every-exit")
    n_every_exit, renders[:] = len(renders), []
    with trame_adapter.rendered_once():
        once, default_once = _nested_page("trame-adapter-once")
    assert core.AbstractElement.__exit__ is exit_before, "rendered_once left the widgets' exit replaced"
    assert once == every_exit, f"{where('trame-client', 11)}: rendered once, the page differs"
    assert default_once == default_every_exit == 0.5, f"{where('trame-client', 11)}: a v_model default no longer reaches the state"
    assert len(renders) < n_every_exit / 2, (len(renders), n_every_exit)
