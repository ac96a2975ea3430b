"""The studio at laptop sizes (1366x768, 1280x720): the variations gallery of a seeded model, pictures exported at a
size of their own whatever the window, and side-by-side captions that never run into each other. Browser tests need
/usr/bin/chromium (fixtures in tests/conftest.py)."""

from __future__ import annotations

import itertools

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


# the 3D view's size in the studio at 1366x768 and 1280x720 (measured in Chromium: the view's <img>)
LAPTOP_VIEWS = {"1366x768": (1018, 388), "1280x720": (932, 357)}


@pytest.mark.parametrize("window", LAPTOP_VIEWS)
def test_side_by_side_captions_never_overlap_and_keep_their_size_while_playing(sample_data, window):
    """Side by side with 3 to 9 figures (variations, other models' followers), the captions' boxes in the picture never
    overlap at the view's size at laptop window sizes: long ones break at ' · ' or shrink; a draft picture (playing, at
    PLAYBACK_SCALE of the view's size) shows them at the same size relative to the picture, and with the same words."""
    pytest.importorskip("pyvista")
    from explorer.rendering.scene import Scene, floor_height
    from explorer.rendering.view_stream import texts_scaled
    from explorer.ui.playback import PLAYBACK_SCALE

    leader, follower = sample_data.canonical(0)
    size = LAPTOP_VIEWS[window]
    scene = Scene(sample_data.skeleton, floor_height(sample_data.leader, sample_data.follower, sample_data.skeleton), size)
    others = [("the paper's GAN", follower), ("1-NN retrieval", follower), ("the diffusion model (parts)\nseed 0", follower)]
    try:
        scene.set_sequence(leader, follower, follower + np.float32([0.0, 0.0, 0.3]))
        scene.set_layout("side_by_side")
        for seeds, compared in ((1, 0), (2, 0), (1, 1), (1, 2), (4, 0), (4, 3)):
            scene.set_variations([follower] * seeds, list(range(seeds)), "the diffusion model" if compared else "")
            scene.set_compared(others[:compared])
            scene.render()
            boxes = scene.caption_boxes()
            assert len(boxes) == 3 + seeds - 1 + compared
            for a, b in itertools.combinations(boxes, 2):
                (l1, r1, b1, t1), (l2, r2, b2, t2) = boxes[a], boxes[b]
                assert r1 <= l2 or r2 <= l1 or t1 <= b2 or t2 <= b1, (window, seeds, compared, a, boxes[a], b, boxes[b])
            assert all(t <= size[1] for *_, t in boxes.values()), boxes  # in the picture
            texts = {k: scene.captions[k].input for k in boxes}
            if (seeds, compared) == (1, 1):  # the case of the issue: the model's title beside another model's
                assert "the diffusion model" in texts["synthesized"] and "seed 0" in texts["synthesized"], texts

            width, height = size
            scene.render_window.SetSize(round(width * PLAYBACK_SCALE), round(height * PLAYBACK_SCALE))
            try:
                with texts_scaled(scene.render_window, PLAYBACK_SCALE):
                    scene.render()
                    drafted = scene.caption_boxes()
                    assert {k: scene.captions[k].input for k in drafted} == texts
            finally:
                scene.render_window.SetSize(width, height)
            for k, (left, right, bottom, top) in boxes.items():
                d_left, d_right, d_bottom, d_top = (v / PLAYBACK_SCALE for v in drafted[k])
                assert abs((d_right - d_left) - (right - left)) <= 0.15 * (right - left) + 4, (k, boxes[k], drafted[k])
                assert abs((d_top - d_bottom) - (top - bottom)) <= 0.15 * (top - bottom) + 4, (k, boxes[k], drafted[k])
            scene.render()
            assert scene.caption_boxes() == boxes  # paused again: as before
    finally:
        scene.close()


@pytest.mark.browser
@pytest.mark.timeout(400)
@pytest.mark.parametrize("size", [(1366, 768), (1280, 720)])
def test_the_variations_gallery_shows_its_seeds_and_a_click_opens_one(browser, studio, size):
    """The diffusion model's gallery (from the variation controls): its seeds' pictures load, all different and on screen
    (two rows of four at laptop sizes), each captioned with its seed; a click on the third sets that seed, which the
    chip and the view then show; the GAN, without seeds, offers no gallery."""
    width, height = size
    page = probe.open_studio(browser, studio.url, width=width, height=height)
    try:
        probe.wait_state(page, "s.get('model_name') === 'diffusion' && s.get('seeded') && !s.get('computing')", 60000)
        probe.wait_for_view_at_rest(page)
        first, before = probe.state(page, "seed"), probe.view_pixels(page)  # the view before the dialog covers it
        page.locator("#open-gallery").click()
        probe.wait_state(page, "s.get('gallery_items').length === 8 && s.get('gallery_items').every(i => i.src)", 60000)
        items = probe.state(page, "gallery_items")
        assert [i["seed"] for i in items] == list(range(first, first + 8))
        assert all(i["caption"].startswith(f"seed {i['seed']}") for i in items), [i["caption"] for i in items]
        assert len({i["src"] for i in items}) == 8  # eight different reactions
        page.wait_for_function("() => { const im = [...document.querySelectorAll('.gallery-item img')]; "
                               "return im.length === 8 && im.every(i => i.complete && i.naturalWidth > 100); }", timeout=30000)
        boxes = [page.locator(".gallery-item").nth(k).bounding_box() for k in range(8)]
        assert all(b["x"] >= 0 and b["y"] >= 0 and b["x"] + b["width"] <= width and b["y"] + b["height"] <= height
                   for b in boxes), boxes  # all on screen, none scrolled away
        probe.shot(page, f"studio-gallery-{width}x{height}")

        n = probe.state(page, "mix_count")
        third = items[2]["seed"]
        page.locator(".gallery-item").nth(2).click()
        probe.wait_state(page, f"String(s.get('seed')) === '{third}' && s.get('mix_count') > {n} && !s.get('computing') "
                               "&& !s.get('gallery_open')", 60000)
        page.wait_for_function(f"() => document.querySelector('#model-chip').textContent.includes('seed {third}')",
                               timeout=10000)
        probe.wait_for_view_at_rest(page)
        changed = np.abs(probe.view_pixels(page).astype(int) - before).max(-1) > 60
        assert int(changed.sum()) > 100, "the view does not show another follower"

        page.locator("#model-gan").click()
        probe.wait_state(page, "s.get('model_name') === 'gan' && !s.get('computing')", 60000)
        assert page.locator("#open-gallery").count() == 0
    finally:
        page.close()
