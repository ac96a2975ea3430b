"""`imm explore --desktop` under Xvfb: the studio window shows the 3D view, and closing the window stops the studio."""

from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from explorer.desktop import BACKENDS

SCREEN = (1366, 768)  # the window's default size: without a window manager it covers the screen from (0, 0)
BACKGROUND = (0xF4, 0xF5, 0xF7)  # explorer/rendering/scene.py's BACKGROUND
VIEW = (slice(80, 400), slice(400, 1300))  # rows, columns inside the 3D view (right of the side panel, above the charts)


def _backend() -> str | None:
    def spec(name):
        try:
            return importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            return False

    if not spec("webview"):
        return None
    return next((name for name, mods in BACKENDS.items() if all(spec(m) for m in mods)), None)


pytestmark = [
    pytest.mark.skipif(shutil.which("Xvfb") is None, reason="Xvfb is not installed (./dev setup installs it)"),
    pytest.mark.skipif(_backend() is None, reason="no pywebview back end importable: pip install 'imm-studio[desktop]'"),
]


def read_xwd(path: Path) -> np.ndarray:
    """Xvfb's -fbdir screen (an XWD image, 32 bits a pixel) -> (H, W, 3) uint8 RGB."""
    data = path.read_bytes()
    h = struct.unpack(">25I", data[:100])
    header, width, height, byte_order, bits, line, ncolors = h[0], h[4], h[5], h[7], h[11], h[12], h[19]
    assert bits == 32, f"XWD with {bits} bits a pixel"
    px = np.frombuffer(data, np.uint8, count=line * height, offset=header + 12 * ncolors).reshape(height, line)
    px = px[:, : 4 * width].reshape(height, width, 4)
    return px[..., [2, 1, 0]] if byte_order == 0 else px[..., [1, 2, 3]]


def scene_shown(img: np.ndarray) -> tuple[bool, float, int]:
    """-> (shown, background share, coloured pixels) in the 3D view's region."""
    region = img[VIEW].astype(int)
    background = (np.abs(region - np.array(BACKGROUND)).max(axis=-1) <= 8).mean()
    coloured = int(((region.max(axis=-1) - region.min(axis=-1)) > 80).sum())  # the blue, red and green figures
    return background > 0.4 and coloured > 300, float(background), coloured


def _free_display() -> int:
    return next(n for n in range(90, 200) if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"))


@pytest.fixture
def xvfb(tmp_path):
    number, fbdir = _free_display(), tmp_path / "fb"
    fbdir.mkdir()
    proc = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", f"{SCREEN[0]}x{SCREEN[1]}x24", "-fbdir", str(fbdir),
                             "-nolisten", "tcp"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    deadline = time.monotonic() + 10
    while not os.path.exists(f"/tmp/.X11-unix/X{number}") and time.monotonic() < deadline:
        time.sleep(0.1)
    yield f":{number}", fbdir / "Xvfb_screen0"
    proc.terminate()
    proc.wait(10)


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


@pytest.mark.timeout(180)
def test_desktop_window_shows_the_scene_and_closing_it_stops_the_studio(xvfb, tmp_path):
    display, screen = xvfb
    env = dict(os.environ, DISPLAY=display, QTWEBENGINE_CHROMIUM_FLAGS="--no-sandbox --disable-gpu", OMP_NUM_THREADS="1")
    env.pop("WAYLAND_DISPLAY", None)
    proc = subprocess.Popen([sys.executable, "-m", "imm_model.cli", "explore", "--desktop", "--cache-dir", str(tmp_path / "cache")],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)  # fmt: skip
    try:
        shown, img, deadline = (False, 0.0, 0), None, time.monotonic() + 90
        while time.monotonic() < deadline and proc.poll() is None:
            time.sleep(2)
            img = read_xwd(screen)
            shown = scene_shown(img)
            if shown[0]:
                break
        if img is not None:
            import imageio.v3 as iio

            iio.imwrite(tmp_path / "desktop.png", img)
        assert proc.poll() is None, "imm explore --desktop exited: " + proc.communicate()[1][-2000:]
        assert shown[0], (f"no 3D scene in the window's view (background share {shown[1]:.2f}, coloured pixels "
                          f"{shown[2]}); see {tmp_path / 'desktop.png'}")
        # the window's own process (python -m explorer.desktop): it ending is the window closing
        windows = [c for c in _children(proc.pid) if b"explorer.desktop" in Path(f"/proc/{c}/cmdline").read_bytes()]
        assert len(windows) == 1, windows
        os.kill(windows[0], signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    assert "IMM Studio ready at http://localhost:" in out
