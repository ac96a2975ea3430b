"""The studio keeps to itself and to its tab: a scripted tour asks nothing of any origin but the studio's (no "Share
chart" upload, no font or script from a CDN) and no request of it fails (the favicon, trame's session-manager probe);
the address bar is the view's link from the first picture on, and another browser opening it gets a studio of its own.
Needs /usr/bin/chromium (fixtures in tests/conftest.py)."""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

import numpy as np
import pytest

from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(400)]

# Where map points are on the page: Plotly's own axes turn data coordinates into pixels.
POINT_PIXELS_JS = """() => { const el = document.getElementById('latent-plotly'), fl = el._fullLayout, r = el.getBoundingClientRect();
    const p = window.trame.state.get('latent_points');
    return p.x.map((x, i) => [r.left + fl.xaxis._offset + fl.xaxis.l2p(x), r.top + fl.yaxis._offset + fl.yaxis.l2p(p.y[i])]); }"""
MODEBAR_TITLES_JS = "() => [...document.querySelectorAll('#latent-plotly .modebar-btn')].map((b) => b.dataset.title || '')"


def origin(url: str) -> str:
    u = urlsplit(url)
    return f"{u.scheme.replace('ws', 'http', 1)}://{u.netloc}"


@pytest.mark.slow
def test_a_tour_asks_only_the_studio_and_nothing_fails(browser, studio, tmp_path):
    """Load, a slider, a click on the map, the review, an export: every request and websocket goes to the studio's own
    origin (data: and blob: URLs never leave the page), none is answered with an error, and the map's tool bar has no
    "Share chart" (plotly.js v4's upload of the figure to Chart Studio)."""
    context = browser.new_context(viewport={"width": 1366, "height": 768}, accept_downloads=True)
    asked: list[str] = []
    failed: list[tuple[int, str, str]] = []
    context.on("request", lambda r: asked.append(r.url))
    context.on("response", lambda r: r.status >= 400 and failed.append((r.status, r.request.method, r.url)))
    try:
        page = context.new_page()
        page.on("websocket", lambda ws: asked.append(ws.url))
        page.goto(studio.url, timeout=60000)
        probe.wait_for_view(page)
        names = probe.state(page, "class_names")
        count = probe.state(page, "mix_count")
        other = next(i for i in range(len(names)) if probe.state(page, f"w_{i}") != 1.0)
        probe.press_slider(page, f".slider-{names[other].replace(' ', '_')}", "End")
        probe.wait_state(page, f"s.get('mix_count') > {count}")

        probe.wait_for_latent_points(page, 60000)
        titles = page.evaluate(MODEBAR_TITLES_JS)
        assert any("Zoom" in t for t in titles), titles  # the tool bar is there ...
        assert not [t for t in titles if "Share" in t or "Chart Studio" in t or "Cloud" in t], titles  # ... with no upload
        points = np.array(page.evaluate(POINT_PIXELS_JS))
        current = probe.state(page, "sequence_index")
        gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(len(points)) * 1e9
        target = int(np.argmax(np.where(np.arange(len(points)) == current, -1, gaps.min(1))))
        page.mouse.click(*points[target])
        probe.wait_state(page, f"s.get('sequence_index') === {target}", timeout_ms=30000)

        page.click("#review-open")
        probe.wait_state(page, "s.get('review_rows').length > 0 && !s.get('review_busy')", timeout_ms=240000)
        page.click("#export-menu")
        with page.expect_download(timeout=60000) as download:
            page.click("#export-npz")
        assert download.value.path().stat().st_size > 1000
    finally:
        context.close()
    mine = origin(studio.url)
    away = [u for u in asked if not u.startswith(("data:", "blob:")) and origin(u) != mine]
    assert not away, away
    assert len(asked) > 10, asked  # the tour was recorded
    assert not failed, failed


def test_the_address_bar_is_the_views_link_and_another_browser_gets_its_own_studio(browser, studio):
    """Right after the first picture the address names the sequence and the mix; opened in another browser (a context of
    its own: no cookies shared) it shows that view in a studio of its own: a slider moved there leaves the first alone."""
    first = probe.open_studio(browser, studio.url)
    try:
        query = parse_qs(urlsplit(first.url).query)
        assert {"seq", "mix"} <= query.keys(), first.url
        shown = probe.state(first, "sequence_title")
        assert shown.startswith(query["seq"][0]), (shown, query)
        weights = [probe.state(first, f"w_{i}") for i in range(len(probe.state(first, "class_names")))]
        first_count = probe.state(first, "mix_count")

        second = probe.open_studio(browser, first.url)
        try:
            assert urlsplit(second.url).path != urlsplit(first.url).path  # another studio process
            probe.wait_state(second, f"s.get('sequence_title') === {shown!r}")
            free = int(np.argmin(np.abs(weights)))
            count = probe.state(second, "mix_count")
            probe.set_state(second, f"w_{free}", -1.0)
            probe.wait_state(second, f"s.get('mix_count') > {count} && s.get('label_text') !== ''")
            probe.wait_state(second, "window.location.search.includes(':-1')")
        finally:
            second.close()
        assert [probe.state(first, f"w_{i}") for i in range(len(weights))] == weights
        assert probe.state(first, "mix_count") == first_count
    finally:
        first.close()


def test_the_address_bar_follows_what_plays(browser, studio):
    """At 1366x768, while the studio plays: a sequence opened (as a map point or a review row opens one) and a slider
    moved are in the address bar at once, with playback going on, so a link copied mid-play shows what plays; the
    frame joins the link once playback stops."""
    page = probe.open_studio(browser, studio.url, width=1366, height=768)
    try:
        probe.set_state(page, "loop", True)
        probe.set_state(page, "playing", True)
        probe.wait_state(page, "s.get('playing') === true")
        current, items = probe.state(page, "sequence_index"), probe.state(page, "sequence_items")
        target = next(it["value"] for it in items[len(items) // 2:] + items if it["value"] != current)
        shown = probe.state(page, "sequence_title")
        probe.set_state(page, "sequence_index", target)
        # the page sets the index at once; the title (and the address) come with the server's answer
        probe.wait_state(page, f"s.get('sequence_index') === {target} && s.get('sequence_title') !== {shown!r}")
        sid = probe.state(page, "sequence_title").split(" · ")[0]
        probe.wait_state(page, f"decodeURIComponent(window.location.search).includes('seq={sid}&')", timeout_ms=30000)
        assert probe.state(page, "playing") and "frame=" not in page.url, page.url
        names = probe.state(page, "class_names")
        free = next(i for i in range(len(names)) if probe.state(page, f"w_{i}") == 0)
        probe.set_state(page, f"w_{free}", -1.0)
        probe.wait_state(page, "window.location.search.includes(':-1')", timeout_ms=30000)
        assert probe.state(page, "playing")
        probe.set_state(page, "playing", False)
        probe.wait_state(page, "window.location.search.includes('frame=')", timeout_ms=30000)
    finally:
        page.close()


def test_a_copied_address_in_another_tab_of_the_same_browser_opens_a_studio_of_its_own(browser, studio):
    """The same browser (one context: cookies shared), a second tab opened on the first tab's address: a studio of its
    own with the view the address names; a reload of the first tab keeps its studio."""
    context = browser.new_context(viewport={"width": 1366, "height": 768})
    try:
        first = context.new_page()
        first.goto(studio.url, timeout=60000)
        probe.wait_for_view(first)
        probe.wait_state(first, "window.location.search.includes('seq=')")
        path, shown = urlsplit(first.url).path, probe.state(first, "sequence_title")
        count = probe.state(first, "mix_count")
        second = context.new_page()
        second.goto(first.url, timeout=60000)
        probe.wait_for_view(second)
        assert urlsplit(second.url).path.removesuffix("index.html") != path.removesuffix("index.html")
        probe.wait_state(second, f"s.get('sequence_title') === {shown!r}")
        probe.set_state(second, "w_0", -1.0)
        probe.wait_state(second, "window.location.search.includes(':-1')")
        assert probe.state(first, "mix_count") == count and probe.state(first, "w_0") != -1.0
        first.reload(timeout=60000)
        probe.wait_for_view(first)
        assert urlsplit(first.url).path.removesuffix("index.html") == path.removesuffix("index.html")  # same tab, same studio
    finally:
        context.close()


def test_a_camera_turned_by_hand_is_in_the_link_and_a_link_restores_it(browser, studio):
    """A drag of the view, once released, puts the camera into the address bar (`camera=hand:` and its placement);
    that link opened in another browser shows the same picture; a crafted placement is named in one line."""
    import numpy as np

    first = probe.open_studio(browser, studio.url, width=1366, height=768)
    other = browser.new_context(viewport={"width": 1366, "height": 768})
    try:
        probe.wait_state(first, "s.get('url_query') !== ''")
        probe.wait_for_view_at_rest(first)
        preset = probe.view_pixels(first).astype(int)
        probe.drag_view(first, 8, 3)
        first.wait_for_function("() => location.search.includes('camera=hand:')", timeout=30000)
        probe.wait_for_view_at_rest(first)
        query = "?" + first.url.split("?", 1)[1]
        second = other.new_page()
        second.goto(studio.url.split("?")[0] + query, timeout=60000)
        probe.wait_for_view(second)
        second.wait_for_function("() => location.search.includes('camera=hand:')", timeout=30000)
        second.locator("#first-use-hints").wait_for(state="visible", timeout=10000)
        second.click("#hints-close")  # over the view in a browser that never dismissed it (the first page's drag did)
        probe.wait_for_view_at_rest(second)
        a, b = probe.view_pixels(first).astype(int), probe.view_pixels(second).astype(int)
        assert a.shape == b.shape == preset.shape
        differ = lambda p, q: (np.abs(p - q).sum(-1) > 60).mean()  # noqa: E731  share of pixels that differ
        assert differ(a, preset) > 0.05  # the drag turned the view ...
        assert differ(a, b) < 0.1 * differ(a, preset), (differ(a, b), differ(a, preset))  # ... and the link turns it alike
        third = other.new_page()
        third.goto(studio.url.split("?")[0] + "?camera=hand:1,2,3,1,2,3,0,1,0", timeout=60000)
        probe.wait_for_view(third)
        probe.wait_state(third, "s.get('error').includes('camera')", timeout_ms=30000)
        assert "\n" not in probe.state(third, "error")
    finally:
        other.close()
        first.close()
