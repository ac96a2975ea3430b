"""Uploads read in a child process with a time and a memory budget, so that no file, however hostile, can pin or drain
the studio process that serves its tab.

A leader file from the page is parsed by code that trusts its header (BVH, npz and SBU readers, bvhio, numpy): a
claim of a billion frames or a reader that loops at end of file would otherwise hold the tab's process, its core and
its client slot. Here each upload is read by a process of its own, killed when it runs past TIME_BUDGET_S or refused
memory past MEMORY_BUDGET_BYTES (RLIMIT_AS); the studio gets the result or a one-line error and keeps its view.

Why a helper process forked at start: a studio process runs threads (its server, its watchdogs), and forking a
process with threads is unsafe; the helper is forked while the studio process is still single-threaded, stays so,
and forks one reader per upload. Results come back as an .npz (no pickle).
"""

from __future__ import annotations

import io
import json
import os
import resource
import select
import signal
import threading
import time
from collections.abc import Callable

import numpy as np

from imm_model.data.canonical import CanonicalFrame
from imm_model.errors import DataFormatError, IMMError
from imm_model.families.base import Leader

TIME_BUDGET_S = 10.0
MEMORY_BUDGET_BYTES = 500 * 1024 * 1024  # on top of what the process already maps
_LENGTH = 8  # every message on the pipes: its length (uint64 little-endian), then its bytes

Read = Callable[[str, bytes], Leader]


class UploadReader:
    """`reader(name, content)` -> the leader (families/base.py Leader), as explorer/session/session.py `read_upload`, read in a child
    process. Construct it while the process has a single thread (it forks its helper then)."""

    def __init__(self, read: Read):
        jobs_read, self._jobs = os.pipe()
        self._answers, answers_write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the helper: keeps only its two pipes (another process's pipe held open here would never end)
            _close_all_but(jobs_read, answers_write)
            code = 0
            try:
                _serve(jobs_read, answers_write, read)
            except BaseException:  # its studio process is gone (a closed pipe): nothing to tell anyone
                code = 1
            finally:
                os._exit(code)
        os.close(jobs_read)
        os.close(answers_write)
        self._helper = pid
        self._lock = threading.Lock()  # one upload at a time per tab

    def close(self) -> None:
        """Stop the helper (it also stops by itself when this process ends)."""
        os.close(self._jobs)
        os.close(self._answers)
        os.waitpid(self._helper, 0)

    def __call__(self, name: str, content: bytes) -> Leader:
        with self._lock:
            try:
                _send(self._jobs, json.dumps({"name": name}).encode())
                _send(self._jobs, content)
                # the helper answers within its own budget; more than that means it is gone
                answer = _receive(self._answers, time.monotonic() + TIME_BUDGET_S + 5.0)
            except (OSError, TimeoutError, EOFError):
                raise DataFormatError(f"{name}: the studio's upload reader has stopped; reload the page to read files again") from None
        if answer[:1] == b"E":
            raise DataFormatError(answer[1:].decode(errors="replace"))
        with np.load(io.BytesIO(answer[1:]), allow_pickle=False) as npz:
            frame = CanonicalFrame(yaw=npz["yaw"], origin=npz["origin"], mode=str(npz["mode"]))
            return Leader(npz["world"], frame, npz["canonical"])


def _serve(jobs: int, answers: int, read: Read) -> None:
    """The helper: one reader process per upload, each answered within the budget."""
    while True:
        try:
            header = json.loads(_receive(jobs, None))
            content = _receive(jobs, None)
        except EOFError:
            return  # the studio process is gone
        _send(answers, _read_in_child(header["name"], content, read, jobs))


def _read_in_child(name: str, content: bytes, read: Read, jobs: int) -> bytes:
    """b"O" + the npz of the result, or b"E" + a one-line error."""
    result_read, result_write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(result_read)
        _limit_self()
        try:
            _send(result_write, b"O" + _pack(read(name, content)))
        except MemoryError:
            _send(result_write, f"E{name}: reading it needs more than the {MEMORY_BUDGET_BYTES >> 20} MB an upload may use".encode())
        except BaseException as err:
            _send(result_write, b"E" + _message(name, err).encode())
        finally:
            os._exit(0)
    os.close(result_write)
    deadline = time.monotonic() + TIME_BUDGET_S
    chunks: list[bytes] = []
    try:
        while True:
            left = deadline - time.monotonic()
            ready = select.select([result_read, jobs], [], [], max(0.0, left))[0] if left > 0 else []
            if not ready:
                return f"E{name}: reading it took longer than {TIME_BUDGET_S:g} s, so it was stopped".encode()
            if jobs in ready:  # the studio process closed its end: nobody waits for this answer
                raise EOFError
            chunk = os.read(result_read, 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(result_read)
        _end(pid)
    data = b"".join(chunks)
    if len(data) < _LENGTH or len(data) != _LENGTH + int.from_bytes(data[:_LENGTH], "little"):
        return f"E{name}: the reader stopped on it (over its {MEMORY_BUDGET_BYTES >> 20} MB memory budget, or a crash)".encode()
    return data[_LENGTH:]


def _limit_self() -> None:
    """The reader process's budget: CPU time as a backstop should its helper be gone, and address space beyond what it
    inherited (the studio's libraries are mapped already)."""
    cpu = int(TIME_BUDGET_S) + 2
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    try:
        with open("/proc/self/statm") as statm:
            mapped = int(statm.read().split()[0]) * resource.getpagesize()
    except OSError:  # no /proc (macOS, which does not enforce RLIMIT_AS either): the time budget still holds
        return
    resource.setrlimit(resource.RLIMIT_AS, (mapped + MEMORY_BUDGET_BYTES, mapped + MEMORY_BUDGET_BYTES))


def _close_all_but(*keep: int) -> None:
    """Close every descriptor above stderr except `keep`."""
    low = 3
    for fd in sorted(keep):
        os.closerange(low, fd)
        low = fd + 1
    os.closerange(low, os.sysconf("SC_OPEN_MAX"))


def _end(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    os.waitpid(pid, 0)


def _pack(leader: Leader) -> bytes:
    buffer = io.BytesIO()
    frame = leader.frame
    np.savez(buffer, world=leader.world, canonical=leader.canonical, yaw=frame.yaw, origin=frame.origin, mode=np.str_(frame.mode))
    return buffer.getvalue()


def _message(name: str, err: BaseException) -> str:
    from explorer.session.words import one_line

    text = one_line(err)
    if isinstance(err, IMMError):
        return text  # already names the file and the problem (explorer/session/session.py read_upload)
    return f"{name}: cannot be read as a leader ({type(err).__name__}: {text})"


def _send(fd: int, data: bytes) -> None:
    view = memoryview(len(data).to_bytes(_LENGTH, "little") + data)
    while view:
        view = view[os.write(fd, view) :]


def _receive(fd: int, deadline: float | None) -> bytes:
    """One message; EOFError when the other end closed, TimeoutError past the deadline."""

    def exactly(n: int) -> bytes:
        parts, left = [], n
        while left:
            if deadline is not None and not select.select([fd], [], [], max(0.0, deadline - time.monotonic()))[0]:
                raise TimeoutError
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                raise EOFError
            parts.append(chunk)
            left -= len(chunk)
        return b"".join(parts)

    return exactly(int.from_bytes(exactly(_LENGTH), "little"))
