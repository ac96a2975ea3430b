"""The latent map at laptop sizes (1366x768, 1280x720), measured in the page with getBoundingClientRect: Plotly's tool
bar covers no legend entry, the AFD colour bar and its title sit on neither of the legend's marks ("this sequence",
"current mix"), and a lasso selection listed beside the map leaves its plot most of its width. Needs /usr/bin/chromium
(fixtures in tests/conftest.py)."""

from __future__ import annotations

import pytest

from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]

# Boxes of the map's parts as [left, top, right, bottom], and the plot area's width (Plotly's own layout).
PARTS_JS = """() => { const el = document.getElementById('latent-plotly');
    const box = (e) => { const b = e.getBoundingClientRect(); return [b.left, b.top, b.right, b.bottom]; };
    const all = (sel) => [...el.querySelectorAll(sel)].map(box);
    return {modebar: all('.modebar'), entries: all('.legend .traces'), colorbar: all('.colorbar'),
            colorbarTitle: all('.colorbar .cbtitle'), plotWidth: el._fullLayout.xaxis._length,
            figureWidth: el._fullLayout.width, boxWidth: el.clientWidth}; }"""
# The figure has been laid out again to its box's size (after the box changed, Plotly resizes on the next frames).
RESIZED_JS = "() => { const el = document.getElementById('latent-plotly'); return Math.abs(el._fullLayout.width - el.clientWidth) <= 1; }"


def overlap(a: list[float], b: list[float]) -> float:
    """The area two boxes share (0 when they only touch)."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def covered(boxes: list[list[float]], others: list[list[float]]) -> list[tuple]:
    return [(a, b) for a in boxes for b in others if overlap(a, b) > 0]


def lasso(page, fraction: float = 0.3) -> None:
    """Draw a lasso round the middle of the plot, as a user does with the tool bar's lasso."""
    page.locator('#latent-plotly .modebar-btn[data-val="lasso"]').click()
    plot = page.locator("#latent-plotly .nsewdrag").bounding_box()
    cx, cy = plot["x"] + plot["width"] / 2, plot["y"] + plot["height"] / 2
    rx, ry = plot["width"] * fraction, plot["height"] * fraction
    corners = [(cx - rx, cy - ry), (cx + rx, cy - ry), (cx + rx, cy + ry), (cx - rx, cy + ry), (cx - rx, cy - ry + 2)]
    page.mouse.move(*corners[0])
    page.mouse.down()
    for (x0, y0), (x1, y1) in zip(corners, corners[1:], strict=False):
        for k in range(1, 6):
            page.mouse.move(x0 + (x1 - x0) * k / 5, y0 + (y1 - y0) * k / 5)
    page.mouse.up()


@pytest.mark.slow
@pytest.mark.parametrize("width,height", [(1366, 768), (1280, 720)])
def test_at_laptop_sizes_the_latent_map_keeps_its_legend_and_plot_clear(browser, studio, width, height):
    """Mouse over the map (its tool bar shown): the tool bar covers no legend entry. Coloured by AFD: the colour bar and
    its title cover neither legend entry. A lasso selection: its list shows beside the map and the plot keeps at least
    three quarters of its width and 200 px."""
    page = probe.open_studio(browser, studio.url, width, height)
    try:
        probe.wait_for_latent_points(page, 60000)
        page.hover("#latent-plotly .nsewdrag")
        page.wait_for_selector("#latent-plotly .modebar .modebar-btn", state="visible")
        parts = page.evaluate(PARTS_JS)
        assert parts["modebar"] and len(parts["entries"]) >= 8, parts  # six classes, this sequence, the current mix
        assert covered(parts["modebar"], parts["entries"]) == [], parts
        before = parts["plotWidth"]

        probe.wait_state(page, "s.get('latent_points') && s.get('latent_points').afd", timeout_ms=180000)
        page.click("#latent-color-afd")
        page.wait_for_selector("#latent-plotly .colorbar .cbtitle", timeout=30000)
        parts = page.evaluate(PARTS_JS)
        probe.shot(page, f"studio-map-afd-{width}x{height}")
        assert len(parts["entries"]) == 2 and parts["colorbarTitle"], parts
        assert covered(parts["colorbar"] + parts["colorbarTitle"], parts["entries"]) == [], parts
        assert covered(parts["modebar"], parts["entries"] + parts["colorbar"]) == [], parts

        page.click("#latent-color button:nth-child(1)")  # by class again
        probe.wait_state(page, "s.get('latent_color') === 'class'")
        lasso(page)
        probe.wait_state(page, "s.get('latent_rows').length > 0")
        page.wait_for_selector("#latent-selection .latent-row")
        page.wait_for_function(RESIZED_JS, timeout=10000)
        parts = page.evaluate(PARTS_JS)
        probe.shot(page, f"studio-map-lasso-{width}x{height}")
        assert parts["plotWidth"] >= max(200, 0.75 * before), (before, parts)
        assert covered(parts["modebar"], parts["entries"]) == [], parts
    finally:
        page.close()
