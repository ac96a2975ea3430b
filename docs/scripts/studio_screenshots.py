"""The studio pictures in docs/: the page at first load at both laptop sizes, in a real browser (Debian's chromium).

    .venv/bin/python docs/scripts/studio_screenshots.py   # docs/studio.png (1366x768), docs/studio-1280.png and
                                                          # docs/studio-timeline.png (1366x768)

The pictures of the review and the gallery are taken by their browser tests' steps (see the user guide); the first two
show what a user sees first: the label mix, the view, the chart and the map; the third the timeline's loop range and
the chart plotting the distance between the two characters' right hands.
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
TIMELINE = "studio-timeline.png"
HANDS = "?plot=distance:A.right_hand:B.right_hand"  # a link's joint plot (explorer/ui/url_state.py)


def map_fitted(page) -> None:
    probe.wait_state(page, "s.get('latent_points') && s.get('latent_points').x.length > 0", timeout_ms=180000)


def timeline(browser, url: str) -> None:
    """The loop range over frames 6-17 of the take, paused at frame 12, the chart on the right hands' distance."""
    page = probe.open_studio(browser, url + HANDS, 1366, 768)
    map_fitted(page)
    for frame, key in ((5, "["), (16, "]")):
        probe.set_state(page, "frame", frame)
        probe.press_key(page, key)
    probe.wait_state(page, "JSON.stringify(s.get('loop_range')) === '[5,16]'")
    probe.set_state(page, "frame", 11)
    probe.wait_for_view_at_rest(page)
    page.screenshot(path=str(DOCS / TIMELINE))
    print(f"{DOCS / TIMELINE}: 1366x768")
    page.close()


def main() -> None:
    with tempfile.TemporaryDirectory() as cache, probe.StudioProcess(cache_dir=Path(cache)) as studio, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        try:
            for name, (width, height) in SIZES.items():
                page = probe.open_studio(browser, studio.url, width, height)
                map_fitted(page)
                probe.wait_for_view_at_rest(page)
                page.screenshot(path=str(DOCS / name))
                print(f"{DOCS / name}: {width}x{height}")
                page.close()
            timeline(browser, studio.url)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
