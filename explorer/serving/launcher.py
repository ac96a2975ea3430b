"""`imm explore`'s front door: one studio process per browser client.

A trame server shares one state among all its clients, so two people on one server would move each
other's sliders. The launcher listens on the public port; each visit to `/` takes a warm studio
process (explorer/serving/worker.py, forked by explorer/serving/zygote.py and listening on its own loopback port) when the
front page's script claims one (a same-origin POST: a bare GET or another web page cannot), forwards the tab
to it (proxy.py) and forks the next spare in the background. A tab's studio process is ended (by the zygote, with
SIGKILL if it is too busy to stop) RECONNECT_GRACE_S after its last websocket closed, or CLAIM_TIMEOUT_S after a claim
that no browser connected to (CLAIM_VISIT_S if its page was not even asked for), so a closed tab frees its client slot
within seconds.
"""

from __future__ import annotations

import asyncio
import errno
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

from explorer.serving.worker import PREFIX

if TYPE_CHECKING:
    from explorer.serving.proxy import InboundBudget  # imports aiohttp, which loads beside the zygote (run)

TOKEN_COOKIE = "imm_studio_token"
PAGE_COOKIE = "imm_studio_page"  # set by the front page: a claim without an Origin header must carry it
# Set by a claim, one random value per browser: a tab's /s/<token>/ answers only the browser that claimed it, so its
# address, copied into another browser, opens a studio of its own there (with the view the address names).
BROWSER_COOKIE = "imm_studio_browser"
# A tab's process outlives its last websocket by RECONNECT_GRACE_S, or by RELOAD_GRACE_S after the tab's last request
# once its page has been asked for again: a reload (page, scripts, then ~2 s of module evaluation here before its
# websocket opens) finds its own session, and a closed tab frees its slot within seconds.
RECONNECT_GRACE_S = 2.0
RELOAD_GRACE_S = 10.0
# a claimed studio process whose browser never connects is ended after this ($IMM_STUDIO_CLAIM_TIMEOUT: tests)
CLAIM_TIMEOUT_S = float(os.environ.get("IMM_STUDIO_CLAIM_TIMEOUT", "20"))
# Claims are rate-limited (a token bucket): CLAIM_BURST at once, then one per CLAIM_EVERY_S. Each claim forks a studio
# process (~0.5 s of CPU), so a script posting claims in a loop would otherwise keep the machine forking.
CLAIM_BURST = 4
CLAIM_EVERY_S = 1.0
# A tab asks for its page the moment its claim is answered: a claim whose page is not asked for within CLAIM_VISIT_S is
# retired, and so is the oldest such claim when a claim finds every slot taken, so a script posting claims in a loop
# never keeps a tab from a studio.
CLAIM_VISIT_S = min(5.0, CLAIM_TIMEOUT_S)
# A claimed spare is replaced once the tabs have been quiet (no websocket message through the proxy) for SPARE_QUIET_S,
# and no sooner than SPARE_DELAY_S after the claim; at once when another tab asks first, and at the latest after
# SPARE_LATEST_S (playback never goes quiet). Why: forking and starting a studio process takes ~0.5 s of CPU, which on
# a small machine competes with the new tab's page as it loads and with its first slider moves (docs/experiments/studio-performance.md).
SPARE_DELAY_S = 3.0
SPARE_QUIET_S = 1.0
SPARE_LATEST_S = 60.0
# Stopping (SIGTERM, Ctrl+C) waits at most STOP_S for the zygote to kill the studio processes and exit (well under a
# second), then CLOSE_S for the tabs' connections to close: within 5 s in all.
STOP_S = 3.0
CLOSE_S = 1.0
LOOPBACK = ("127.0.0.1", "localhost", "::1")
IMMUTABLE = "public, max-age=31536000, immutable"  # /static/: every name there changes with its content


class LaunchError(Exception):
    """A user-facing start-up problem: printed as one line, exit code 2."""


@dataclass
class Worker:
    id: str  # the zygote's name for it (explorer/serving/zygote.py)
    secret: str  # its wslink secret (proxy.py puts it into the browser's hello)
    port: int = 0
    exited: bool = False
    retired: bool = False  # asked to stop: its slot is free already
    sockets: int = 0  # open websockets of its tab
    connected: bool = False  # a websocket has reached it since its claim
    reloading: bool = False  # its page was asked for while it had no websocket
    browser: str = ""  # the claiming browser's BROWSER_COOKIE
    last_seen: float = 0.0  # time.monotonic() of its tab's last request or closed websocket
    budget: InboundBudget | None = None  # what its websockets may claim (made when the first one opens)
    ready: asyncio.Future = field(default_factory=lambda: asyncio.get_running_loop().create_future())


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
        self.spares: list[Worker] = []
        self.busy: list[Worker] = []
        self.sessions: dict[str, Worker] = {}  # /s/<token>/ -> the tab's studio process
        self.workers: dict[str, Worker] = {}  # by zygote id, until it exits
        self.zygote: asyncio.subprocess.Process | None = None  # explorer/serving/zygote.py: forks the studio processes
        self.loaded: asyncio.Future | None = None
        self.gone = ""  # why the zygote is no more, once it has exited
        self.spawned = 0
        self.url = ""
        self.spare_wanted = asyncio.Event()  # a tab is waiting: a delayed spare starts now
        self.last_traffic = 0.0  # time.monotonic() of the last websocket message through the proxy
        self.page_secret = secrets.token_urlsafe(18)  # the front page's cookie (PAGE_COOKIE)
        self.claim_tokens, self.claim_refilled = float(CLAIM_BURST), time.monotonic()
        self.assets: dict[str, Path] = {}  # /static/<name> -> its file (public libraries the page loads)
        self.shells: dict[str, Path] = {}  # /static/<key>/... -> the page folder the studio processes serve

    # ---- workers -------------------------------------------------------------------------
    async def spawn(self) -> Worker:
        """A studio process on a loopback port of its own, forked by the zygote: browsers reach it only through this
        launcher (proxy.py). Its secret goes through the zygote's stdin, not argv: `ps` shows argv to every local user."""
        if self.zygote is None:
            await self._start_zygote()
        await self.loaded  # a bad data file or checkpoint fails here, in one line
        if self.gone:
            raise LaunchError(self.gone)
        self.spawned += 1
        w = Worker(str(self.spawned), secrets.token_urlsafe(24))
        self.workers[w.id] = w
        self._tell(f"spawn {w.id} {w.secret}")
        return w

    async def _start_zygote(self) -> None:
        c = self.config
        cmd = [sys.executable, "-m", "explorer.serving.zygote", "--data", str(c.data),
               "--host", "127.0.0.1", "--port", "0", "--export-dir", str(c.export_dir), "--render", c.render]  # fmt: skip
        cmd += [arg for name, path in c.models for arg in ("--model", f"{name}={path}")]
        cmd += ["--cache-dir", str(c.cache_dir)] if c.cache_dir else []
        cmd += ["--sequence", c.sequence] if c.sequence else []
        cmd += ["--judge", c.judge] if c.judge else []
        env = {**os.environ, "OMP_NUM_THREADS": "1", "VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow"}
        self.loaded = asyncio.get_running_loop().create_future()
        self.zygote = await asyncio.create_subprocess_exec(*cmd, stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.PIPE, env=env)
        asyncio.get_running_loop().create_task(self._read())

    def _tell(self, line: str) -> None:
        if self.zygote is not None and self.zygote.stdin is not None and not self.zygote.stdin.is_closing():
            self.zygote.stdin.write(line.encode() + b"\n")

    async def _read(self) -> None:
        """The zygote's lines: loaded, and each studio process's READY, ERROR and EXIT."""
        assert self.zygote is not None and self.zygote.stdout is not None
        while line := await self.zygote.stdout.readline():
            words = line.decode(errors="replace").strip().split(" ", 3)
            if len(words) < 2 or words[0] != PREFIX:
                continue
            kind, wid, rest = words[1], (words[2:3] or [""])[0], (words[3:4] or [""])[0]
            if kind == "LOADED" and not self.loaded.done():
                self.loaded.set_result(True)
            elif kind == "ERROR" and wid == "-" and not self.loaded.done():
                self.loaded.set_exception(LaunchError(rest))
            elif (w := self.workers.get(wid)) is not None:
                self._worker_says(w, kind, rest)
        code = await self.zygote.wait()
        # later spawns fail at once instead of waiting for a READY that cannot come
        self.gone = f"the studio's loader (explorer/serving/zygote.py) stopped with exit code {code}: restart imm explore"
        if not self.loaded.done():
            self.loaded.set_exception(LaunchError(f"the studio's loader exited with code {code} before it was ready"))
        for w in list(self.workers.values()):
            self._worker_says(w, "EXIT", str(code))

    def _worker_says(self, w: Worker, kind: str, rest: str) -> None:
        if kind == "READY" and not w.ready.done():
            port, _, shell = rest.partition(" ")
            w.port = int(port)
            if shell:  # the page's folder: the files it loads from /static/<key>/ (explorer/serving/page_shell.py)
                self.shells[Path(shell).name.removeprefix("page-")] = Path(shell)
            w.ready.set_result(True)
        elif kind == "ERROR" and not w.ready.done():
            w.ready.set_exception(LaunchError(rest))
        elif kind == "EXIT":
            w.exited = True
            if not w.ready.done():
                w.ready.set_exception(LaunchError(self.gone or f"studio process exited with code {rest} before it was ready"))
            self.workers.pop(w.id, None)
            for pool in (self.spares, self.busy):
                if w in pool:
                    pool.remove(w)
            for token in [t for t, s in self.sessions.items() if s is w]:
                del self.sessions[token]

    def retire(self, w: Worker) -> None:
        """End a studio process whose tab has gone and free its slot now: the zygote stops it, with SIGKILL when it is
        too busy to stop by itself (explorer/serving/zygote.py)."""
        if w.exited or w.retired:
            return
        w.retired = True
        self._tell(f"retire {w.id}")
        if w in self.busy:
            self.busy.remove(w)
        for token in [t for t, s in self.sessions.items() if s is w]:
            del self.sessions[token]
        self._top_up()

    def _retire_if_unconnected(self, w: Worker) -> None:
        if not w.connected:
            self.retire(w)

    def _retire_if_gone(self, w: Worker) -> None:
        """Called after a tab's last websocket closed: retire it unless the tab came back or is coming back."""
        if w.sockets or w.exited or w.retired:
            return
        grace = RELOAD_GRACE_S if w.reloading else RECONNECT_GRACE_S
        quiet = time.monotonic() - w.last_seen
        if quiet < grace:  # look again when it should have connected
            asyncio.get_running_loop().call_later(grace - quiet, self._retire_if_gone, w)
        else:
            self.retire(w)

    def _top_up(self) -> None:
        want = min(self.config.spares, self.config.max_clients - len(self.busy)) - len(self.spares)
        self.spare_wanted.clear()
        for _ in range(max(0, want)):
            self.spares.append(None)  # type: ignore[arg-type]  # placeholder until spawn returns
            asyncio.get_running_loop().create_task(self._add_spare())

    def note_traffic(self) -> None:
        self.last_traffic = time.monotonic()

    async def _spare_due(self) -> None:
        """Returns when the next spare should start: the tabs are quiet, another tab is waiting, or it is late."""
        claimed = time.monotonic()
        while not self.spare_wanted.is_set():
            due = min(max(claimed + SPARE_DELAY_S, self.last_traffic + SPARE_QUIET_S), claimed + SPARE_LATEST_S)
            if time.monotonic() >= due:
                return
            try:
                await asyncio.wait_for(self.spare_wanted.wait(), due - time.monotonic())
            except TimeoutError:
                pass

    async def _add_spare(self) -> None:
        await self._spare_due()
        try:
            w = await self.spawn()
        except LaunchError:
            w = None  # the loader is gone: take() says so
        slot = self.spares.index(None)  # type: ignore[arg-type]
        if w is None:
            del self.spares[slot]
        else:
            self.spares[slot] = w

    async def take(self) -> Worker:
        """A ready worker for a new client (waits for the spare when it is still loading)."""
        self.spare_wanted.set()
        while None in self.spares:
            await asyncio.sleep(0.02)
        if not self.spares:
            if len(self.busy) >= self.config.max_clients:
                raise LaunchError(f"the studio is serving its maximum of {self.config.max_clients} clients; close one and reload")
            self.spares.append(await self.spawn())
        w = self.spares.pop(0)
        self.busy.append(w)
        self._top_up()
        await w.ready
        return w

    # ---- http ----------------------------------------------------------------------------
    async def handle(self, request):
        """The front page: no studio process is taken by a GET (a bare request, a prefetch or another web
        page's <img> would otherwise hold one); its script claims one with a same-origin POST."""
        from aiohttp import web

        if not self.authorized(request):
            return web.Response(status=403, content_type="text/html",
                                text=_error_page("this studio needs its access token: open the address it printed at start"))
        page = web.Response(content_type="text/html", text=CLAIM_PAGE)
        if self.config.token and "token" in request.query:  # later requests (claim, studio) carry it as a cookie
            page.set_cookie(TOKEN_COOKIE, self.config.token, httponly=True, samesite="Strict", path="/")
        page.set_cookie(PAGE_COOKIE, self.page_secret, httponly=True, samesite="Strict", path="/")
        return page

    async def claim(self, request):
        """POST /claim from the front page -> {"url": the studio process for this tab}. Refused for a request from
        another web origin or addressed to a host name this studio does not serve (DNS rebinding), and for one that
        shows no sign of the page (a bare POST); rate-limited."""
        from aiohttp import web

        if not self.authorized(request) or not self.from_the_page(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        if not self._claim_allowed():
            return web.Response(status=429, content_type="text/html",
                                text=_error_page("too many new tabs at once: wait a second and reload"))
        self._make_room()
        try:
            w = await self.take()
        except LaunchError as err:
            return web.Response(status=503, content_type="text/html", text=_error_page(str(err)))
        asyncio.get_running_loop().call_later(CLAIM_VISIT_S, self._retire_if_unvisited, w)
        asyncio.get_running_loop().call_later(CLAIM_TIMEOUT_S, self._retire_if_unconnected, w)
        token = secrets.token_urlsafe(18)
        self.sessions[token] = w
        w.browser = request.cookies.get(BROWSER_COOKIE) or secrets.token_urlsafe(18)
        answer = web.json_response({"url": f"s/{token}/"})  # relative: a reverse proxy's path prefix is kept
        answer.set_cookie(BROWSER_COOKIE, w.browser, httponly=True, samesite="Strict", path="/")
        return answer

    def _make_room(self) -> None:
        """Before a claim that finds every slot taken: retire the oldest claim whose page nobody has asked for."""
        if len(self.busy) >= self.config.max_clients:
            unvisited = [w for w in self.busy if self._unvisited(w)]  # self.busy is in claim order
            if unvisited:
                self.retire(unvisited[0])

    @staticmethod
    def _unvisited(w: Worker) -> bool:
        return not w.connected and not w.last_seen

    def _retire_if_unvisited(self, w: Worker) -> None:
        if self._unvisited(w):
            self.retire(w)

    def _claim_allowed(self) -> bool:
        now = time.monotonic()
        self.claim_tokens = min(CLAIM_BURST, self.claim_tokens + (now - self.claim_refilled) / CLAIM_EVERY_S)
        self.claim_refilled = now
        if self.claim_tokens < 1:
            return False
        self.claim_tokens -= 1
        return True

    async def studio(self, request):
        """/s/<token>/<path>: the tab's page, assets and websocket, forwarded to its studio process."""
        from aiohttp import web

        from explorer.serving.proxy import InboundBudget, forward_http, forward_websocket

        if not self.authorized(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        w = self.sessions.get(request.match_info["token"])
        if w is None or w.exited:
            self.sessions.pop(request.match_info["token"], None)
        if w is None or w.exited or not hmac.compare_digest(request.cookies.get(BROWSER_COOKIE, "").encode(), w.browser.encode()):
            # an old or unknown link, or another browser's tab: back to the front page for a fresh studio, with the view
            # the link names
            raise web.HTTPFound("../../" + (f"?{request.query_string}" if request.query_string else ""))
        tail = request.match_info["tail"]
        w.last_seen = time.monotonic()
        if request.headers.get("Upgrade", "").lower() != "websocket":
            # the page asked for again once a websocket had connected is a reload, even while the closing one is still
            # being torn down here (the browser sends the new request as soon as the old page unloads)
            w.reloading = w.reloading or (w.connected and (not w.sockets or tail in ("", "index.html")))
            return await forward_http(request, w.port, tail)
        w.sockets += 1
        w.connected, w.reloading = True, False
        w.budget = w.budget or InboundBudget()
        try:
            return await forward_websocket(request, w.port, tail, w.secret, w.budget, on_message=self.note_traffic)
        finally:
            w.sockets -= 1
            w.last_seen = time.monotonic()
            if not w.sockets:
                asyncio.get_running_loop().call_later(RECONNECT_GRACE_S, self._retire_if_gone, w)

    async def no_session_manager(self, request):
        """trame's page first asks `paraview/` for a session (a ParaView-style launcher's endpoint) and connects to its
        own `ws` when that gives none: 204 says "none" without the 405 a browser would log on every load."""
        from aiohttp import web

        if not self.authorized(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        return web.Response(status=204)

    async def static(self, request):
        """/static/<name>: a public library the page loads (plotly.js), at one versioned path for every tab, cached by
        the browser for a year. No token or cookie (nothing in it is secret), but another web origin and, without a
        token, a host name this studio does not serve are refused as on every other path."""
        from aiohttp import web

        if not self.public(request):
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

        if not self.public(request):
            return web.Response(status=403, text="refused: the studio only answers its own page")
        shell = self.shells.get(request.match_info["key"])
        parts = request.match_info["tail"].split("/")
        if shell is None or parts == ["index.html"] or any(not p or p.startswith(".") for p in parts):
            return web.Response(status=404, text="not found")
        path = shell.joinpath(*parts)
        if not path.is_file():
            return web.Response(status=404, text="not found")
        return web.FileResponse(path, headers={"Cache-Control": IMMUTABLE})

    def allowed_hosts(self) -> set[str]:
        return {"localhost", "127.0.0.1", "::1", "[::1]", self.config.host} - {"0.0.0.0", "::"}

    def origins(self, request) -> set[str]:
        """The page's own origin as a browser names it: the host it asked for, over the scheme it used (a TLS reverse
        proxy says which in X-Forwarded-Proto), and the public address --base-url names."""
        forwarded = request.headers.get("X-Forwarded-Proto", "").split(",")[0].strip().lower()
        schemes = {request.scheme} | ({forwarded} if forwarded in ("http", "https") else set())
        mine = {f"{scheme}://{request.host}".lower() for scheme in schemes}
        if self.config.base_url:
            public = urlsplit(self.config.base_url)
            mine |= {f"{public.scheme}://{public.netloc}".lower(), f"{public.scheme}://{request.host}".lower()}
        return mine

    def from_the_page(self, request) -> bool:
        """A claim names the page's origin (browsers send Origin with every POST; authorized() compared it), or,
        where a browser's privacy settings withhold it, carries the cookie the front page set. A bare POST does neither."""
        if request.headers.get("Origin", "null") != "null":
            return True
        return hmac.compare_digest(request.cookies.get(PAGE_COOKIE, "").encode(), self.page_secret.encode())

    def same_origin(self, request) -> bool:
        origin = request.headers.get("Origin", "null")
        return origin == "null" or origin.lower() in self.origins(request)

    def host_served(self, request) -> bool:
        return self.config.no_auth or (request.url.host or "") in self.allowed_hosts()

    def public(self, request) -> bool:
        """What /static/ needs: no token (nothing there is secret), but this studio's origin and host names."""
        return self.same_origin(request) and bool(self.config.token or self.host_served(request))

    def authorized(self, request) -> bool:
        """Another web origin is always refused ("null", an origin a browser withholds, counts as none: a claim then
        needs the page's cookie, and a studio's pages its unguessable session path). Then: the access token (first URL
        or cookie) if there is one; without one, a host name this studio serves (a DNS-rebinding page names its own)."""
        if not self.same_origin(request):
            return False
        if self.config.no_auth:
            return True
        if self.config.token is None:
            return self.host_served(request)
        given = request.query.get("token") or request.cookies.get(TOKEN_COOKIE) or ""
        return hmac.compare_digest(given.encode(), self.config.token.encode())

    async def run(self, sock: socket.socket) -> int:
        t0 = time.monotonic()
        try:
            first = await self.spawn()  # the zygote starts loading now; the web server's imports go beside it
            self.spares.append(first)
            from aiohttp import web

            from explorer.serving.page_shell import plotly_js, plotly_name

            try:
                self.assets = {plotly_name(): plotly_js()}
            except (ImportError, OSError) as err:
                raise LaunchError(str(err)) from None

            await first.ready  # bad data/checkpoint fail here, before any URL is printed
        except LaunchError:
            await self.shutdown()
            raise
        app = web.Application()
        app.router.add_get("/", self.handle)
        app.router.add_post("/claim", self.claim)
        app.router.add_get("/s/{token}/{tail:.*}", self.studio)
        app.router.add_post("/s/{token}/paraview/", self.no_session_manager)
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
            await self.shutdown()
            await runner.cleanup()
        return 0

    async def shutdown(self) -> None:
        """Closing the zygote's stdin ends every studio process (their stdin closes too), then the zygote."""
        if self.zygote is None or self.zygote.returncode is not None:
            return
        if self.zygote.stdin is not None:
            self.zygote.stdin.close()
        try:
            await asyncio.wait_for(self.zygote.wait(), STOP_S)
        except TimeoutError:
            self.zygote.kill()
            await self.zygote.wait()


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
