"""Details of the studio page a user sees: a refused seed, the legend of hidden figures, the sequence box, downloads
named for what they hold, an .mp4 at the view's own size, the first-use hints. Needs /usr/bin/chromium (fixtures in
tests/conftest.py)."""

from __future__ import annotations

import pytest

from explorer.ui.layout import HINTS_SEEN
from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]


def test_a_refused_seed_leaves_the_seed_drawn_on_the_chip_and_the_field(page):
    probe.wait_state(page, "s.get('model_name') === 'diffusion' && !s.get('computing')", timeout_ms=60000)  # the default
    try:
        seed = probe.state(page, "seed")
        field = page.locator("#seed-field")
        field.fill("-5")
        field.press("Enter")
        page.locator("#error-alert").wait_for(state="visible", timeout=15000)
        probe.wait_state(page, f"String(s.get('seed')) === '{seed}'")
        page.wait_for_function(f"() => document.querySelector('#model-chip').textContent.includes('seed {seed}')", timeout=10000)
        assert "-5" not in page.locator("#model-chip").inner_text()
        assert "primary" in (page.locator("#variation-count .v-btn--active").get_attribute("class") or "")  # the count shows
    finally:
        probe.set_state(page, "error", "")


def test_the_legend_lists_only_the_figures_shown(page):
    assert page.locator(".legend-ground_truth").count() == 1
    probe.set_state(page, "show_ground_truth", False)
    try:
        page.locator(".legend-ground_truth").wait_for(state="detached", timeout=10000)
        assert page.locator(".legend-leader").count() == 1 and page.locator(".legend-synthesized").count() == 1
    finally:
        probe.set_state(page, "show_ground_truth", True)


def test_typing_in_the_sequence_box_replaces_the_name_shown(page):
    box = page.locator("#sequence-picker")
    box.click()
    page.wait_for_function("() => document.querySelector('#sequence-picker').value.includes(' · ')")  # the name on screen
    page.keyboard.type("s01s02")
    assert box.input_value() == "s01s02"
    page.keyboard.press("Escape")


def test_downloads_are_named_for_the_sequence_and_mix_and_the_mp4_keeps_the_views_size(page, tmp_path):
    import imageio.v3 as iio

    sequence = probe.state(page, "sequence_title").split(" · ")[0].replace("/", "-")
    page.click("#export-menu")
    with page.expect_download(timeout=60000) as npz:
        page.click("#export-npz")
    assert npz.value.suggested_filename.startswith(sequence) and npz.value.suggested_filename.endswith(".npz")
    size_js = f"() => {{ const i = document.querySelector('{probe.VIEW_IMG}'); return [i.naturalWidth, i.naturalHeight]; }}"
    width, height = page.evaluate(size_js)
    page.click("#export-menu")
    with page.expect_download(timeout=120000) as mp4:
        page.click("#export-mp4")
    assert mp4.value.suggested_filename.startswith(sequence) and mp4.value.suggested_filename.endswith(".mp4")
    path = tmp_path / "view.mp4"
    mp4.value.save_as(path)
    frames = iio.imread(path, index=None)
    assert frames.shape[1:3] == (height // 2 * 2, width // 2 * 2), (frames.shape, width, height)


def test_first_use_hints_show_until_dismissed_and_the_browser_remembers(browser, studio):
    def with_hints(context):
        page = context.new_page()
        page.goto(studio.url, timeout=60000)
        probe.wait_for_view(page)
        hints = page.locator("#first-use-hints")
        hints.wait_for(state="visible", timeout=10000)
        return page, hints

    context = browser.new_context(viewport={"width": 1366, "height": 768})
    try:
        first, hints = with_hints(context)
        assert "rotate" in hints.inner_text() and "latent map" in hints.inner_text()
        box = hints.bounding_box()
        assert box["height"] <= 40, box  # one line
        first.click("#hints-close")
        hints.wait_for(state="detached", timeout=10000)
        first.close()
        again = context.new_page()
        again.goto(studio.url, timeout=60000)
        probe.wait_for_view(again)
        probe.wait_state(again, "s.get('url_query') !== ''")  # the page's start-up hooks have run
        assert again.locator("#first-use-hints").count() == 0
    finally:
        context.close()
    fresh = browser.new_context(viewport={"width": 1366, "height": 768})  # a browser that never dismissed them
    try:
        page, hints = with_hints(fresh)
        probe.drag_view(page, 4, 0, height_fraction=1 / 3)  # a drag: what the hint says to do
        hints.wait_for(state="detached", timeout=10000)
        assert page.evaluate(f"() => localStorage.getItem('{HINTS_SEEN}')") == "1"
    finally:
        fresh.close()


def test_at_1280_the_charts_axis_title_keeps_off_the_contact_line(browser, studio):
    page = probe.open_studio(browser, studio.url, 1280, 720)
    try:
        page.wait_for_selector("#distance-chart .imm-axis-y", timeout=30000)
        title, contact, chart = (page.locator(sel).bounding_box() for sel in ("#distance-chart .imm-axis-y", "#contact-text",
                                                                                 "#chart-card"))
        assert title["y"] >= contact["y"] + contact["height"] - 1, (title, contact)  # below the contact line, not on it
        assert chart["x"] <= title["x"] and title["y"] + title["height"] <= chart["y"] + chart["height"], (title, chart)
    finally:
        page.close()


def test_the_views_corner_turns_on_trails_follows_the_pair_and_goes_full_screen(browser, studio):
    import numpy as np

    page = probe.open_studio(browser, studio.url, 1366, 768)
    try:
        probe.watch_view_images(page)
        probe.set_state(page, "frame", 12)
        probe.wait_state(page, "s.get('time_text').startsWith('frame 13/')")
        page.wait_for_function("() => { const i = document.querySelector('.imm-scene img'); return i.complete; }")
        before = probe.view_pixels(page)
        n = probe.images_seen(page)
        page.click("#trails-button")
        probe.wait_state(page, "s.get('trails') === true")
        probe.wait_for_new_image(page, n)
        page.wait_for_function("() => { const i = document.querySelector('.imm-scene img'); return i.complete; }")
        assert int((np.abs(probe.view_pixels(page).astype(int) - before.astype(int)).sum(-1) > 60).sum()) > 200  # ghosts drawn
        page.click("#follow-button")
        probe.wait_state(page, "s.get('follow_camera') === true")
        width = page.evaluate("() => document.querySelector('.imm-scene img').naturalWidth")
        page.click("#fullscreen-button")
        page.wait_for_function("() => document.fullscreenElement && document.fullscreenElement.matches('.imm-stage')", timeout=10000)
        page.wait_for_function(f"() => document.querySelector('.imm-scene img').naturalWidth > {width}", timeout=30000)
        play = page.locator("#play-button").bounding_box()  # full screen keeps the playback controls on screen
        screen = page.evaluate("() => [window.innerWidth, window.innerHeight]")
        assert play and 0 <= play["y"] and play["y"] + play["height"] <= screen[1], (play, screen)
        page.click("#play-button")
        probe.wait_state(page, "s.get('playing') === true")
        page.click("#play-button")
        probe.wait_state(page, "s.get('playing') === false")
        page.click("#fullscreen-button")
        page.wait_for_function("() => !document.fullscreenElement", timeout=10000)
    finally:
        page.close()


def test_hovering_a_joint_names_it_with_its_speed(browser, studio):
    import numpy as np

    from explorer.rendering.palette import LEADER

    page = probe.open_studio(browser, studio.url, 1366, 768)
    try:
        page.click("#hints-close")
        leader = probe.color_mask(probe.view_pixels(page), LEADER)
        leader[:40] = False  # the legend over the view's top
        ys, xs = np.nonzero(leader)
        top = int(np.argmin(ys))  # the top of the head: its joint's sphere
        box = page.locator(probe.VIEW_IMG).bounding_box()
        page.mouse.move(box["x"] + float(xs[top]), box["y"] + float(ys[top]) + 2)
        probe.wait_state(page, "s.get('joint_hover') && s.get('joint_hover').text.startsWith('Leader')")
        tip = page.locator("#joint-hover")
        tip.wait_for(state="visible", timeout=10000)
        assert tip.inner_text().endswith("m/s")
        page.mouse.move(box["x"] + 5, box["y"] + box["height"] - 5)  # the floor's corner: no joint there
        probe.wait_state(page, "s.get('joint_hover') === null")
    finally:
        page.close()
