"""Where the studio's start-to-interactive time goes (targets: <= 3 s warm, <= 5 s cold, on an idle machine).

Starts `imm explore` twice on one latent cache folder (cold, then warm) and opens it in headless chromium. Prints,
per start: when the address was printed, and in the page (ms after navigation) when the websocket opened, when
the initial state arrived, when each script finished loading, when the client sent its next message (it sends
nothing while it loads and evaluates the modules), when the Vuetify app mounted and when the first 3D picture
was shown, and when the latent map was drawn (a Plotly figure whose plotly.js the page loads after its first picture;
on a cold cache the map is also fitted after the page opens).

    .venv/bin/python benchmarks/explorer_startup.py        # ~1 minute; run it on an idle machine
    .venv/bin/python benchmarks/explorer_startup.py --model gan=sample_data/imm_sbu.safetensors ...  # other models first

Arguments, if any, go to `imm explore` (default: the bundled models, the diffusion model first).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from tests import studio_probe as probe  # noqa: E402

# Injected before the page's own scripts: stamps websocket traffic and the first appearance of the app and picture.
PAGE_MARKS = """(() => {
  const marks = window.__immMarks = {sent: [], received: []};
  const now = () => Math.round(performance.now());
  const once = k => { if (!(k in marks)) marks[k] = now(); };
  const send = WebSocket.prototype.send;
  WebSocket.prototype.send = function (d) { marks.sent.push(now()); return send.call(this, d); };
  const Original = window.WebSocket;
  window.WebSocket = function (...args) {
    const ws = new Original(...args);
    ws.addEventListener('open', () => once('websocket open'));
    ws.addEventListener('message', e => marks.received.push([now(), e.data.size || e.data.byteLength || e.data.length || 0]));
    return ws;
  };
  window.WebSocket.prototype = Original.prototype;
  const poll = () => {
    if (document.querySelector('.v-application')) once('app mounted');
    const img = document.querySelector('VIEW_IMG');
    if (img && img.complete && img.naturalWidth > 100) { once('first picture'); return; }
    requestAnimationFrame(poll);
  };
  requestAnimationFrame(poll);
})()""".replace("VIEW_IMG", probe.VIEW_IMG)


def timeline(page) -> list[tuple[int, str]]:
    marks = page.evaluate("() => window.__immMarks")
    scripts = page.evaluate("""() => performance.getEntriesByType('resource').filter(e => e.name.endsWith('.js'))
        .map(e => [Math.round(e.responseEnd), e.name.split('/').pop(), e.encodedBodySize])""")
    state = next(((t, n) for t, n in marks["received"] if n > 10_000), (None, 0))  # the initial state message
    events = [(marks[k], k) for k in ("websocket open", "app mounted", "first picture") if k in marks]
    events += [(t, f"script loaded: {name} ({size / 1e6:.1f} MB)") for t, name, size in scripts]
    if state[0] is not None:
        events.append((state[0], f"initial state received ({state[1] / 1e3:.0f} kB)"))
        later = [t for t in marks["sent"] if t > state[0]]
        if later:
            events.append((later[0], "client sends again (modules loaded and evaluated)"))
    return sorted(events)


def main() -> int:
    from playwright.sync_api import sync_playwright

    cache = Path(tempfile.mkdtemp(prefix="imm-startup-"))
    with sync_playwright() as pw:
        browser = probe.launch_chromium(pw)
        for kind in ("cold", "warm"):
            # the tab is open before the studio starts, as a user's browser is (opening it took 0.2-0.3 s here)
            context = browser.new_context(viewport={"width": 1400, "height": 900})
            context.add_init_script(PAGE_MARKS)
            page = context.new_page()
            t0 = time.monotonic()
            studio = probe.StudioProcess(*sys.argv[1:], cache_dir=cache, timeout=120)
            navigated = time.monotonic() - t0
            page.goto(studio.url, timeout=120000)
            probe.wait_for_view(page, 120000)
            total = time.monotonic() - t0
            print(f"{kind} cache: first picture {total:.2f} s after start; address printed at {studio.ready_s:.2f} s; "
                  f"page opened at {navigated:.2f} s, then (ms after navigation):")
            for t, what in timeline(page):
                print(f"  {t:6d}  {what}")
            # a cold cache's map is fitted after the page opens: wait for it, so that the warm start finds it cached
            page.wait_for_selector(probe.LATENT_POINTS, timeout=120000)
            drawn = time.monotonic() - t0
            plotly_js = page.evaluate("""() => performance.getEntriesByType('resource').filter(e => /plotly[^/]*[.]min[.]js$/.test(e.name))
                .map(e => [Math.round(e.startTime), Math.round(e.responseEnd)])[0] || null""")
            if plotly_js:
                print(f"  {plotly_js[0]:6d}  plotly.min.js requested (after the first picture); loaded at {plotly_js[1]} ms")
            print(f"  latent map (Plotly) drawn {drawn:.2f} s after start")
            context.close()
            studio.stop()
        browser.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
