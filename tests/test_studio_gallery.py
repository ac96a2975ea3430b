"""The studio at laptop sizes (1366x768, 1280x720): the variations gallery of a seeded model, pictures exported at a
size of their own whatever the window, and side-by-side captions that never run into each other. Browser tests need
/usr/bin/chromium (fixtures in tests/conftest.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tests import studio_probe as probe


@pytest.mark.browser
@pytest.mark.timeout(400)
def test_a_png_exported_at_1280x720_from_a_1366x768_window_has_that_size_and_its_strip(browser, studio, tmp_path):
    """The Export menu's size: the picture is 1280x720 whatever the view's size, and its strip (legend, mix, frame)
    stays in its top band, the frame number inside the right edge."""
    from PIL import Image

    page = probe.open_studio(browser, studio.url, width=1366, height=768)
    try:
        view = page.locator(probe.VIEW_IMG).bounding_box()
        assert round(view["width"]) != 1280  # the view is not already that size
        page.locator("#export-menu").click()
        page.locator("#export-size").get_by_role("button", name="1280x720").click()
        probe.wait_state(page, "s.get('export_size') === '1280x720'")
        assert page.locator("#export-png").is_visible()  # the size's click kept the menu open
        with page.expect_download(timeout=30000) as download:
            page.locator("#export-png").click()
        path = tmp_path / "view.png"
        download.value.save_as(path)
        with Image.open(path) as im:
            assert im.size == (1280, 720)
            png = np.asarray(im.convert("RGB"))
        dark = png.max(-1) < 100  # the strip's text; the figures are coloured, the floor light
        rows = np.flatnonzero(dark.any(1))
        strip = rows[rows < 0.2 * 720]
        assert len(strip) > 10 and strip.max() < 0.12 * 720, strip.max()
        cols = np.flatnonzero(dark[: strip.max() + 1].any(0))
        assert cols.min() > 4 and cols.max() < 1280 - 4, (cols.min(), cols.max())  # nothing cut at the edges
        probe.shot(page, "studio-export-size-1366x768")
    finally:
        page.close()
