"""The parent of every studio process: loads the data, model, latent map and the heavy libraries once, then forks
one studio process (explorer/serving/worker.py `serve`) per browser tab.

Why a fork server: a studio process that starts from scratch imports VTK and trame and loads everything itself
(before the zygote, with torch then: ~5-10 s before a tab could open and ~350 MB of private memory each). A process
forked from this loaded parent is serving in well under a second and shares those pages (copy-on-write) with its
siblings; `gc.freeze` keeps the collector from touching, and so copying, the inherited objects.

The launcher (launcher.py) talks to it with lines on its stdin and stdout:
  launcher -> zygote   "spawn <id> <secret>"   fork studio process <id> with its own wslink secret
                       "retire <id>"           its tab has gone: SIGTERM, and SIGKILL RETIRE_GRACE_S later if it is
                                               still there (busy: its server's signal handler runs on its event loop)
                       "dump <id>"             it is stuck: SIGUSR1, on which it writes its threads' Python stacks to
                                               stderr (faulthandler: even while its main thread is stuck in C code)
                       end of file             the launcher is gone: every studio process is killed, then this one ends
  zygote -> launcher   "IMM-WORKER LOADED" or "IMM-WORKER ERROR - <message>" once, after loading
                       "IMM-WORKER READY <id> <port> <page folder>", "IMM-WORKER ERROR <id> <message>", "IMM-WORKER EXIT <id> <code>"
This process stays single-threaded (a select loop): forking a process with threads is unsafe.
"""

from __future__ import annotations

import contextlib
import faulthandler
import gc
import os
import select
import signal
import sys
import time

from explorer.serving import worker
from explorer.session.words import one_line

RETIRE_GRACE_S = 1.0


def preload() -> None:
    """Import what a studio process needs before the first fork, so that no child imports it again."""
    from explorer.trame_adapter import preload as preload_trame

    preload_trame()  # trame's server, trame-rca's image scheduler, wslink's websocket protocol
    import explorer.serving.page_shell  # noqa: F401
    import explorer.ui.app  # noqa: F401 - the page, the scene (PyVista), the charts, the view stream
    from explorer.rendering.scene import warm_up

    warm_up()  # PyVista's first-Plotter costs, paid here once rather than in every tab
    import explorer.serving.upload_reader  # noqa: F401 - not the file readers it runs (bvh: 0.5 s here), which uploads import


class ForkServer:
    def __init__(self, loaded: tuple, args):
        self.loaded, self.args = loaded, args
        self.children: dict[int, tuple[str, int]] = {}  # pid -> (worker id, write end of its stdin pipe)
        self.killing: dict[int, float] = {}  # pid -> time.monotonic() when a retired process gets SIGKILL

    def run(self) -> int:
        pending = b""
        while True:
            readable, _, _ = select.select([0], [], [], 0.1 if self.killing else 0.5)
            self.reap()
            self.kill_overdue()
            if not readable:
                continue
            chunk = os.read(0, 4096)
            if not chunk:  # the launcher is gone
                break
            pending += chunk
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                self.command(line.decode(errors="replace").split())
        # Everything is stopping (SIGTERM, Ctrl+C): nothing in a studio process is worth a grace period, and one whose
        # server shuts down gracefully on SIGTERM could outlive the few seconds stopping may take.
        for pid in list(self.children):
            self.killing[pid] = time.monotonic()
        deadline = time.monotonic() + 2.0
        while self.children and time.monotonic() < deadline:
            self.kill_overdue()
            self.reap()
            time.sleep(0.02)
        return 0

    def command(self, words: list[str]) -> None:
        if len(words) == 3 and words[0] == "spawn":
            self.fork(words[1], words[2])
        elif len(words) == 2 and words[0] in ("retire", "dump"):
            for pid, (wid, _) in list(self.children.items()):
                if wid == words[1] and words[0] == "retire":
                    self.retire(pid)
                elif wid == words[1]:
                    self.dump(pid)

    def dump(self, pid: int) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGUSR1)

    def retire(self, pid: int) -> None:
        if pid in self.killing:
            return
        self.killing[pid] = time.monotonic() + RETIRE_GRACE_S
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            pass

    def kill_overdue(self) -> None:
        now = time.monotonic()
        for pid in [p for p, due in self.killing.items() if due <= now]:
            del self.killing[pid]
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def fork(self, wid: str, secret: str) -> None:
        read_end, write_end = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(write_end)
            self.become_studio(wid, secret, read_end)  # never returns
        os.close(read_end)
        self.children[pid] = (wid, write_end)

    def become_studio(self, wid: str, secret: str, stdin_fd: int) -> None:
        for _, fd in self.children.values():  # a sibling's pipe held open here would never reach end of file
            os.close(fd)
        os.dup2(stdin_fd, 0)
        os.close(stdin_fd)
        channel = os.fdopen(os.dup(1), "w")  # our lines to the launcher; stray prints go to stderr instead
        os.dup2(2, 1)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        faulthandler.register(signal.SIGUSR1, file=sys.stderr, all_threads=True)  # "dump": where it is stuck
        gc.enable()
        code = 2
        try:
            uploads = self.upload_reader()  # forks its helper while this process has one thread
            code = worker.serve(*self.loaded, self.args, secret=secret, say=worker.Channel(channel, wid), uploads=uploads)
        except BaseException as err:  # one line for the launcher, never a traceback
            worker.Channel(channel, wid)("ERROR", one_line(err))
        finally:
            os._exit(code)

    def upload_reader(self):
        from explorer.serving.upload_reader import UploadReader
        from explorer.session.uploads import read_upload

        model = next(iter(self.loaded[1].values()))  # every model of the studio reads a leader alike (one skeleton, frame)
        return UploadReader(lambda name, content: read_upload(name, content, model))

    def reap(self) -> None:
        while self.children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            self.killing.pop(pid, None)
            wid, fd = self.children.pop(pid, ("?", -1))
            if fd >= 0:
                os.close(fd)
            worker.say_line("EXIT", wid, os.waitstatus_to_exitcode(status))


def one_thread_for_torch() -> None:
    """The bundled models run in numpy (their families' numpy runtimes); a model that needs torch (the paper's
    frame-by-frame decoder) gets one intra-op thread: the per-request work is a few ms, several studio processes
    share the cores (more threads made each synthesis 4x slower here), and a fork would not carry a thread pool over."""
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def main(argv=None) -> int:
    args = worker.parse_args(argv)
    # Ctrl+C reaches the whole process group: the launcher handles it and closes our stdin, which ends everything.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    gc.disable()  # nothing to collect while loading, and freeze below keeps what was loaded out of later collections
    try:
        loaded = worker.load_everything(args)
        args.start = worker.start_index(loaded[0], args.sequence)
        preload()
        one_thread_for_torch()
    except Exception as err:
        worker.say_line("ERROR", "-", one_line(err))
        return 2
    gc.freeze()
    worker.say_line("LOADED")
    return ForkServer(loaded, args).run()


if __name__ == "__main__":
    sys.exit(main())
