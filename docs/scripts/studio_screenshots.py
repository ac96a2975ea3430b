"""The studio pictures in docs/: the page at first load at both laptop sizes, in a real browser (Debian's chromium).

    .venv/bin/python docs/scripts/studio_screenshots.py   # writes docs/studio.png (1366x768) and docs/studio-1280.png

The pictures of the review, the timeline and the gallery are taken by their browser tests' steps (see the user guide);
these two show what a user sees first: the label mix, the view, the chart and the map.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from playwright.sync_api import sync_playwright

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the studio driver lives beside the tests
from tests import studio_probe as probe  # noqa: E402

DOCS = Path(__file__).resolve().parents[1]
SIZES = {"studio.png": (1366, 768), "studio-1280.png": (1280, 720)}


def main() -> None:
    with tempfile.TemporaryDirectory() as cache, probe.StudioProcess(cache_dir=Path(cache)) as studio, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        try:
            for name, (width, height) in SIZES.items():
                page = probe.open_studio(browser, studio.url, width, height)
                probe.wait_state(page, "s.get('latent_points') && s.get('latent_points').x.length > 0", timeout_ms=180000)  # the map fitted
                probe.wait_for_view_at_rest(page)
                page.screenshot(path=str(DOCS / name))
                print(f"{DOCS / name}: {width}x{height}")
                page.close()
        finally:
            browser.close()


if __name__ == "__main__":
    main()
