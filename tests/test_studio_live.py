"""Live mode in a real browser at 1366x768: the follower made frame by frame as the leader plays, a slider moved mid-play
steering the frames to come and leaving the ones made alone, the export recording how the take was made. Needs
/usr/bin/chromium (fixtures in tests/conftest.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(400)]


def test_live_mode_plays_and_a_slider_moved_mid_play_steers_the_next_frames(browser, studio):
    page = probe.open_studio(browser, studio.url, width=1366, height=768)
    try:
        toggle = page.locator("#live-toggle")
        box = toggle.bounding_box()
        assert box and box["y"] + box["height"] <= 768 and box["x"] + box["width"] <= 1366, box  # on screen, no scrolling
        assert probe.state(page, "can_go_live") and toggle.is_enabled()
        probe.set_state(page, "loop", False)
        probe.set_state(page, "speed", 0.25)  # a frame every 0.27 s: room to pause and steer mid-take
        toggle.check()
        probe.wait_state(page, "s.get('live') === true && s.get('live_made') === 0")
        frames = probe.state(page, "num_frames")
        assert frames >= 16, frames

        probe.set_state(page, "playing", True)
        probe.wait_state(page, "s.get('live_made') >= 6", timeout_ms=30000)
        count = probe.state(page, "mix_count")
        probe.set_state(page, "playing", False)
        probe.wait_state(page, f"s.get('mix_count') > {count}", timeout_ms=30000)  # paused: the review reads what was made
        first = probe.export_npz(page)
        made = int(first["live_frames"])
        assert 6 <= made < frames and list(first["live_label_from"]) == [0]

        probe.set_state(page, "playing", True)
        probe.wait_state(page, f"s.get('live_made') >= {made + 2}", timeout_ms=30000)
        names = probe.state(page, "class_names")
        free = next(i for i in range(len(names)) if probe.state(page, f"w_{i}") == 0)
        count = probe.state(page, "mix_count")
        probe.set_state(page, f"w_{free}", 1.0)  # a second class, mid-play
        probe.wait_state(page, f"s.get('mix_count') > {count}", timeout_ms=30000)
        assert probe.state(page, "playing")
        probe.wait_state(page, f"s.get('playing') === false && s.get('live_made') === {frames}", timeout_ms=120000)

        second = probe.export_npz(page)
        assert int(second["live_frames"]) == frames
        steered_from = [int(f) for f in second["live_label_from"]]
        assert len(steered_from) == 2 and made + 2 <= steered_from[1] < frames, steered_from
        np.testing.assert_array_equal(second["follower"][:made], first["follower"][:made])  # the past stays
        after = steered_from[1]
        assert np.abs(second["follower"][after:] - first["follower"][after:]).max() > 0.01  # the next frames changed
        assert names[free].replace(" ", "_") in str(second["live_label_text"][1])
    finally:
        page.close()
