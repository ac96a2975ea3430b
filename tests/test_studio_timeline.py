"""The timeline and the chart under the view. Without a browser: a loop range's ends and wraps, a link's joint plot,
the contact ticks' frames. In a real browser at laptop sizes: a loop range set with the buttons and
the keys [ ], drawn on the timeline, that playback keeps to over its wraps, kept through a mix and reset by another
sequence; the contact frames as ticks that seek; and the chart's plot of a picked joint pair's distance or a joint's
speed, matching the exported interaction's numbers, in the page's link. Needs /usr/bin/chromium (fixtures in
tests/conftest.py)."""

from __future__ import annotations

import numpy as np
import pytest

from explorer.rendering.charts import contact_frames
from explorer.session.files import FPS
from explorer.session.joint_plot import JointPlot
from explorer.session.loop_range import loop_bounds, with_end, wrap
from imm_model.skeleton import KINECT15
from tests import studio_probe as probe

# a line's heights over the plot's floor, frame by frame, in viewBox units (proportional to its values)
LINE_JS = """(series) => { const l = document.querySelector(`#distance-chart polyline[data-series=${series}]`);
    return l ? l.getAttribute('points').split(' ').map((p) => 1000 - Number(p.split(',')[1])) : null; }"""
TRACK_JS = "() => { const r = document.querySelector('#timeline .v-slider-track').getBoundingClientRect(); return [r.left, r.width]; }"
ON_SCREEN_JS = """([sel, w, h]) => { const b = document.querySelector(sel).getBoundingClientRect();
    return b.width > 0 && b.left >= 0 && b.top >= 0 && b.right <= w && b.bottom <= h; }"""


def joint(arrays: dict, who_joint: str, follower: str = "follower") -> np.ndarray:
    """(T, 3) world metres of "A.<joint>" (the leader) or "B.<joint>" (the `follower` array) in an exported interaction."""
    who, name = who_joint.split(".")
    return arrays["leader" if who == "A" else follower][:, KINECT15.joint_names.index(name)].astype(np.float64)


def assert_line_is(page, series: str, values: np.ndarray) -> None:
    """The chart's line `series` has a point per frame, at heights proportional to `values`."""
    heights = np.asarray(page.evaluate(LINE_JS, series))
    assert len(heights) == len(values), (len(heights), len(values))
    np.testing.assert_allclose(heights / heights.max(), values / values.max(), atol=2e-3)


def test_a_loop_range_is_set_at_either_end_and_wraps_playback_into_it():
    assert loop_bounds([], 24) == (0, 23) and loop_bounds([9, 3], 24) == (0, 23) and loop_bounds(["x", None], 24) == (0, 23)
    assert loop_bounds([-5, 99], 24) == (0, 23) and loop_bounds([3, 9], 24) == (3, 9)
    assert with_end([], "in", 5, 24) == [5, 23] and with_end([], "out", 5, 24) == [0, 5]
    assert with_end([3, 9], "in", 12, 24) == [12, 23]  # an in past the out runs to the end of the take
    assert with_end([3, 9], "out", 2, 24) == [0, 2] and with_end([3, 9], "out", 30, 24) == [3, 23]
    assert wrap(10.5, 3, 9) == pytest.approx(3.5) and wrap(16.25, 3, 9) == pytest.approx(9.25)  # once or more round


def test_a_joint_plot_is_read_from_a_link_only_as_the_picker_offers_it():
    names = KINECT15.joint_names
    assert JointPlot.parse("distance:A.right_hand:B.head", names).joints == ("A.right_hand", "B.head")
    assert JointPlot.parse("speed:B.head", names).text() == "speed:B.head"
    for bad in ("speed:A.head", "speed:B.nose", "distance:A.head", "height:B.head", "distance:A.head:B.head:B.neck"):
        with pytest.raises(ValueError):
            JointPlot.parse(bad, names)


def test_a_joint_plot_draws_the_follower_and_the_ground_truth_or_the_leader_alone():
    from types import SimpleNamespace

    t = np.arange(5.0)[:, None, None] * np.ones((5, 15, 3))  # every joint moves 1 m a frame on each axis
    session = SimpleNamespace(leader=np.zeros((5, 15, 3)), synth=t, ground_truth=None, world=lambda x: x,
                              data=SimpleNamespace(skeleton=KINECT15))
    assert JointPlot("speed", ("B.head",)).series(session)["follower"] == pytest.approx(np.full(5, np.sqrt(3) * FPS))
    assert list(JointPlot("distance", ("A.head", "B.neck")).series(session)) == ["follower"]  # no ground truth: no line
    session.ground_truth = 2 * t
    lines = JointPlot("distance", ("A.head", "B.neck")).series(session)
    assert lines["truth"] == pytest.approx(2 * lines["follower"]) and lines["follower"][-1] == pytest.approx(4 * np.sqrt(3))
    assert list(JointPlot("distance", ("A.head", "A.left_hand")).series(session)) == ["leader"]


@pytest.mark.parametrize("closest, marks", [([0.3, 0.04, 0.02, 0.03, 0.5, 0.01, 0.6], [2, 5]), ([0.3, 0.2, 0.4], [1]), ([], [])])
def test_the_contact_ticks_are_the_closest_frame_of_each_contact(closest, marks):
    assert contact_frames(np.asarray(closest)) == marks


@pytest.mark.browser
@pytest.mark.timeout(400)
def test_a_loop_range_keeps_playback_inside_it_and_lasts_as_long_as_its_sequence(browser, studio):
    page = probe.open_studio(browser, studio.url, width=1366, height=768)
    try:
        for sel in ("#loop-in", "#loop-out", "#timeline"):
            assert page.evaluate(ON_SCREEN_JS, [sel, 1366, 768]), sel
        n = probe.state(page, "num_frames")
        assert probe.state(page, "loop") and probe.state(page, "loop_range") == [] and n >= 16, n
        probe.set_state(page, "frame", 3)
        page.click("#loop-in")
        probe.wait_state(page, f"JSON.stringify(s.get('loop_range')) === '[3,{n - 1}]'")
        probe.set_state(page, "frame", 9)
        probe.press_key(page, "]")
        probe.wait_state(page, "JSON.stringify(s.get('loop_range')) === '[3,9]'")
        span = page.locator("#loop-span")
        assert span.inner_text().split() == ["4", "10"]  # numbered as the time is, from 1
        left, width = page.evaluate(TRACK_JS)
        box = span.bounding_box()  # from the in frame's place on the track to the out frame's
        assert abs(box["x"] - (left + width * 3 / (n - 1))) < 3 and abs(box["x"] + box["width"] - (left + width * 9 / (n - 1))) < 3

        probe.set_state(page, "speed", 2.0)
        probe.watch_frames(page)
        probe.set_state(page, "playing", True)
        wraps = "(() => { const f = window.__immFrames; return f.filter((x, i) => i > 0 && x < f[i - 1]).length; })()"
        page.wait_for_function(f"() => {wraps} >= 2", timeout=30000)  # round the range twice
        probe.set_state(page, "playing", False)
        played = probe.frames_seen(page, stop=True)
        assert set(played) <= set(range(3, 10)) and min(played) <= 4 and max(played) >= 8, played

        names = probe.state(page, "class_names")
        free = next(i for i in range(len(names)) if probe.state(page, f"w_{i}") == 0)
        count = probe.state(page, "mix_count")
        probe.set_state(page, f"w_{free}", 0.5)  # another mix: the same take, the same range
        probe.wait_state(page, f"s.get('mix_count') > {count}", timeout_ms=30000)
        assert probe.state(page, "loop_range") == [3, 9]
        probe.shot(page, "studio-timeline-1366x768")

        marks = probe.state(page, "contact_marks")
        assert marks and all(0 <= m < n for m in marks)
        page.locator(".imm-contact-tick").first.click()
        probe.wait_state(page, f"s.get('frame') === {marks[0]}")

        page.click("#loop-clear")
        probe.wait_state(page, "s.get('loop_range').length === 0")
        assert page.locator("#loop-span").count() == 0
        probe.press_key(page, "[")
        probe.wait_state(page, "s.get('loop_range').length === 2")
        other = next(it["value"] for it in probe.state(page, "sequence_items") if it["value"] != probe.state(page, "sequence_index"))
        probe.set_state(page, "sequence_index", other)
        probe.wait_state(page, f"s.get('sequence_index') === {other} && s.get('loop_range').length === 0", timeout_ms=30000)
        page.locator("#loop-span").wait_for(state="detached", timeout=10000)

        probe.press_key(page, "?")
        probe.wait_state(page, "s.get('show_keys')")
        assert "loop range" in page.locator("#keys-card").inner_text()
    finally:
        page.close()


@pytest.mark.browser
@pytest.mark.timeout(400)
@pytest.mark.parametrize("size", [(1366, 768), (1280, 720)])
def test_the_chart_plots_a_picked_joint_pair_or_speed_and_a_link_restores_it(browser, studio, size):
    width, height = size
    page = probe.open_studio(browser, studio.url, width=width, height=height)
    try:
        assert page.evaluate(LINE_JS, "follower") is None and page.evaluate(LINE_JS, "truth")  # today's chart by default
        n = probe.state(page, "num_frames")
        page.select_option("#plot-kind", "distance")
        page.wait_for_function(f"() => ({LINE_JS})('follower')", timeout=15000)
        card = page.locator("#chart-card").bounding_box()
        for sel in ("#plot-kind", "#plot-a", "#plot-b"):  # the picker fits its card
            box = page.locator(sel).bounding_box()
            assert box["x"] >= card["x"] and box["x"] + box["width"] <= card["x"] + card["width"], (sel, box, card)
        arrays = probe.export_npz(page)
        hands = {key: np.linalg.norm(joint(arrays, "A.right_hand") - joint(arrays, "B.right_hand", key), axis=-1)
                 for key in ("follower", "ground_truth")}
        assert_line_is(page, "follower", hands["follower"])
        assert_line_is(page, "truth", hands["ground_truth"])

        before = page.evaluate(LINE_JS, "follower")
        page.select_option("#plot-b", "B.left_foot")
        page.wait_for_function(f"(b) => JSON.stringify(({LINE_JS})('follower')) !== JSON.stringify(b)", arg=before, timeout=15000)
        assert_line_is(page, "follower", np.linalg.norm(joint(arrays, "A.right_hand") - joint(arrays, "B.left_foot"), axis=-1))

        page.select_option("#plot-kind", "speed")
        page.select_option("#plot-joint", "B.head")
        probe.wait_state(page, "s.get('url_query').includes('plot=speed:B.head')")
        speed = np.linalg.norm(np.gradient(joint(arrays, "B.head"), axis=0), axis=-1) * FPS
        page.wait_for_function("() => document.querySelector('#distance-chart .imm-axis-y').textContent === 'm/s'", timeout=15000)
        assert_line_is(page, "follower", speed)
        box = page.locator("#distance-seek").bounding_box()  # a click on the plot seeks, as on today's chart
        page.mouse.click(box["x"] + box["width"] * 0.5, box["y"] + box["height"] / 2)
        probe.wait_state(page, f"Math.abs(s.get('frame') - {round((n - 1) * 0.5)}) <= 1")
        probe.shot(page, f"studio-joint-plot-{width}x{height}")

        query = probe.state(page, "url_query")
        other = probe.open_studio(browser, studio.url + query, width, height, timeout_ms=90000)
        try:
            probe.wait_state(other, "s.get('plot_kind') === 'speed' && s.get('plot_joint') === 'B.head'", timeout_ms=30000)
            assert other.locator("#plot-kind").input_value() == "speed" and other.locator("#plot-joint").input_value() == "B.head"
            other.wait_for_function(f"() => ({LINE_JS})('follower')", timeout=15000)
            assert_line_is(other, "follower", speed)
        finally:
            other.close()
    finally:
        page.close()
