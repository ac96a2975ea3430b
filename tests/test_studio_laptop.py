"""The label mix where a researcher works, in a real browser at laptop sizes (1366x768, 1280x720) and at 1920x1080: the
class sliders on screen at load without scrolling, each at least 160 px long, a value typed per class, and the part
switch in words. Needs /usr/bin/chromium (fixtures in tests/conftest.py)."""

from __future__ import annotations

import pytest

from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(400)]

TRACKS_JS = """() => [...document.querySelectorAll('.class-slider .v-slider-track')].map((e) => {
    const r = e.getBoundingClientRect(); return {top: r.top, bottom: r.bottom, left: r.left, width: r.width}; })"""


@pytest.mark.parametrize("size", [(1366, 768), (1280, 720), (1920, 1080)])
def test_the_label_mix_is_on_screen_at_load_with_long_sliders(browser, studio, size):
    width, height = size
    page = probe.open_studio(browser, studio.url, width=width, height=height)
    try:
        tracks = page.evaluate(TRACKS_JS)
        assert len(tracks) == len(probe.state(page, "class_names"))
        assert tracks[0]["top"] >= 0 and tracks[0]["bottom"] <= height, tracks[0]  # the first slider, without scrolling
        assert all(t["width"] >= 160 for t in tracks), [round(t["width"]) for t in tracks]
        assert page.evaluate("() => document.querySelector('.v-navigation-drawer__content').scrollTop") == 0
        if size == (1366, 768):
            probe.shot(page, "studio-1366x768")
        if size == (1280, 720):
            probe.shot(page, "studio-1280x720")
    finally:
        page.close()


def test_a_value_typed_per_class_sets_its_slider(browser, studio):
    page = probe.open_studio(browser, studio.url, width=1366, height=768)
    try:
        names = probe.state(page, "class_names")
        free = next(i for i in range(len(names)) if probe.state(page, f"w_{i}") == 0)
        count = probe.state(page, "mix_count")
        field = page.locator(f"#value-slider-{free}")
        field.fill("0.35")
        field.press("Enter")
        probe.wait_state(page, f"s.get('w_{free}') === 0.35 && s.get('mix_count') > {count}", timeout_ms=30000)
        assert f"{names[free]} +0.35" in probe.state(page, "label_text")
        count = probe.state(page, "mix_count")
        field.fill("7")  # beyond the range: the slider's end
        field.press("Tab")  # leaving the field sets it too
        # the server has drawn it and sent its label in words (which would overwrite the one set below)
        probe.wait_state(page, f"s.get('w_{free}') === 1 && s.get('mix_count') > {count}", timeout_ms=30000)
        page.wait_for_function(f"() => document.querySelector('#value-slider-{free}').value === '1.00'", timeout=10000)
        scale = page.locator("#value-scale")
        scale.fill("1.5")
        # the server changes the page while the value is being typed (a reaction settling does): the typing stays
        probe.set_state(page, "label_text", "changed while typing")
        page.wait_for_function("() => document.querySelector('#label-text').innerText.includes('changed while typing')")
        assert scale.input_value() == "1.5"
        scale.press("Enter")
        probe.wait_state(page, "s.get('scale') === 1.5", timeout_ms=30000)
        page.wait_for_function("() => document.querySelector('#value-scale').value === '1.50'", timeout=10000)
        toggle = page.locator(f"#parts-{free}")
        if probe.state(page, "part_labels"):  # the default model reads a label per body part: the switch says so in words
            assert "by body part" in toggle.inner_text().lower()
            assert toggle.bounding_box()["height"] >= 20
    finally:
        page.close()
