"""The studio in headless Chromium: the page, the 3D picture, mixing, the latent map, playback and
five independent clients. Needs /usr/bin/chromium (Debian package); never downloads a browser."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest

from imm_model.paths import REPO_ROOT, SAMPLE_CHECKPOINT
from tests.relays import PrefixProxy, TcpRelay

pytestmark = [
    pytest.mark.browser,
    pytest.mark.timeout(240),
    pytest.mark.skipif(not os.path.exists("/usr/bin/chromium"), reason="needs /usr/bin/chromium (apt-get install -y chromium)"),
    pytest.mark.skipif(not SAMPLE_CHECKPOINT.exists(), reason=f"bundled checkpoint missing: {SAMPLE_CHECKPOINT}"),
]
sync_api = pytest.importorskip("playwright.sync_api")
probe = pytest.importorskip("tests.studio_probe")
ARTIFACTS = REPO_ROOT / "test-artifacts"


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    # closed tabs keep their process for a minute (--idle-exit): room for the tabs earlier tests opened and closed
    with probe.StudioProcess("--max-clients", "12", cache_dir=tmp_path_factory.mktemp("studio-cache")) as s:
        yield s


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        b = probe.launch_chromium(p)
        yield b
        b.close()


@pytest.fixture(scope="module")
def page(studio, browser):
    pg = probe.open_studio(browser, studio.url)
    probe.watch_view_images(pg)
    yield pg
    pg.close()


def shot(page, name: str) -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path))
    return path


def colors(page) -> list[int]:
    from explorer.palette import GROUND_TRUTH, LEADER, SYNTHESIZED

    return probe.count_colors(probe.view_pixels(page), [LEADER, GROUND_TRUTH, SYNTHESIZED])


def test_page_shows_three_skeletons(page):
    shot(page, "studio-loaded")
    leader, gt, synth = colors(page)
    assert min(leader, gt, synth) > 300, (leader, gt, synth)
    assert page.title() == "IMM Studio"
    assert probe.state(page, "label_text")  # the label in words


def test_class_slider_changes_follower(page):
    from explorer.palette import SYNTHESIZED
    from tests.studio_probe import color_mask

    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    other = (own + 1) % len(names)
    before_px = color_mask(probe.view_pixels(page), SYNTHESIZED)
    n_img, n_mix = probe.images_seen(page), probe.state(page, "mix_count")
    probe.press_slider(page, f".slider-{names[other].replace(' ', '_')}", "End")
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=10000)
    probe.wait_for_new_image(page, n_img)
    time.sleep(0.3)
    assert probe.state(page, f"w_{other}") == 1.0
    assert names[other] in probe.state(page, "label_text")
    reads = probe.state(page, "reads_as")  # the 'reads as' panel follows the mix
    assert len(reads) == len(names) and reads[other]["asked"] == "+" and sum(r["p"] for r in reads) == pytest.approx(1, abs=0.01)
    assert page.locator("#reads-as .reads-as-row").count() == len(names)
    after_px = color_mask(probe.view_pixels(page), SYNTHESIZED)
    changed = int((before_px ^ after_px).sum())
    shot(page, "studio-mixed")
    assert changed > 100, f"only {changed} green pixels changed"
    page.click("#match-label")
    page.wait_for_function(f"() => window.trame.state.get('w_{other}') === 0", timeout=10000)


def test_latent_click_switches_sequence(page):
    current = probe.state(page, "sequence_index")
    points = page.locator("#latent-plot .imm-pt")
    assert points.count() > 10
    ring = page.locator("#latent-ring").bounding_box()  # the current sequence is ringed on the map
    mine = page.locator(f'#latent-plot .imm-pt[data-index="{current}"]').bounding_box()
    assert abs(ring["x"] + ring["width"] / 2 - (mine["x"] + mine["width"] / 2)) < 2
    target = int(points.nth(7).get_attribute("data-index"))
    if target == current:
        target = int(points.nth(8).get_attribute("data-index"))
    point = page.locator(f'#latent-plot .imm-pt[data-index="{target}"]')
    point.hover()
    point.click()
    page.wait_for_function(f"() => window.trame.state.get('sequence_index') !== {current}", timeout=10000)
    assert probe.state(page, "sequence_index") == target
    assert probe.state(page, "frame") == 0
    shot(page, "studio-picked")


def test_distance_chart_click_seeks_and_cursor_follows(page):
    """A click on the per-frame chart moves to that frame; the dotted cursor is drawn there."""
    n = probe.state(page, "num_frames")
    box = page.locator("#distance-seek").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.75, box["y"] + box["height"] / 2)
    want = round((n - 1) * 0.75)
    page.wait_for_function(f"() => Math.abs(window.trame.state.get('frame') - {want}) <= 1", timeout=10000)
    cursor = page.locator("#distance-seek .imm-cursor").bounding_box()
    assert abs(cursor["x"] - (box["x"] + box["width"] * 0.75)) < box["width"] / max(1, n - 1) + 2


def test_umap_fits_while_the_page_keeps_working(page):
    """The first UMAP fit runs in a separate process: the map says so, a slider still re-synthesizes meanwhile,
    then the UMAP map replaces the t-SNE one."""
    page.locator("#umap-button").click()
    _wait_state(page, "s.get('projection_busy') === true")
    assert page.locator("#latent-busy").is_visible()
    n = probe.state(page, "mix_count")
    probe.set_state(page, "w_1", 0.5 if probe.state(page, "w_1") != 0.5 else -0.5)
    _wait_state(page, f"s.get('mix_count') > {n}")
    assert probe.state(page, "projection_busy")  # the page answered while the fit ran (importing numba alone takes longer)
    _wait_state(page, "s.get('projection_busy') === false && s.get('latent_chart').includes('UMAP')", timeout_ms=240000)
    assert page.locator("#latent-plot .imm-pt").count() > 10 and page.locator("#latent-busy").count() == 0
    page.get_by_role("button", name="t-SNE").click()
    _wait_state(page, "s.get('latent_chart').includes('t-SNE')")


def test_dragging_the_view_turns_the_camera_and_keys_stay_out_of_vtk(page):
    """A drag on the 3D view reaches the server's interactor (a new picture from another angle); keys pressed with the
    view focused do not (VTK's default 'w' would draw wireframes, 'r' would reset the camera)."""
    probe.watch_view_images(page)
    box = page.locator(probe.VIEW_IMG).bounding_box()
    before = probe.view_pixels(page)
    n = probe.images_seen(page)
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    for step in range(1, 9):
        page.mouse.move(x + 25 * step, y + 4 * step)
    page.mouse.up()
    probe.wait_for_new_image(page, n)
    time.sleep(0.6)  # the sharper still picture that follows an interaction
    turned = probe.view_pixels(page)
    assert (np.abs(turned.astype(int) - before.astype(int)).max(-1) > 40).sum() > 500
    n = probe.images_seen(page)
    page.keyboard.press("w")
    page.keyboard.press("3")
    time.sleep(0.6)
    assert probe.images_seen(page) == n  # no render was asked for
    page.locator("#camera-default").click()  # back to the preset, for the tests after this one
    probe.wait_for_new_image(page, n)


def test_play_advances_frames(page):
    page.click("#play-button")
    try:
        page.wait_for_function("() => window.trame.state.get('frame') >= 4", timeout=15000)
    finally:
        page.click("#play-button")
    page.wait_for_function("() => window.trame.state.get('playing') === false", timeout=5000)


def test_export_bvh_downloads_a_file_that_reimports(page, tmp_path):
    from imm_model.data.bvh import read_bvh

    page.get_by_role("button", name="Export").click()
    with page.expect_download(timeout=20000) as download:
        page.locator(".export-bvh-follower").click()
    path = tmp_path / "follower.bvh"
    download.value.save_as(path)
    motion = read_bvh(path)
    assert motion.shape[1:] == (15, 3) and len(motion) == probe.state(page, "num_frames")


def test_upload_a_bvh_leader_then_a_broken_file(page, tmp_path, sample_data):
    """A real-format BVH leader joins the view without ground truth and exports as BVH; a broken file gets its
    one-line reason in the page, and the page keeps working."""
    from imm_model.data.bvh import read_bvh, write_bvh

    leader = tmp_path / "my_leader.bvh"
    write_bvh(leader, sample_data.world(12)[0])
    n_mix = probe.state(page, "mix_count")
    page.locator("input[type=file]").set_input_files(str(leader))
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=20000)
    page.wait_for_selector("#uploaded-chip", timeout=10000)
    assert "my_leader.bvh" in probe.state(page, "sequence_title") and "no ground truth" in probe.state(page, "afd_text")
    assert probe.state(page, "num_frames") == len(sample_data.canonical(12)[0])
    time.sleep(0.5)
    shot(page, "studio-uploaded")
    page.get_by_role("button", name="Export").click()
    with page.expect_download(timeout=20000) as download:
        page.locator(".export-bvh-follower").click()
    download.value.save_as(tmp_path / "f.bvh")
    assert read_bvh(tmp_path / "f.bvh").shape == (probe.state(page, "num_frames"), 15, 3)

    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0\n")
    page.locator("input[type=file]").set_input_files(str(broken))
    page.wait_for_function("() => (window.trame.state.get('error') || '').includes('broken.bvh')", timeout=20000)
    assert "\n" not in probe.state(page, "error")
    assert "my_leader.bvh" in probe.state(page, "sequence_title")  # what the user had stays
    names = probe.state(page, "class_names")
    n_mix = probe.state(page, "mix_count")
    probe.press_slider(page, f".slider-{names[1].replace(' ', '_')}", "End")
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=10000)


def _press(page, key: str) -> None:
    page.bring_to_front()
    page.evaluate("() => document.activeElement && document.activeElement.blur()")  # keys typed on the page, not a slider
    page.keyboard.press(key)


def _wait_state(page, expression: str, timeout_ms: int = 15000) -> None:
    page.wait_for_function(f"() => {{ const s = window.trame.state; return {expression}; }}", timeout=timeout_ms)


def _load_sequence(page, index: int) -> None:
    """Pick a sequence as the page does and wait for the server's answer (the page's own sequence_index changes at
    once; the label and the review follow from the server)."""
    n = probe.state(page, "mix_count")
    probe.set_state(page, "sequence_index", index)
    _wait_state(page, f"s.get('mix_count') > {n} && s.get('sequence_uploaded') === false")


def test_keyboard_drives_frames_playback_and_sliders(page):
    _load_sequence(page, 1)  # a dataset sequence (an uploaded leader has no class to match)
    _press(page, "Home")
    _wait_state(page, "s.get('frame') === 0")
    _press(page, "ArrowRight")
    _press(page, "ArrowRight")
    _wait_state(page, "s.get('frame') === 2")
    _press(page, "End")
    _wait_state(page, "s.get('frame') === s.get('num_frames') - 1")
    _press(page, "3")
    _wait_state(page, "s.get('key_slider') === 2")
    before = probe.state(page, "w_2")
    _press(page, "ArrowUp")
    _wait_state(page, f"Math.abs(s.get('w_2') - {min(1.0, before + 0.1)}) < 1e-6")
    _press(page, "m")
    _wait_state(page, "s.get('w_2') === 0 || s.get('w_2') === 1")
    _press(page, "?")
    page.wait_for_selector("#keys-card", state="visible", timeout=5000)
    page.keyboard.press("Escape")
    page.wait_for_selector("#keys-card", state="hidden", timeout=5000)
    _press(page, " ")
    _wait_state(page, "s.get('playing') === true")
    _press(page, " ")
    _wait_state(page, "s.get('playing') === false")


def test_a_link_reopens_the_same_picture(studio, browser, page):
    """The address bar follows the view; the copied link, opened in a new tab (a new studio process), shows the
    same sequence, mix, frame, layout and camera: the two pictures match."""
    _press(page, " ") if probe.state(page, "playing") else None
    probe.set_state(page, "w_3", 0.5)
    probe.set_state(page, "scene_layout", "side_by_side")
    page.get_by_role("button", name="top").click()
    probe.set_state(page, "frame", 7)
    _wait_state(page, "s.get('url_query').includes('frame=7') && s.get('url_query').includes('camera=top')")
    _wait_state(page, "s.get('url_query').includes('layout=side_by_side') && s.get('url_query').includes(':0.5')")
    assert "frame=7" in page.url  # the address bar itself
    page.locator("#copy-link").click()
    _wait_state(page, "!!s.get('share_link')")
    link = probe.state(page, "share_link")
    assert link.startswith(studio.url) and "/s/" not in link, link
    page.keyboard.press("Escape")  # close the link's card, which covers a corner of the view
    query = probe.state(page, "url_query")
    other = probe.open_studio(browser, link, timeout_ms=90000)
    try:
        _wait_state(other, f"s.get('url_query') === {query!r}", timeout_ms=30000)
        time.sleep(1.0)  # the last picture of both views
        a, b = probe.view_pixels(page).astype(float), probe.view_pixels(other).astype(float)
        shot(page, "studio-link-sender")
        shot(other, "studio-link-receiver")
        assert a.shape == b.shape
        assert np.abs(a - b).mean() < 2.0, np.abs(a - b).mean()
    finally:
        other.close()
    probe.set_state(page, "scene_layout", "overlay")
    page.get_by_role("button", name="reset").first.click()


def test_a_bad_link_names_what_it_ignored(browser, studio):
    other = probe.open_studio(browser, studio.url + "?seq=nope&scale=7&layout=overlay", timeout_ms=90000)
    try:
        _wait_state(other, "s.get('error').startsWith('link:')")
        error = probe.state(other, "error")
        assert "no sequence 'nope'" in error and "scale '7' is outside" in error
    finally:
        other.close()


def test_screenshot_downloads_the_view_as_png(page, tmp_path):
    from PIL import Image

    with page.expect_download(timeout=20000) as download:
        page.locator("#screenshot").click()
    path = tmp_path / "view.png"
    download.value.save_as(path)
    with Image.open(path) as im:
        assert im.format == "PNG" and min(im.size) > 100


def test_pin_a_mix_then_compare_swap_and_clear(page):
    """A/B: the pinned mix shows as a purple figure with its own line on the distance chart; swap puts it back on
    the sliders; clear removes it."""
    from explorer.palette import PINNED

    _load_sequence(page, 2)
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    other = (own + 3) % len(names)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] < 50
    page.locator("#pin-mix").click()
    _wait_state(page, "!!s.get('pinned_text')")
    probe.set_state(page, f"w_{other}", 1.0)
    pinned_line = "s.get('distance_chart').includes('data-series=\"pinned\"')"
    _wait_state(page, f"s.get('ab_text').includes('mean') && {pinned_line}")
    time.sleep(0.5)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] > 300
    page.locator("#swap-mix").click()  # the pinned mix (own class only) back on the sliders
    _wait_state(page, f"s.get('w_{other}') === 0 && s.get('w_{own}') === 1")
    assert probe.state(page, "pinned_text") != "" and "+1" in probe.state(page, "pinned_text")
    page.locator("#clear-pin").click()
    _wait_state(page, f"s.get('pinned_text') === '' && !{pinned_line}")
    time.sleep(0.5)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] < 50


def test_interpenetrating_limbs_are_marked(page):
    """A sequence whose synthesized hug goes into the leader: the count in words, shaded frames on the chart, and
    orange limbs in the view at such a frame."""
    from explorer.palette import WARNING

    probe.set_state(page, "scene_layout", "overlay")
    _load_sequence(page, 5)
    _wait_state(page, "s.get('contact_text').includes('interpenetrate in')")
    assert page.locator("#distance-chart rect.penetration").count() >= 1
    probe.set_state(page, "frame", 15)
    _wait_state(page, "s.get('frame') === 15")
    time.sleep(0.8)
    assert probe.count_colors(probe.view_pixels(page), [WARNING])[0] > 100
    shot(page, "studio-contact")


def test_single_port_through_a_forwarded_port(studio, browser, tmp_path):
    """A browser that can reach only one forwarded port (as through `ssh -L 8080:127.0.0.1:8080 host`): the page
    loads, a slider re-synthesizes, an export downloads."""
    from urllib.parse import urlsplit

    relay = TcpRelay(urlsplit(studio.url).port)
    try:
        pg = probe.open_studio(browser, f"http://127.0.0.1:{relay.port}/", timeout_ms=90000)
        assert pg.url.startswith(f"http://127.0.0.1:{relay.port}/s/")
        names = probe.state(pg, "class_names")
        n_mix = probe.state(pg, "mix_count")
        probe.press_slider(pg, f".slider-{names[2].replace(' ', '_')}", "End")
        pg.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=15000)
        pg.get_by_role("button", name="Export").click()
        with pg.expect_download(timeout=20000) as download:
            pg.locator(".export-bvh-follower").click()
        download.value.save_as(tmp_path / "f.bvh")
        assert (tmp_path / "f.bvh").read_text().startswith("HIERARCHY")
        pg.close()
    finally:
        relay.close()


def test_behind_a_reverse_proxy_with_a_path_prefix(browser, tmp_path):
    """--base-url: the printed address is the proxy's; through /imm/ the page loads and a slider re-synthesizes."""
    from urllib.parse import urlsplit

    proxy = PrefixProxy()
    base = f"http://127.0.0.1:{proxy.port}/imm/"
    try:
        with probe.StudioProcess("--base-url", base, cache_dir=tmp_path) as studio:
            assert studio.url == base
            served = [ln for ln in studio.lines if "served from" in ln][0]
            proxy.target = urlsplit(served.split("served from ")[1].split()[0]).port
            pg = probe.open_studio(browser, base, timeout_ms=90000)
            assert pg.url.startswith(base + "s/"), pg.url
            names = probe.state(pg, "class_names")
            n_mix = probe.state(pg, "mix_count")
            probe.press_slider(pg, f".slider-{names[2].replace(' ', '_')}", "End")
            pg.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=15000)
            pg.close()
    finally:
        proxy.close()


def test_five_clients_are_independent(studio, browser):
    pages = []
    try:
        for _ in range(5):
            pg = probe.open_studio(browser, studio.url, width=1200, height=800, timeout_ms=90000)
            probe.watch_view_images(pg)
            pages.append(pg)
        sessions = {pg.url.split("/s/")[1].split("/")[0] for pg in pages}
        assert len(sessions) == 5, "each client must get its own studio process"
        assert all(pg.url.startswith(studio.url) for pg in pages)  # all through the launcher's one port
        texts = [probe.state(pg, "label_text") for pg in pages]
        # Client 0 mixes in a class; the others must not move.
        names = probe.state(pages[0], "class_names")
        own = [i for i in range(len(names)) if probe.state(pages[0], f"w_{i}") == 1.0][0]
        other = (own + 2) % len(names)
        n_mix = probe.state(pages[0], "mix_count")
        probe.press_slider(pages[0], f".slider-{names[other].replace(' ', '_')}", "End")
        pages[0].wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=10000)
        time.sleep(0.5)
        assert probe.state(pages[0], "label_text") != texts[0]
        for pg, text in zip(pages[1:], texts[1:], strict=True):
            assert probe.state(pg, "label_text") == text
            assert probe.state(pg, f"w_{other}") == 0
        # Every client still answers a slider promptly while the others are open.
        delays = []
        for pg in pages:
            n_img = probe.images_seen(pg)
            t0 = time.monotonic()
            probe.press_slider(pg, f".slider-{names[(own + 3) % len(names)].replace(' ', '_')}", "ArrowRight")
            try:
                probe.wait_for_new_image(pg, n_img, timeout_ms=10000)
            except Exception:
                print("no picture", probe.state(pg, "label_text"), probe.state(pg, "mix_count"), probe.images_seen(pg), n_img)
                raise
            delays.append(time.monotonic() - t0)
        pages[-1].screenshot(path=str(ARTIFACTS / "studio-client5.png"))
        assert max(delays) < 3.0, f"slider -> picture per client: {np.round(delays, 2)} s"
    finally:
        for pg in pages:
            pg.close()
