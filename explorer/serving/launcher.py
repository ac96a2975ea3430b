"""`imm explore`'s front door: one studio process per browser client.

A trame server shares one state among all its clients, so two people on one server would move each
other's sliders. The launcher listens on the public port; each visit to `/` takes a warm studio
process (explorer/serving/worker.py, forked by explorer/serving/zygote.py and listening on its own loopback port) when the
front page's script claims one (a same-origin POST: a bare GET or another web page cannot), forwards the tab
to it (proxy.py) and forks the next spare in the background. A tab's studio process is ended (by the zygote, with
SIGKILL if it is too busy to stop) RECONNECT_GRACE_S after its last websocket closed, or CLAIM_TIMEOUT_S after a claim
that no browser connected to (CLAIM_VISIT_S if its page was not even asked for), so a closed tab frees its client slot
within seconds. A studio process that has not answered its tab's page or websocket within ANSWER_S is stuck: it is
ended, and the tab is sent to a fresh one.
"""

from __future__ import annotations

import asyncio
import errno
import functools
import gc
import hmac
import html
import os
import secrets
import signal
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from explorer.serving.access import PAGE_COOKIE, TOKEN_COOKIE, Access
from explorer.serving.pool import RECONNECT_GRACE_S, LaunchError, WorkerPool

# Set by a claim, one random value per browser: a tab's /s/<token>/ answers only the browser that claimed it, so its
# address, copied into another browser, opens a studio of its own there (with the view the address names).
BROWSER_COOKIE = "imm_studio_browser"
# a claimed studio process whose browser never connects is ended after this ($IMM_STUDIO_CLAIM_TIMEOUT: tests)
CLAIM_TIMEOUT_S = float(os.environ.get("IMM_STUDIO_CLAIM_TIMEOUT", "20"))
# A tab asks for its page the moment its claim is answered: a claim whose page is not asked for within CLAIM_VISIT_S is
# retired, and so is the oldest such claim when a claim finds every slot taken, so a script posting claims in a loop
# never keeps a tab from a studio.
CLAIM_VISIT_S = min(5.0, CLAIM_TIMEOUT_S)
# A studio process answers its page's websocket in milliseconds: one that has not within ANSWER_S is stuck, and is
# replaced (proxy.py forward_websocket; $IMM_STUDIO_ANSWER_TIMEOUT: tests)
ANSWER_S = float(os.environ.get("IMM_STUDIO_ANSWER_TIMEOUT", "30"))
# Stopping waits for the studio processes (pool.py STOP_S), then at most CLOSE_S for the tabs' connections to close:
# within 5 s in all.
CLOSE_S = 1.0
LOOPBACK = ("127.0.0.1", "localhost", "::1")
LAYOUT_LATE_S = 20  # a page loads itself again when its layout has not come this long after its studio answered
LATE_NOTE_CHARS = 600  # of the files such a page names as still loading, in the log
IMMUTABLE = "public, max-age=31536000, immutable"  # /static/: every name there changes with its content


@dataclass
class LaunchConfig:
    data: Path
    models: tuple[tuple[str, Path], ...]  # (name, checkpoint) in the switch's order: the first opens the studio
    host: str = "127.0.0.1"
    port: int = 0
    cache_dir: Path | None = None
    export_dir: Path = Path("imm-exports")
    max_clients: int = 8
    spares: int = 1
    open_browser: bool = True
    open_url: Callable[[str], None] | None = None  # what opens the ready URL (the desktop window); None: the system's browser
    sequence: str | None = None
    render: str = "remote"
    judge: str | None = None  # the 'reads as' classifier: a path, "none", or None for the bundled one
    # Access: None serves loopback host names only (DNS rebinding); a token is required in the first URL (then a
    # cookie) and admits any host name; no_auth admits every request (the user chose so for a non-loopback --host).
    token: str | None = None
    no_auth: bool = False
    base_url: str | None = None  # the address users open, behind a reverse proxy (printed instead of the local one)


def bind_socket(host: str, port: int) -> socket.socket:
    """Bind now, so a busy port is reported before anything slow starts."""
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as err:
        sock.close()
        if err.errno == errno.EADDRINUSE:
            raise LaunchError(f"port {port} on {host} is already in use (choose another with --port, or --port 0 for a free one)") from None
        raise LaunchError(f"cannot listen on {host}:{port}: {err.strerror or err}") from None
    sock.listen(64)
    sock.setblocking(False)
    return sock


class Launcher:
    def __init__(self, config: LaunchConfig):
        self.config = config
        self.pool = WorkerPool(config)  # the studio processes, one per tab (pool.py)
        self.access = Access(config)  # who is answered (access.py)
        self.url = ""
        self.assets: dict[str, Path] = {}  # /static/<name> -> its file (public libraries the page loads)

    # ---- http ----------------------------------------------------------------------------
    async def handle(self, request):
        """The front page: no studio process is taken by a GET (a bare request, a prefetch or another web
        page's <img> would otherwise hold one); its script claims one with a same-origin POST."""
        from aiohttp import web

        if not self.access.authorized(request):
            return web.Response(status=403, content_type="text/html",
                                text=_error_page("this studio needs its access token: open the address it printed at start"))
        page = web.Response(content_type="text/html", text=CLAIM_PAGE)
        if self.config.token and "token" in request.query:  # later requests (claim, studio) carry it as a cookie
            page.set_cookie(TOKEN_COOKIE, self.config.token, httponly=True, samesite="Strict", path="/")
        page.set_cookie(PAGE_COOKIE, self.access.page_secret, httponly=True, samesite="Strict", path="/")
        return page

    async def claim(self, request):
        """POST /claim from the front page -> {"url": the studio process for this tab}. Refused for a request from
        another web origin or addressed to a host name this studio does not serve (DNS rebinding), and for one that
        shows no sign of the page (a bare POST); rate-limited."""
        from aiohttp import web

        if not self.access.authorized(request) or not self.access.from_the_page(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        if not self.access.claim_allowed():
            return web.Response(status=429, content_type="text/html",
                                text=_error_page("too many new tabs at once: wait a second and reload"))
        self.pool.make_room()
        try:
            w = await self.pool.take()
        except LaunchError as err:
            return web.Response(status=503, content_type="text/html", text=_error_page(str(err)))
        asyncio.get_running_loop().call_later(CLAIM_VISIT_S, self.pool.retire_if_unvisited, w)
        asyncio.get_running_loop().call_later(CLAIM_TIMEOUT_S, self.pool.retire_if_unconnected, w, CLAIM_TIMEOUT_S)
        token = secrets.token_urlsafe(18)
        self.pool.sessions[token] = w
        w.browser = request.cookies.get(BROWSER_COOKIE) or secrets.token_urlsafe(18)
        answer = web.json_response({"url": f"s/{token}/"})  # relative: a reverse proxy's path prefix is kept
        answer.set_cookie(BROWSER_COOKIE, w.browser, httponly=True, samesite="Strict", path="/")
        return answer

    async def studio(self, request):
        """/s/<token>/<path>: the tab's page, assets and websocket, forwarded to its studio process."""
        from aiohttp import web

        from explorer.serving.proxy import InboundBudget, forward_http, forward_websocket

        if not self.access.authorized(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        w = self.pool.sessions.get(request.match_info["token"])
        if w is None or w.exited:
            self.pool.sessions.pop(request.match_info["token"], None)
        # an old or unknown link, or another browser's tab: back to the front page for a fresh studio, with the view the
        # link names
        fresh = web.HTTPFound("../../" + (f"?{request.query_string}" if request.query_string else ""))
        if w is None or w.exited or not hmac.compare_digest(request.cookies.get(BROWSER_COOKIE, "").encode(), w.browser.encode()):
            raise fresh
        tail = request.match_info["tail"]
        w.last_seen = time.monotonic()
        stuck = functools.partial(self.pool.retire_silent, w)
        if request.headers.get("Upgrade", "").lower() != "websocket":
            # the page asked for again once a websocket had connected is a reload, even while the closing one is still
            # being torn down here (the browser sends the new request as soon as the old page unloads)
            w.reloading = w.reloading or (w.connected and (not w.sockets or tail in ("", "index.html")))
            answer = await forward_http(request, w.port, tail, answer_s=ANSWER_S, on_silent=stuck)
            if answer is None and tail in ("", "index.html"):
                raise fresh  # its studio process was stuck, and is replaced: the page goes to a fresh one
            return answer or web.Response(status=504, text="the studio process of this tab did not answer: reload the page")
        w.sockets += 1
        w.connected, w.reloading = True, False
        w.budget = w.budget or InboundBudget()
        try:
            return await forward_websocket(request, w.port, tail, w.secret, w.budget, on_message=self.pool.note_traffic,
                                           answer_s=ANSWER_S, on_silent=stuck)
        finally:
            w.sockets -= 1
            w.last_seen = time.monotonic()
            if not w.sockets:
                asyncio.get_running_loop().call_later(RECONNECT_GRACE_S, self.pool.retire_if_gone, w)

    async def layout_late(self, request):
        """POST /s/<token>/layout-late from a tab's page about to load itself again because its layout had not come
        (explorer/static/websocket_bytes.js): said in one line with the files it was still waiting for (at most
        LATE_NOTE_CHARS of what the page sent, printable), so that a tab that recovered still names what held it."""
        from aiohttp import web

        w = self.pool.sessions.get(request.match_info["token"])
        if (not self.access.authorized(request) or not self.access.from_the_page(request) or w is None
                or not hmac.compare_digest(request.cookies.get(BROWSER_COOKIE, "").encode(), w.browser.encode())):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        waiting = (await request.content.read(LATE_NOTE_CHARS)).decode(errors="replace")
        waiting = "".join(c if c.isprintable() else "?" for c in waiting) or "nothing named"
        print(f"a tab's page was loaded again: its layout had not come {LAYOUT_LATE_S:g} s after its studio answered "
              f"(still loading: {waiting})", flush=True)
        return web.Response(status=204)

    async def no_session_manager(self, request):
        """trame's page first asks `paraview/` for a session (a ParaView-style launcher's endpoint) and connects to its
        own `ws` when that gives none: 204 says "none" without the 405 a browser would log on every load."""
        from aiohttp import web

        if not self.access.authorized(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        return web.Response(status=204)

    async def static(self, request):
        """/static/<name>: a public library the page loads (plotly.js), at one versioned path for every tab, cached by
        the browser for a year. No token or cookie (nothing in it is secret), but another web origin and, without a
        token, a host name this studio does not serve are refused as on every other path."""
        from aiohttp import web

        if not self.access.public(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        path = self.assets.get(request.match_info["name"])
        if path is None:
            return web.Response(status=404, text="not found")
        # aiohttp answers If-None-Match (its ETag: the file's mtime and size) with 304, and Range requests
        return web.FileResponse(path, headers={"Cache-Control": IMMUTABLE, "Content-Type": "text/javascript; charset=utf-8"})

    async def page_file(self, request):
        """/static/<key>/<path>: a file the page loads (vue, vuetify and its fonts, trame's client), from the page
        folder the studio processes serve (explorer/serving/page_shell.py), at one path for every tab and cached by
        the browser for a year: the key changes with the folder's content. Checked as `static`; not the page itself."""
        from aiohttp import web

        if not self.access.public(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        shell = self.pool.shells.get(request.match_info["key"])
        parts = request.match_info["tail"].split("/")
        if shell is None or parts == ["index.html"] or any(not p or p.startswith(".") for p in parts):
            return web.Response(status=404, text="not found")
        path = shell.joinpath(*parts)
        if not path.is_file():
            return web.Response(status=404, text="not found")
        return web.FileResponse(path, headers={"Cache-Control": IMMUTABLE})

    async def run(self, sock: socket.socket) -> int:
        t0 = time.monotonic()
        try:
            first = await self.pool.spawn()  # the zygote starts loading now; the web server's imports go beside it
            self.pool.spares.append(first)
            from aiohttp import web

            from explorer.serving.page_shell import PLOTLY_JS

            self.assets = {PLOTLY_JS.name: PLOTLY_JS}
            await first.ready  # bad data/checkpoint fail here, before any URL is printed
        except LaunchError:
            await self.pool.shutdown()
            raise
        app = web.Application()
        app.router.add_get("/", self.handle)
        app.router.add_post("/claim", self.claim)
        app.router.add_get("/s/{token}/{tail:.*}", self.studio)
        app.router.add_post("/s/{token}/paraview/", self.no_session_manager)
        app.router.add_post("/s/{token}/layout-late", self.layout_late)
        app.router.add_get("/static/{name}", self.static)
        app.router.add_get("/static/{key}/{tail:.+}", self.page_file)
        runner = web.AppRunner(app, access_log=None, shutdown_timeout=CLOSE_S)
        await runner.setup()
        await web.SockSite(runner, sock).start()
        # What is loaded now stays: out of the collector's sight, a full collection no longer walks aiohttp's and the
        # launcher's objects (33 ms here, in the middle of relaying a picture: docs/experiments/studio-performance.md).
        gc.freeze()
        port = sock.getsockname()[1]
        wildcard = {"0.0.0.0": socket.gethostname(), "::": socket.gethostname()}
        shown = "localhost" if self.config.host in LOOPBACK else wildcard.get(self.config.host, self.config.host)
        local = f"http://{shown}:{port}/"
        self.url = (self.config.base_url or local) + (f"?token={self.config.token}" if self.config.token else "")
        behind = f"; served from {local} behind it" if self.config.base_url else ""
        print(f"IMM Studio ready at {self.url} ({time.monotonic() - t0:.1f} s{behind}; one studio process per browser tab, "
              "Ctrl+C to stop)", flush=True)
        if self.config.open_browser:
            (self.config.open_url or _open_browser)(self.url)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)  # stop the studio processes too, not only this one
        try:
            await stop.wait()
        finally:
            # The studio processes first: their websockets close, which ends each tab's relay; then the web server, which
            # would otherwise wait on the open relays (32 s with a tab open).
            await self.pool.shutdown()
            await runner.cleanup()
        return 0

def _open_browser(url: str) -> None:
    """Open a graphical browser when there is a desktop; on a headless machine `webbrowser` would
    start a text-mode browser inside this terminal, so only say where the studio is."""
    has_desktop = sys.platform in ("darwin", "win32") or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    if not has_desktop:
        print("no desktop found: open the address above in a browser (or pass --no-browser)", flush=True)
        return
    import webbrowser

    try:
        webbrowser.open(url)
    except Exception:  # a missing browser must not stop the studio
        pass


# The front page names no icon file: a browser would ask for /favicon.ico and log the 404 on every load.
NO_ICON = '<link rel="icon" href="data:,">'
CLAIM_PAGE = f"""<!doctype html><title>IMM Studio</title>{NO_ICON}
<body style="font-family:sans-serif;padding:2em"><h2>IMM Studio</h2><p id="m">starting your studio...</p>
<script>
async function claim(tries) {{
  const r = await fetch("claim", {{method: "POST"}});
  if (r.status === 429 && tries > 1) {{  // other tabs (or a script) are starting: try again a second later
    await new Promise((done) => setTimeout(done, 1000));
    return claim(tries - 1);
  }}
  if (!r.ok) throw new Error(await r.text());
  const url = (await r.json()).url;
  // this tab's own studio (explorer/static/page_aids.js: another tab opening the address gets a studio of its own)
  try {{ sessionStorage.setItem("imm-studio-tab", new URL(url, location.href).pathname); }} catch (e) {{}}
  location.replace(url + location.search);  // a link's view (explorer/ui/url_state.py) goes along
}}
claim(10).catch((e) => {{ const m = document.getElementById("m"); m.style.color = "#b00020";
  m.textContent = (e.message || String(e)).replace(/<[^>]*>/g, " ").replace(/\\s+/g, " ").replace("IMM Studio", "").trim(); }});
</script></body>"""


def _error_page(message: str) -> str:
    return (
        f"<!doctype html><title>IMM Studio</title>{NO_ICON}<body style='font-family:sans-serif;padding:2em'>"
        f"<h2>IMM Studio</h2><p style='color:#b00020'>{html.escape(message)}</p></body>"
    )


def launch(config: LaunchConfig) -> int:
    if not hasattr(os, "fork"):
        raise LaunchError("imm explore needs a system with fork() (Linux, macOS): its studio processes are forked from one loaded parent")
    sock = bind_socket(config.host, config.port)
    launcher = Launcher(config)
    try:
        return asyncio.run(launcher.run(sock))
    except KeyboardInterrupt:
        return 0
    finally:
        sock.close()
