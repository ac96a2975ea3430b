"""How soon the address bar names a sequence opened from the latent map, while it plays (headless Chromium).

    .venv/bin/python benchmarks/link_latency.py [--clicks 20] [--width 1366 --height 768]

Opens the studio, then clicks points of the latent map one after another (each a sequence other than the one
playing, spread over the map); per click, the time in the page (performance.now()) from the click to the first
moment `location.search` names the clicked sequence, and whether playback was going on then. Prints the median, p95
and max in ms, with the machine's load. The bar: within 1 s.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
from playwright.sync_api import sync_playwright

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from tests import studio_probe as probe  # noqa: E402

POINT_PIXELS_JS = """() => { const el = document.getElementById('latent-plotly'), fl = el._fullLayout, r = el.getBoundingClientRect();
    const p = window.trame.state.get('latent_points');
    return p.x.map((x, i) => [r.left + fl.xaxis._offset + fl.xaxis.l2p(x), r.top + fl.yaxis._offset + fl.yaxis.l2p(p.y[i])]); }"""
# Clicks at (x, y) and resolves with the ms until the address bar names `sid`, polled every animation frame (null
# after 10 s: the click opened another point, or nothing).
CLICK_JS = """([x, y, sid]) => new Promise((resolve) => {
    const t0 = performance.now();
    const el = document.elementFromPoint(x, y);
    for (const type of ['mousedown', 'mouseup', 'click']) {
      el.dispatchEvent(new MouseEvent(type, {bubbles: true, clientX: x, clientY: y, view: window})); }
    const poll = () => decodeURIComponent(location.search).includes(`seq=${sid}&`)
      ? resolve({ms: performance.now() - t0, playing: window.trame.state.get('playing')})
      : performance.now() - t0 > 10000 ? resolve({ms: null, playing: null}) : requestAnimationFrame(poll);
    poll(); })"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clicks", type=int, default=20)
    ap.add_argument("--width", type=int, default=1366)
    ap.add_argument("--height", type=int, default=768)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as cache, probe.StudioProcess(cache_dir=Path(cache)) as studio, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        page = probe.open_studio(browser, studio.url, args.width, args.height)
        page.wait_for_selector(probe.LATENT_POINTS, timeout=180000)
        points = np.array(page.evaluate(POINT_PIXELS_JS))
        ids = probe.state(page, "latent_points")["id"]
        gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(len(points)) * 1e9
        order = np.argsort(-gaps.min(1))  # the points with the most room around them: a click hits the one meant
        times, playing, missed = [], [], 0
        for target in order[: args.clicks]:
            if int(target) == probe.state(page, "sequence_index"):
                continue
            x, y = points[target]
            page.mouse.move(x, y)  # Plotly picks the hovered point on click
            page.wait_for_selector("#latent-plotly .hoverlayer .hovertext", timeout=5000)
            result = page.evaluate(CLICK_JS, [float(x), float(y), ids[target]])
            if result["ms"] is None:
                missed += 1
                continue
            times.append(result["ms"])
            playing.append(bool(result["playing"]))
            probe.wait_state(page, f"s.get('sequence_index') === {int(target)}")
        browser.close()
    t = np.array(times)
    print(f"{len(t)} latent-map clicks at {args.width}x{args.height}, load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores: "
          f"address bar names the sequence after median {np.median(t):.0f} ms, p95 {np.percentile(t, 95):.0f} ms, "
          f"max {t.max():.0f} ms; playing at that moment in {sum(playing)} of {len(t)}; clicks that opened no sequence "
          f"within 10 s: {missed}")


if __name__ == "__main__":
    main()
