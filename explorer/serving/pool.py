"""The studio processes behind the launcher (launcher.py): forked by the zygote (explorer/serving/zygote.py), one per
browser tab, a spare kept warm for the next tab, each retired once its tab has gone."""

from __future__ import annotations

import asyncio
import os
import secrets
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from explorer.serving.worker import PREFIX

if TYPE_CHECKING:
    from explorer.serving.proxy import InboundBudget  # imports aiohttp, which loads beside the zygote (launcher run)

# A tab's process outlives its last websocket by RECONNECT_GRACE_S, or by RELOAD_GRACE_S after the tab's last request
# once its page has been asked for again: a reload (page, scripts, then ~2 s of module evaluation here before its
# websocket opens) finds its own session, and a closed tab frees its slot within seconds.
RECONNECT_GRACE_S = 2.0
RELOAD_GRACE_S = 10.0
# A claimed spare is replaced once the tabs have been quiet (no websocket message through the proxy) for SPARE_QUIET_S,
# and no sooner than SPARE_DELAY_S after the claim; at once when another tab asks first, and at the latest after
# SPARE_LATEST_S (playback never goes quiet). Why: forking and starting a studio process takes ~0.5 s of CPU, which on
# a small machine competes with the new tab's page as it loads and with its first slider moves (docs/experiments/studio-performance.md).
SPARE_DELAY_S = 3.0
SPARE_QUIET_S = 1.0
SPARE_LATEST_S = 60.0
# Stopping (SIGTERM, Ctrl+C) waits at most STOP_S for the zygote to kill the studio processes and exit (well under a
# second).
STOP_S = 3.0


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


class WorkerPool:
    def __init__(self, config) -> None:
        """The studio processes `config` (launcher.py LaunchConfig) asks for: its data, models and limits."""
        self.config = config
        self.spares: list[Worker] = []
        self.busy: list[Worker] = []
        self.sessions: dict[str, Worker] = {}  # /s/<token>/ -> the tab's studio process
        self.workers: dict[str, Worker] = {}  # by zygote id, until it exits
        self.zygote: asyncio.subprocess.Process | None = None  # explorer/serving/zygote.py: forks the studio processes
        self.loaded: asyncio.Future | None = None
        self.gone = ""  # why the zygote is no more, once it has exited
        self.spawned = 0
        self.spare_wanted = asyncio.Event()  # a tab is waiting: a delayed spare starts now
        self.last_traffic = 0.0  # time.monotonic() of the last websocket message through the proxy
        self.shells: dict[str, Path] = {}  # /static/<key>/... -> the page folder the studio processes serve

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

    def retire_if_unconnected(self, w: Worker, waited_s: float) -> None:
        if not w.connected and not (w.exited or w.retired):
            # said, because a tab still loading its page when this happens stays on trame's "Loading..."
            print(f"a tab's studio process ended: its page did not connect within {waited_s:g} s of its claim", flush=True)
            self.retire(w)

    def retire_silent(self, w: Worker, why: str) -> None:
        """Its page's request or websocket found it stuck (proxy.py): its threads' Python stacks go to the log
        (explorer/serving/zygote.py `dump`), then it is retired; the page asks for a fresh studio."""
        if w.exited or w.retired:  # said once, for its first request that found it so
            return
        print(f"a tab's studio process was replaced: {why}", flush=True)
        self._tell(f"dump {w.id}")
        self.retire(w)

    def retire_if_gone(self, w: Worker) -> None:
        """Called after a tab's last websocket closed: retire it unless the tab came back or is coming back."""
        if w.sockets or w.exited or w.retired:
            return
        grace = RELOAD_GRACE_S if w.reloading else RECONNECT_GRACE_S
        quiet = time.monotonic() - w.last_seen
        if quiet < grace:  # look again when it should have connected
            asyncio.get_running_loop().call_later(grace - quiet, self.retire_if_gone, w)
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

    def make_room(self) -> None:
        """Before a claim that finds every slot taken: retire the oldest claim whose page nobody has asked for."""
        if len(self.busy) >= self.config.max_clients:
            unvisited = [w for w in self.busy if self._unvisited(w)]  # self.busy is in claim order
            if unvisited:
                self.retire(unvisited[0])

    @staticmethod
    def _unvisited(w: Worker) -> bool:
        return not w.connected and not w.last_seen

    def retire_if_unvisited(self, w: Worker) -> None:
        if self._unvisited(w):
            self.retire(w)

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
