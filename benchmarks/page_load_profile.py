"""Where the page's own time goes from its address to the first 3D picture: a CPU profile of the tab (Chromium's
sampling profiler through the DevTools protocol) over each load, summed by function and by script.

    .venv/bin/python benchmarks/page_load_profile.py [--loads 2] [--top 15]

Starts a studio with the bundled models (its latent cache in a temporary folder, so the first load is a cold one),
then loads the page `--loads` times in fresh browser contexts at 1366x768. Prints, per load, the time to the first
picture, the profiled milliseconds per script ("" is the browser's own work: layout, style, paint, garbage
collection) and the `--top` functions by their own time.
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from tests import studio_probe as probe  # noqa: E402

SAMPLING_US = 200


def profile_load(browser, url: str) -> tuple[float, collections.Counter]:
    """-> (seconds to the first picture, {(function, script, line): profiled ms})."""
    ctx = browser.new_context(viewport={"width": 1366, "height": 768})
    try:
        page = ctx.new_page()
        cdp = ctx.new_cdp_session(page)
        cdp.send("Profiler.enable")
        cdp.send("Profiler.setSamplingInterval", {"interval": SAMPLING_US})
        cdp.send("Profiler.start")
        start = time.perf_counter()
        page.goto(url, timeout=120_000)
        probe.wait_for_view(page)
        seconds = time.perf_counter() - start
        profile = cdp.send("Profiler.stop")["profile"]
    finally:
        ctx.close()
    frames = {node["id"]: node["callFrame"] for node in profile["nodes"]}
    own: collections.Counter = collections.Counter()
    for sample, delta_us in zip(profile["samples"], profile["timeDeltas"], strict=True):
        f = frames[sample]
        own[(f["functionName"] or "(anonymous)", f["url"].rsplit("/", 1)[-1], f["lineNumber"])] += delta_us / 1000
    return seconds, own


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loads", type=int, default=2)
    ap.add_argument("--top", type=int, default=15)
    args = ap.parse_args()
    if args.loads < 1 or args.top < 1:
        ap.error("--loads and --top must be at least 1")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as cache, sync_playwright() as pw, probe.StudioProcess(cache_dir=Path(cache), timeout=120) as studio:
        browser = probe.launch_chromium(pw)
        for load in range(1, args.loads + 1):
            seconds, own = profile_load(browser, studio.url)
            by_script: collections.Counter = collections.Counter()
            for (_, script, _), ms in own.items():
                by_script[script or '""'] += ms
            print(f"load {load}: first picture after {seconds:.2f} s; profiled {sum(own.values()):.0f} ms")
            print("  by script: " + ", ".join(f"{name} {ms:.0f} ms" for name, ms in by_script.most_common()))
            print(f"  of which the template compiler: {sum(ms for (f, s, _), ms in own.items() if f in ('parse', 'compile')):.0f} ms")
            for (function, script, line), ms in own.most_common(args.top):
                print(f"  {ms:7.1f} ms  {function}  {script}:{line}")
        browser.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
