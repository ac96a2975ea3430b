"""`imm explore --desktop`: the studio in a window of its own (pywebview), with the same one-port launcher behind it.

As trame's own desktop mode does, the server stays in this process and the window runs in a process of its own: a GUI
toolkit wants the main thread, and the launcher keeps its signal handling and its clean shutdown. The launcher calls
the window's `open` with its ready URL instead of opening a browser (LaunchConfig.open_url). When the window closes (or its
process ends) this process gets SIGTERM, which the launcher answers as it does Ctrl+C: every studio process stops,
exit code 0. The window process, `python -m explorer.desktop URL`, closes its window when this process is gone.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import signal
import subprocess
import sys
import threading
import time

TITLE = "IMM Studio"
WIDTH, HEIGHT = 1366, 768
# pywebview's GUI back ends, in the order it tries them on Linux, by the module each needs
BACKENDS = {"qt": ("qtpy", "PyQt6.QtWebEngineWidgets"), "qt-pyside": ("qtpy", "PySide6.QtWebEngineWidgets"), "gtk": ("gi",)}
# a window killed by one of these was closed on purpose (by this process, a session's end, `kill`)
CLOSED = (0, -signal.SIGTERM, -signal.SIGINT, -signal.SIGHUP)


class DesktopError(Exception):
    """No display, or no pywebview back end: printed as one line, exit code 2."""


def _spec(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):  # a parent package that is missing or broken
        return False


def check() -> None:
    """Raise DesktopError when no window can be opened here: before the launcher starts anything."""
    if sys.platform.startswith("linux") or "bsd" in sys.platform:
        display = os.environ.get("DISPLAY", "")
        if not display and not os.environ.get("WAYLAND_DISPLAY"):
            raise DesktopError("--desktop needs a display (DISPLAY or WAYLAND_DISPLAY is not set); without one, "
                               "run imm explore and open its address in a browser")  # fmt: skip
        number = display.split(":", 1)[1].split(".", 1)[0] if display.startswith(":") else ""
        if number.isdigit() and not os.path.exists(f"/tmp/.X11-unix/X{number}"):
            raise DesktopError(f"--desktop: no X server answers on DISPLAY={display}")
    if not _spec("webview"):
        raise DesktopError("--desktop needs pywebview: pip install 'imm-studio[desktop]'")
    if sys.platform.startswith("linux") and not any(all(_spec(m) for m in mods) for mods in BACKENDS.values()):
        raise DesktopError("--desktop needs a pywebview back end (Qt WebEngine or GTK WebKit): pip install 'imm-studio[desktop]'")


class Window:
    """The studio window, in a process of its own: opened once on the launcher's ready URL."""

    def __init__(self):
        self.proc: subprocess.Popen | None = None
        self.stopping = False

    def open(self, url: str) -> None:
        if self.proc is not None:  # one window per studio
            return
        # its own session: Ctrl+C in the terminal reaches the launcher, which then closes the window (close())
        self.proc = subprocess.Popen([sys.executable, "-m", "explorer.desktop", "--parent", str(os.getpid()), url],
                                     start_new_session=True)  # fmt: skip
        threading.Thread(target=self._watch, name="imm-desktop-window", daemon=True).start()

    def _watch(self) -> None:
        assert self.proc is not None
        self.proc.wait()
        if not self.stopping:  # the window was closed: stop the launcher as Ctrl+C would
            os.kill(os.getpid(), signal.SIGTERM)

    def close(self) -> int | None:
        """Close the window if it is still open; -> its exit code (None if it never opened)."""
        self.stopping = True
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


def _close_when_gone(parent: int, window) -> None:
    """The launcher's process is gone (killed, crashed): close the window rather than show a dead studio."""
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            window.destroy()
            return


def show(url: str, parent: int | None = None) -> None:
    """Open the window on `url` and block until it is closed (on the main thread: GUI toolkits want it)."""
    if os.name == "posix" and os.geteuid() == 0:
        os.environ.setdefault("QTWEBENGINE_DISABLE_SANDBOX", "1")  # Chromium's sandbox refuses to run as root
    import webview

    window = webview.create_window(TITLE, url, width=WIDTH, height=HEIGHT)
    func = (lambda: _close_when_gone(parent, window)) if parent else None
    # the back end found, named: pywebview would otherwise try GTK first and log a traceback where it is missing
    gui = next((name.split("-")[0] for name, mods in BACKENDS.items() if all(_spec(m) for m in mods)), None)
    webview.start(func, gui=gui)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m explorer.desktop", description="Open the IMM Studio window on a URL.")
    p.add_argument("url")
    p.add_argument("--parent", type=int, default=None, help="close the window when this process is gone")
    args = p.parse_args(argv)
    try:
        check()
        show(args.url, args.parent)
    except DesktopError as err:
        print(f"imm explore: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # the toolkit failed to start (a missing system library, ...): one line
        print(f"imm explore: error: --desktop could not open a window: {type(err).__name__}: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
