"""Run many jobs on Ray (a local Ray on this machine's cores, or a cluster at --address), or, without Ray
installed, in local processes. One progress bar over all jobs and one line per finished job.

A job may need earlier jobs (an evaluation needs its training runs). The runner keeps one job per free lane in
flight and, when a lane frees, submits the ready job with the largest expected cost (longest first, so one long
evaluation does not run alone at the end while the other lanes idle); Ray core places the tasks (num_cpus per
task). The local fallback is a spawn-context multiprocessing pool of the same width, so results do not depend on
the backend.
"""

from __future__ import annotations

import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from tqdm import tqdm

from imm_model.errors import IMMError


@dataclass(frozen=True)
class Task:
    name: str
    fn: Callable[..., Any]  # a module-level function (it is pickled to the worker)
    args: tuple
    describe: Callable[[Any], str] = str  # the one line printed when it finishes
    needs: tuple[int, ...] = ()  # indices of earlier tasks in the same list that must have succeeded first
    cost: float = 0.0  # expected seconds, for the order only (the longest ready task goes first)


def _call(fn: Callable[..., Any], args: tuple) -> tuple[bool, Any]:
    """Run in the worker: a failure comes back as its one-line reason, never as a lost batch."""
    try:
        return True, fn(*args)
    except Exception as err:  # noqa: BLE001 (reported with the task's name, the other tasks go on)
        return False, f"{type(err).__name__}: {err}"


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _end_with(parent: int) -> None:
    """In each local worker: end within a second of the reproduce that started it, even one killed with -9 (which
    runs no clean-up), so no trainer is left running. A process whose parent dies is given another parent, which a
    daemon thread watches for. (prctl's PDEATHSIG would fire when the pool's thread that started the worker ends,
    killing a worker that holds the pool's queue lock.) Ray's own workers end with their raylet."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="end-with-reproduce", daemon=True).start()


def _check_reachable(address: str, seconds: float = 5.0) -> None:
    """A cluster address that nothing answers at is refused within `seconds` (ray.init would retry it for minutes,
    printing warnings). "auto" and other addresses without a port are left to Ray."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=seconds).close()
    except OSError as err:
        raise IMMError(f"--address {address}: nothing answers there ({err.strerror or type(err).__name__}); "
                       f"start the cluster (ray start --head) or give its address") from None


def ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


class Runner:
    """`with Runner(address, cpus_per_task) as r: results = r.run(tasks)`; results in task order."""

    def __init__(self, address: str | None = None, cpus_per_task: int = 1, backend: str = "auto"):
        if backend not in ("auto", "ray", "local"):
            raise ValueError(f"backend must be auto, ray or local, not {backend!r}")
        if cpus_per_task < 1:
            raise ValueError(f"cpus per task must be >= 1, not {cpus_per_task}")
        self.why_local = "--backend local"
        if backend == "auto":
            backend = "ray" if ray_available() else "local"
            self.why_local = "Ray is not installed; pip install -e '.[cluster]' to use it"
        if backend == "ray" and not ray_available():
            raise ValueError("Ray is not installed: pip install -e '.[cluster]' (or run without --address)")
        if backend == "local" and address:
            raise ValueError("--address needs Ray: pip install -e '.[cluster]'")
        self.address, self.cpus, self.backend = address, cpus_per_task, backend
        self.width = max(1, (os.cpu_count() or 1) // cpus_per_task)
        self._pool = None

    def __enter__(self) -> Runner:
        # a SIGTERM (e.g. `kill`) unwinds like Ctrl-C, so local Ray and the worker processes are shut down
        signal.signal(signal.SIGTERM, _interrupt)
        if self.backend == "ray":
            import ray

            if self.address:
                _check_reachable(self.address)
            try:
                ray.init(address=self.address, include_dashboard=False, log_to_driver=False, configure_logging=False,
                         **({} if self.address else {"num_cpus": os.cpu_count()}))
            except ConnectionError as err:
                raise IMMError(f"--address {self.address}: no Ray cluster to join ({str(err).splitlines()[0][:200]})") from None
            # Ray's core worker puts its own SIGTERM handler in place, which prints a crash report and aborts: ours
            # again, so a SIGTERM unwinds as Ctrl-C does and Ray is shut down
            signal.signal(signal.SIGTERM, _interrupt)
            self.width = max(1, int(ray.cluster_resources().get("CPU", 1)) // self.cpus)
            where = f"the Ray cluster at {self.address}" if self.address else "a local Ray"
        else:
            import multiprocessing

            self._pool = multiprocessing.get_context("spawn").Pool(self.width, _end_with, (os.getpid(),), maxtasksperchild=1)
            where = f"local processes ({self.why_local})"
        print(f"running on {where}: {self.width} jobs at a time, {self.cpus} CPU each", file=sys.stderr, flush=True)
        return self

    def __exit__(self, *exc) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool.join()
        if self.backend == "ray":
            import ray

            ray.shutdown()
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

    def run(self, tasks: list[Task], desc: str) -> list[tuple[bool, Any]]:
        """Every task to the end (a failed one does not stop the others; a task whose needs failed is reported
        and skipped) -> [(ok, result or reason)] in task order."""
        results: list[tuple[bool, Any] | None] = [None] * len(tasks)
        t0 = time.perf_counter()
        with tqdm(total=len(tasks), desc=desc, dynamic_ncols=True, file=sys.stderr) as bar:
            for i, (ok, value) in self._completed(tasks, results):
                results[i] = (ok, value)
                line = tasks[i].describe(value) if ok else f"FAILED: {value}"
                bar.write(f"[{bar.n + 1}/{len(tasks)}] {tasks[i].name}: {line} ({time.perf_counter() - t0:.0f} s)")
                bar.update()
        return results  # type: ignore[return-value]

    def _completed(self, tasks: list[Task], results: list) -> Iterator[tuple[int, tuple[bool, Any]]]:
        """Keep a task per lane in flight, the longest ready one first; yield (index, outcome) as tasks finish.
        A task whose needs failed is yielded as skipped."""
        submit, wait = self._ray_backend() if self.backend == "ray" else self._pool_backend()
        waiting, running = list(range(len(tasks))), {}
        while waiting or running:
            ready = []
            for i in list(waiting):
                needs = [results[j] for j in tasks[i].needs]
                if any(r is not None and not r[0] for r in needs):
                    waiting.remove(i)
                    failed = next(tasks[j].name for j in tasks[i].needs if not results[j][0])
                    yield i, (False, f"skipped: it needs {failed}, which failed")
                elif all(r is not None for r in needs):
                    ready.append(i)
            for i in sorted(ready, key=lambda i: -tasks[i].cost)[:self.width - len(running)]:
                waiting.remove(i)
                running[submit(tasks[i])] = i
            if running:
                handle, outcome = wait(running)
                yield running.pop(handle), outcome

    def _ray_backend(self):
        import ray

        remote = ray.remote(num_cpus=self.cpus)(_call)

        def wait(running: dict):
            ready: list = []
            while not ready:  # back in Python every fraction of a second, where a SIGTERM or Ctrl-C is handled
                ready, _ = ray.wait(list(running), num_returns=1, timeout=0.2)
            return ready[0], ray.get(ready[0])

        return (lambda t: remote.remote(t.fn, t.args)), wait

    def _pool_backend(self):
        def wait(running: dict):
            while True:
                for future in running:
                    if future.ready():
                        return future, future.get()
                time.sleep(0.2)

        return (lambda t: self._pool.apply_async(_call, (t.fn, t.args))), wait
