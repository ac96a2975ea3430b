"""What a change to each piece of state a slider move touches costs the page's thread, before the page sends anything
else: a new value set from the page (trame's `state.set`), timed to its websocket message. trame sends it after the
page's re-render (Vue runs that as a microtask queued first), so the time is the re-render of what reads the key:
the page's whole template, or a part rendered apart from it (explorer/ui/layout.py `rendered_apart`).

    .venv/bin/python benchmarks/page_render_cost.py [--repeats 10] [--keys w_1 label_text ...]

Keys: a class slider's value (the page sets it), and what the server sends back with every follower drawn (set from
the page here: the server takes the value and draws nothing for it), beside a key nothing reads. Prints the median and
p95 in ms per key. A studio with the bundled models, headless Chromium, the view at 1400x900.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from benchmarks.explorer_latency import VIEW_SIZE, WIRE_JS  # noqa: E402
from tests import studio_probe as probe  # noqa: E402

# two values each key takes in turn (the map's marks as the studio sends them; the server sends the rest as text)
KEYS = {
    "w_1": (1.0, 0.0),
    "label_text": ("+1 kicking", "+1 kicking, +1 pushing"),
    "reads_as": ([], [{"name": "kicking", "p": 0.5, "asked": "+", "color": "#e41a1c"}]),
    "afd_text": ("AFD 0.41", "AFD 0.52"),
    "contact_text": ("", "contact: frame 12"),
    "contact_marks": ([], [12]),
    "distance_chart": ("<b>a</b>", "<b>b</b>"),
    "url_query": ("?a=1", "?a=2"),
    "latent_marks": ({"ring": [0.1, 0.2], "star": [0.3, 0.4]}, {"ring": [0.1, 0.2], "star": [0.5, 0.1]}),
    "imm_read_by_nothing": (1, 0),
}
SET_JS = """async ([key, value]) => { const wire = window.__immWire, n = wire.sent.length, t0 = performance.now();
    window.trame.state.set(key, value);
    while (wire.sent.length === n && performance.now() - t0 < 2000) await new Promise((r) => setTimeout(r, 0));
    return wire.sent.length > n ? wire.sent[n] - t0 : null; }"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--keys", nargs="+", default=list(KEYS), choices=list(KEYS))
    args = ap.parse_args()
    if args.repeats < 2:
        ap.error("--repeats must be at least 2")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        studio = probe.StudioProcess(cache_dir=Path(tmp), timeout=120)
        try:
            page = probe.open_studio(browser, studio.url, *VIEW_SIZE)
            probe.wait_state(page, "!s.get('projection_busy')", 180000)  # the map's fit off the cores first
            page.evaluate(WIRE_JS)
            time.sleep(2)
            print("a change set from the page -> its websocket message (ms); the page's template re-rendered first if it "
                  "reads the key")
            for key in args.keys:
                times = []
                for k in range(args.repeats + 1):
                    ms = page.evaluate(SET_JS, [key, KEYS[key][k % 2]])
                    if k and ms is not None:  # the first change of a key is a warm-up
                        times.append(ms)
                    time.sleep(0.3)
                print(f"  {key:22s} median {np.median(times):6.1f}  p95 {np.percentile(times, 95):6.1f}")
        finally:
            studio.stop()
            browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
