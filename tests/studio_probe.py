"""Drive a running studio from Python: start `imm explore` in a subprocess and open it in headless
Chromium with Playwright. Shared by the studio tests and benchmarks/explorer_latency.py; not part of the installed
package.
"""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from imm_model.paths import REPO_ROOT

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]  # fmt: skip
URL_RE = re.compile(r"IMM Studio ready at (http://\S+)")
ARTIFACTS = REPO_ROOT / "test-artifacts"  # the browser tests' screenshots
VIEW_IMG = ".v-main .rounded.border img"
LATENT_POINTS = "#latent-plotly .scatterlayer .point"  # the latent map's points, once Plotly has drawn them


# the launcher's lines for a tab's studio process found stuck (explorer/serving/pool.py) and for a page that loaded
# itself again because its layout had not come (explorer/serving/launcher.py layout_late)
NOTICE = ("a tab's studio process was replaced", "a tab's page was loaded again")


class StudioProcess:
    """`imm explore --port 0 --no-browser` in a subprocess; `url` once it printed its address. `noticed`: every
    studio of this test run whose launcher said a NOTICE line, for the run's summary (tests/conftest.py)."""

    noticed: list[StudioProcess] = []

    def __init__(self, *extra: str, cache_dir: Path | None = None, timeout: float = 60.0):
        cmd = [sys.executable, "-m", "imm_model.cli", "explore", "--port", "0", "--no-browser", *extra]
        if cache_dir:
            cmd += ["--cache-dir", str(cache_dir)]
        self.started = time.monotonic()
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        self.lines: list[str] = []
        self.url = ""
        self.ready_s = float("nan")
        seen = threading.Event()

        def pump(stream):
            for line in stream:
                self.lines.append(line.rstrip())
                if line.startswith(NOTICE) and self not in StudioProcess.noticed:
                    StudioProcess.noticed.append(self)
                m = URL_RE.search(line)
                if m and not self.url:
                    self.url, self.ready_s = m.group(1), time.monotonic() - self.started
                    seen.set()
            seen.set()

        for s in (self.proc.stdout, self.proc.stderr):
            threading.Thread(target=pump, args=(s,), daemon=True).start()
        deadline = time.monotonic() + timeout
        while not self.url and self.proc.poll() is None and time.monotonic() < deadline:
            seen.wait(0.05)
        if not self.url:
            self.stop()
            raise RuntimeError("studio did not start: " + " | ".join(self.lines[-5:]))

    def read_log(self, timeout: float = 60.0) -> list[str]:
        """`lines` once it holds everything the studio wrote before this call: a marker written into the studio's own
        output pipes (through /proc) comes out of them after all of it."""
        marks = {fd: f"studio-probe-mark-{fd}-{time.monotonic_ns()}" for fd in (1, 2)}
        for fd, mark in marks.items():
            with open(f"/proc/{self.proc.pid}/fd/{fd}", "w") as pipe:
                pipe.write(mark + "\n")
        deadline = time.monotonic() + timeout
        while not set(marks.values()) <= set(self.lines):
            if time.monotonic() > deadline:
                raise TimeoutError("the studio's output was not read within the time")
            time.sleep(0.02)
        return [ln for ln in self.lines if not ln.startswith("studio-probe-mark-")]

    def stop(self) -> None:
        """Stop the launcher and its studio processes (its own process group, started above)."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                return
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def launch_chromium(playwright):
    return playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)


def open_studio(browser, url: str, width: int = 1400, height: int = 900, timeout_ms: int = 120000):
    """A new page on the studio, returned once the remote 3D view shows a real picture. Each page is served by a studio
    process of its own, forked as the page asks for it when the spare is taken: on a busy two-core machine its first
    picture can take most of a minute."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.goto(url, timeout=timeout_ms)
    wait_for_view(page, timeout_ms)
    return page


# What the page shows of its view and its connection, for a wait that failed.
# `link`: the page's websocket (explorer/static/websocket_bytes.js); `app`: trame has mounted the page's layout;
# `pending`: the page's stylesheets and scripts that have not loaded (trame's client waits for each before the layout)
VIEW_REPORT_JS = f"""() => {{ const i = document.querySelector('{VIEW_IMG}'), t = window.trame;
    return {{img: !!i, complete: i && i.complete, naturalWidth: i && i.naturalWidth, box: i && i.getBoundingClientRect().width,
             trame: !!t, app: !!document.querySelector('.v-application'), link: window.__immLink || null,
             loaded: document.readyState, pending: window.__immLink ? window.__immLink.waiting() : null,
             alert: (document.querySelector('.v-alert') || {{}}).innerText || '', address: location.pathname}}; }}"""


def wait_for_view(page, timeout_ms: int = 120000) -> None:
    """Until the 3D view's image shows a real picture; when it does not, the error says what the page had instead and
    a screenshot goes to test-artifacts/."""
    try:
        page.wait_for_function(
            f"() => {{ const i = document.querySelector('{VIEW_IMG}'); return i && i.complete && i.naturalWidth > 100 }}",
            timeout=timeout_ms,
        )
    except Exception as err:
        report = page.evaluate(VIEW_REPORT_JS)
        shot(page, "view-never-shown")
        raise TimeoutError(f"the 3D view showed no picture within {timeout_ms} ms; the page had {report}") from err


def state(page, key: str):
    return page.evaluate("k => window.trame.state.get(k)", key)


def set_state(page, key: str, value) -> None:
    """Set a state key as the page would, and wait until it has left for the server: trame's client holds a change
    back while a call of its own is under way, and a trigger sent meanwhile would overtake it."""
    page.evaluate("([k, v]) => window.trame.state.set(k, v)", [key, value])
    page.wait_for_function("() => { const d = window.trame.state.dirtyKeys; return !d || !d.has || d.size === 0; }",
                           timeout=30000)


def view_pixels(page) -> np.ndarray:
    """(H, W, 3) uint8 of the 3D view as the browser shows it."""
    from io import BytesIO

    from PIL import Image

    png = page.locator(VIEW_IMG).screenshot()
    return np.asarray(Image.open(BytesIO(png)).convert("RGB"))


def color_mask(rgb: np.ndarray, hex_color: str, tol: int = 60) -> np.ndarray:
    """Pixels within `tol` (per channel) of a character color; shading darkens, so compare hue-ish."""
    h = hex_color.lstrip("#")
    target = np.array([int(h[i : i + 2], 16) for i in (0, 2, 4)], float)
    px = rgb.astype(float)
    # Normalize brightness: compare chromaticity, and require a saturated pixel (not grey floor).
    sat = px.max(-1) - px.min(-1)
    chroma = px / (px.sum(-1, keepdims=True) + 1e-6)
    tchroma = target / target.sum()
    close = np.abs(chroma - tchroma).max(-1) < tol / 765.0
    return close & (sat > 60)


def count_colors(rgb: np.ndarray, colors: Sequence[str]) -> list[int]:
    return [int(color_mask(rgb, c).sum()) for c in colors]


def watch_view_images(page) -> None:
    """Count pictures the browser has decoded in the 3D view, with their performance.now() times
    (window.__immImages), so a test can wait for the picture that follows an action."""
    page.evaluate(
        """(sel) => {
        if (window.__immImages) return;
        window.__immImages = [];
        const img = document.querySelector(sel);
        img.addEventListener('load', () => window.__immImages.push(performance.now()));
    }""",
        VIEW_IMG,
    )


def images_seen(page) -> int:
    return page.evaluate("() => window.__immImages.length")


def wait_for_new_image(page, after: int, timeout_ms: int = 10000) -> None:
    page.wait_for_function("(n) => window.__immImages.length > n", arg=after, timeout=timeout_ms)


def wait_for_view_at_rest(page, timeout_ms: int = 60000) -> None:
    """Wait until the 3D view shows the picture an action ends on: the server has no picture to render or hold back,
    the last one it sent is the sharp still picture, the page reported it shown, and the view's image is loaded
    (explorer/rendering/view_stream.py's `view_at_rest`). Asked after the action's state reached the page, so the
    server answers after it asked for the action's picture: an older still picture never counts."""
    at_rest = f"""async () => {{ await window.trame.state.flush();  // a change the test just made goes first
        return (await window.trame.trigger('view_at_rest')) === true && document.querySelector('{VIEW_IMG}').complete; }}"""
    deadline = time.monotonic() + timeout_ms / 1000
    while not page.evaluate(at_rest):  # (wait_for_function would take the async function's promise for a yes)
        if time.monotonic() > deadline:
            raise TimeoutError(f"the 3D view did not come to rest within {timeout_ms} ms")
        page.wait_for_timeout(100)


def drag_view(page, dx: float, dy: float, steps: int = 10, height_fraction: float = 0.5) -> None:
    """Drag across the 3D view as a user turns it: from its centre (or `height_fraction` down it), `steps` moves of
    (dx, dy) pixels with the button held."""
    box = page.locator(VIEW_IMG).bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] * height_fraction
    page.mouse.move(x, y)
    page.mouse.down()
    for k in range(1, steps + 1):
        page.mouse.move(x + dx * k, y + dy * k)
    page.mouse.up()


def press_slider(page, css: str, key: str) -> None:
    """Move a Vuetify slider as a user does with the keyboard (End = max, Home = min, arrows = step)."""
    page.bring_to_front()  # background tabs are throttled by Chromium
    thumb = page.locator(f"{css} .v-slider-thumb")
    thumb.focus()
    page.keyboard.press(key)


def press_key(page, key: str) -> None:
    """A key typed on the page itself, not into a focused slider."""
    page.bring_to_front()
    page.evaluate("() => document.activeElement && document.activeElement.blur()")
    page.keyboard.press(key)


def wait_state(page, expression: str, timeout_ms: int = 15000) -> None:
    """Wait until a JavaScript expression over the page's trame state `s` is true."""
    page.wait_for_function(f"() => {{ const s = window.trame.state; return {expression}; }}", timeout=timeout_ms)


# what the page knows of its map, for a test whose map did not come in time
MAP_STATE_JS = """() => { const s = window.trame.state; const p = s.get('latent_points');
    return {error: s.get('error'), projection: s.get('projection'), fitting: s.get('projection_busy'),
            points_sent: p ? p.x.length : 0, plotly_loaded: !!window.Plotly}; }"""


def wait_for_latent_points(page, timeout_ms: int = 60000) -> None:
    """Wait until Plotly has drawn the latent map's points; past the timeout, fail with what the page knows of the map
    (the fit still running, an error, the points sent but plotly.js not loaded)."""
    try:
        page.wait_for_selector(LATENT_POINTS, timeout=timeout_ms)
    except Exception as err:
        raise AssertionError(f"no latent map after {timeout_ms / 1000:.0f} s: {page.evaluate(MAP_STATE_JS)}") from err


def shot(page, name: str) -> Path:
    """A screenshot of the whole page in test-artifacts/."""
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path))
    return path


def watch_frames(page) -> None:
    """Record every frame the page's state shows from now on (window.__immFrames, sampled each 5 ms: a frame is shown
    for 33 ms or more), so a test can judge the frames playback went through."""
    page.evaluate("""() => { clearInterval(window.__immFrameWatch); window.__immFrames = [];
        window.__immFrameWatch = setInterval(() => { const f = window.trame.state.get('frame'), seen = window.__immFrames;
            if (seen[seen.length - 1] !== f) seen.push(f); }, 5); }""")


def frames_seen(page, stop: bool = False) -> list[int]:
    """The frames recorded since watch_frames, in order, each change once; `stop`: and stop recording."""
    return page.evaluate("(stop) => { if (stop) clearInterval(window.__immFrameWatch); return window.__immFrames; }", stop)


def export_npz(page) -> dict:
    """The view's reaction as the Export menu's .npz gives it: {field: array}."""
    page.click("#export-menu")
    with page.expect_download(timeout=60000) as download:
        page.click("#export-npz")
    with np.load(io.BytesIO(download.value.path().read_bytes())) as z:
        return {k: z[k] for k in z.files}
