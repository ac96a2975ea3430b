"""How long Chromium's page thread is held evaluating plotly.js: the studio's vendored basic bundle against another
build (e.g. the plotly Python package's full plotly.min.js), and the first draw of a latent-map-like figure.

    .venv/bin/python benchmarks/plotly_bundle.py [--other PATH/plotly.min.js] [--rounds 3]

Each bundle is loaded by a <script> into a fresh browser context (an empty cache) and then into a second page of the
same context (from its cache); prints the milliseconds from the script's insertion to its `load` (download from a
local server + evaluation) and of a Plotly.newPlot of 197 points with a colour bar and the map's marker symbols.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import sys
import tempfile
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from explorer.serving.page_shell import PLOTLY_JS  # noqa: E402
from tests import studio_probe as probe  # noqa: E402


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # a line per request would bury the figures
        pass


LOAD_AND_DRAW = """async (src) => {
  const t0 = performance.now();
  await new Promise((ok, fail) => { const s = document.createElement('script'); s.src = src; s.onload = ok;
                                    s.onerror = fail; document.head.appendChild(s); });
  const t1 = performance.now();
  const x = Array.from({length: 197}, (_, i) => Math.sin(i)), y = x.map((_, i) => Math.cos(1.3 * i));
  await Plotly.newPlot('p', [
      {type: 'scatter', mode: 'markers', x, y, marker: {color: x, colorscale: 'Viridis', showscale: true,
                                                        symbol: x.map((v) => (v > 0 ? 'circle-open' : 'circle'))}},
      {type: 'scatter', mode: 'markers', x: [0], y: [0], marker: {symbol: 'star', size: 17}}],
    {dragmode: 'lasso'}, {responsive: true});
  return [t1 - t0, performance.now() - t1];
}"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--other", type=Path, help="another plotly.js build to compare (e.g. plotly/package_data/plotly.min.js)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    if args.rounds < 1:
        ap.error("--rounds must be at least 1")
    if args.other is not None and not args.other.is_file():
        ap.error(f"--other: no file {args.other}")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as site:
        bundles = {"vendored basic": PLOTLY_JS} | ({"other": args.other} if args.other else {})
        for i, path in enumerate(bundles.values()):
            shutil.copy(path, Path(site) / f"b{i}.js")
        (Path(site) / "index.html").write_text('<html><body><div id="p" style="width:400px;height:300px"></div></body></html>')
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=site))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        url = f"http://127.0.0.1:{server.server_address[1]}/index.html"
        try:
            with sync_playwright() as pw:
                browser = probe.launch_chromium(pw)
                for r in range(args.rounds):
                    for i, (name, path) in enumerate(bundles.items()):
                        ctx = browser.new_context()
                        times = []
                        for _ in range(2):  # an empty cache, then the same context's cache
                            page = ctx.new_page()
                            page.goto(url)
                            times += page.evaluate(LOAD_AND_DRAW, f"b{i}.js")
                        ctx.close()
                        print(f"round {r + 1}  {name:14s} {path.stat().st_size / 1e6:4.1f} MB  load + evaluate "
                              f"{times[0]:5.0f} ms (cached {times[2]:5.0f})  first draw {times[1]:4.0f} ms (cached {times[3]:4.0f})")
                browser.close()
        finally:
            server.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
