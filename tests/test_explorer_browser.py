"""The studio in headless Chromium, one tab: the page, the 3D picture, mixing, the latent map, the charts, playback,
keys, export, upload, A/B and contact (fixtures in tests/conftest.py; serving, links and several tabs in
test_explorer_serving.py). Needs /usr/bin/chromium (Debian package); never downloads a browser."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests import studio_probe as probe

pytestmark = [pytest.mark.browser, pytest.mark.timeout(240)]


def colors(page) -> list[int]:
    from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED

    return probe.count_colors(probe.view_pixels(page), [LEADER, GROUND_TRUTH, SYNTHESIZED])


def test_page_shows_three_skeletons(page):
    probe.shot(page, "studio-loaded")
    leader, gt, synth = colors(page)
    assert min(leader, gt, synth) > 300, (leader, gt, synth)
    assert page.title() == "IMM Studio"
    assert probe.state(page, "label_text")  # the label in words


def test_the_page_hands_wslink_websocket_bytes(page):
    """explorer/serving/page_shell.py: the page's websocket is the shell's, which delivers binary messages as bytes."""
    assert page.evaluate("() => window.WebSocket.name") == "BytesWebSocket"


def test_sliders_and_reads_as_bars_do_not_glide(page):
    """A key or click moves a slider's thumb at once (Vuetify would animate it for 0.3 s, repainting while the
    server makes the picture), and the 'reads as' bars change without an animation."""
    durations = page.evaluate("""() => ['.v-slider-thumb', '.v-slider-track__fill', '.reads-as-bar .v-progress-linear__determinate']
        .flatMap(sel => [...document.querySelectorAll(sel)].map(el => getComputedStyle(el).transitionDuration))""")
    assert len(durations) >= 2 * 8 + 6, durations  # thumbs and fills of 6 class sliders, scale and frame; 6 bars
    assert {d for ds in durations for d in ds.replace(" ", "").split(",")} == {"0s"}, durations


# Counts the renders of the component whose own render makes the element with this id (Vue's components reached from
# the app's root vnode; a slot's contents belong to the component that renders the slot): window.__immRenders.
COUNT_RENDERS_JS = """(id) => {
  const owns = (vnode) => {  // the element in this subtree, not inside a child component
    if (!vnode) return false;
    if (vnode.props && vnode.props.id === id) return true;
    return !vnode.component && Array.isArray(vnode.children) && vnode.children.some(owns);
  };
  const components = [];
  const walk = (vnode) => {
    if (!vnode) return;
    if (vnode.component) { components.push(vnode.component); walk(vnode.component.subTree); return; }
    if (Array.isArray(vnode.children)) vnode.children.forEach(walk);
  };
  walk(document.querySelector('#app')._vnode);
  const owner = components.find((c) => owns(c.subTree));
  window.__immRenders = 0;
  const render = owner.render;
  owner.render = function (...args) { window.__immRenders += 1; return render.apply(this, args); };
  return owner.type.name;
}"""


def test_a_slider_move_re_renders_the_slider_and_what_it_changed_not_the_drawer(page):
    """A class slider's new value, and what the server sends back with the follower (the label in words, the reads-as
    panel, the contact ticks, the map's marks, the URL), re-render parts of their own (layout.py `rendered_apart`),
    not the drawer around them: on 2 cores the drawer's re-render held each move's state back ~10 ms
    (docs/experiments/studio-performance.md). The counter itself counts: a key the drawer reads re-renders it."""
    assert page.evaluate(COUNT_RENDERS_JS, "match-label") == "VNavigationDrawer"
    renders = "() => new Promise((r) => requestAnimationFrame(() => setTimeout(() => r(window.__immRenders), 0)))"
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    other = (own + 1) % len(names)
    before = probe.state(page, "label_text")
    probe.set_state(page, f"w_{other}", 1.0)  # the server draws the mix and sends back what changed with it
    probe.wait_state(page, f"s.get('label_text') !== {before!r}")
    probe.wait_for_view_at_rest(page)
    assert page.evaluate(renders) == 0
    probe.set_state(page, "key_slider", other)  # the drawer underlines the class a key selects
    assert page.evaluate(renders) >= 1
    probe.set_state(page, f"w_{other}", 0.0)
    probe.set_state(page, "key_slider", own)


def test_a_label_changes_first_picture_is_a_stretched_draft_then_full_size(page):
    """explorer/rendering/view_stream.py: the picture right after a slider move is rendered at half the view's width and
    height and shown stretched over the whole view; the still picture that follows is full size. The map drawn first:
    while the page evaluates plotly.js it reports no picture shown, and the still replaces the draft held back (the
    latest picture wins, view_stream.PictureGate), as a page busy for 0.6 s after a move showed."""
    probe.wait_for_latent_points(page, 60000)
    page.evaluate(f"""() => {{ window.__sizes = []; const i = document.querySelector('{probe.VIEW_IMG}');
        i.addEventListener('load', () => window.__sizes.push([i.naturalWidth, i.clientWidth, i.clientHeight])); }}""")
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    probe.press_slider(page, f".slider-{names[(own + 2) % len(names)].replace(' ', '_')}", "End")
    # the first picture smaller than the view, then a full one (an earlier still may land first)
    page.wait_for_function("""() => { const s = window.__sizes, k = s.findIndex(([n, w]) => n < w);
        return k >= 0 && s.slice(k + 1).some(([n, w]) => n === w); }""", timeout=10000)
    sizes = page.evaluate("() => window.__sizes")
    k = next(i for i, (n, w, _) in enumerate(sizes) if n < w)
    (draft, shown_w, shown_h), (full, still_w, still_h) = sizes[k], sizes[k + 1]
    assert abs(draft - full / 2) <= 1 and shown_w == still_w == full and abs(shown_h - still_h) <= 1, sizes


def test_class_slider_changes_follower(page):
    from explorer.rendering.palette import SYNTHESIZED
    from tests.studio_probe import color_mask

    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    other = (own + 1) % len(names)
    before_px = color_mask(probe.view_pixels(page), SYNTHESIZED)
    n_img, n_mix = probe.images_seen(page), probe.state(page, "mix_count")
    probe.press_slider(page, f".slider-{names[other].replace(' ', '_')}", "End")
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=10000)
    probe.wait_for_new_image(page, n_img)
    probe.wait_for_view_at_rest(page)  # the still picture, and the 'reads as' panel after it
    probe.wait_state(page, f"s.get('reads_as')[{other}].asked === '+'")
    assert probe.state(page, f"w_{other}") == 1.0
    assert names[other] in probe.state(page, "label_text")
    reads = probe.state(page, "reads_as")  # the 'reads as' panel follows the mix
    assert len(reads) == len(names) and reads[other]["asked"] == "+" and sum(r["p"] for r in reads) == pytest.approx(1, abs=0.01)
    assert page.locator("#reads-as .reads-as-row").count() == len(names)
    row = page.locator("#reads-as .reads-as-row").nth(other).inner_text()  # the ask marks the name, not the share
    assert row.startswith(f"+ {names[other]}") and row.rstrip().endswith("%") and "+ " not in row.split("\n")[-1], row
    after_px = color_mask(probe.view_pixels(page), SYNTHESIZED)
    changed = int((before_px ^ after_px).sum())
    probe.shot(page, "studio-mixed")
    assert changed > 100, f"only {changed} green pixels changed"
    page.click("#match-label")
    page.wait_for_function(f"() => window.trame.state.get('w_{other}') === 0", timeout=10000)


def test_a_mix_that_does_not_read_is_named_under_the_bars(page):
    """Kicking + hugging, a pair that fails the mix target: the bundled model gives the hug (on s04's 49 held-out
    leaders the studio's classifier reads kicking at 0.04 on average, and both members at 0.25 or more for none), and
    the panel says so in words."""
    from imm_model.reads_as import MIX_SHARE

    names = probe.state(page, "class_names")
    kick, hug = names.index("kicking"), names.index("hugging")
    page.click("#reset-label")
    probe.wait_state(page, f"{list(range(len(names)))}.every((i) => s.get('w_' + i) === 0)")
    probe.set_state(page, f"w_{kick}", 1.0)
    probe.set_state(page, f"w_{hug}", 1.0)
    asked = "s.get('reads_as').map((r) => r.asked).join(',')"  # the panel updates a moment after the picture
    probe.wait_state(page, f"{asked} === {','.join('+' if i in (kick, hug) else '' for i in range(len(names)))!r}")
    reads = probe.state(page, "reads_as")
    assert reads[kick]["p"] < MIX_SHARE <= reads[hug]["p"], reads
    note = page.locator("#reads-as-note")
    note.wait_for(state="visible", timeout=10000)
    assert "kicking" in note.inner_text() and "hugging" not in note.inner_text()
    probe.shot(page, "studio-mix-not-read")
    page.click("#match-label")
    probe.wait_state(page, "!s.get('reads_as_note')")


# Where map points are on the page: Plotly's own axes turn data coordinates into pixels.
POINT_PIXELS_JS = """() => { const el = document.getElementById('latent-plotly'), fl = el._fullLayout, r = el.getBoundingClientRect();
    const p = window.trame.state.get('latent_points');
    return p.x.map((x, i) => [r.left + fl.xaxis._offset + fl.xaxis.l2p(x), r.top + fl.yaxis._offset + fl.yaxis.l2p(p.y[i])]); }"""


def wait_for_map(page, afd: bool = False) -> None:
    probe.wait_for_latent_points(page, 30000)
    if afd:  # the per-sequence AFDs are computed once, a moment after the first page opened
        probe.wait_state(page, "s.get('latent_points') && !!s.get('latent_points').afd", timeout_ms=60000)
        page.wait_for_function("() => document.querySelector('#latent-plotly').data.some((t) => t.customdata &&"
                               " t.customdata.length && t.customdata[0][5] !== '(computing)')", timeout=10000)


def test_latent_map_is_a_plotly_figure_and_a_click_loads_and_plays(page):
    """Hover a point for its readout; a click opens that sequence and plays it; the current sequence is ringed."""
    wait_for_map(page, afd=True)
    current = probe.state(page, "sequence_index")
    points = np.array(page.evaluate(POINT_PIXELS_JS))
    ring = page.evaluate("() => { const el = document.getElementById('latent-plotly');"
                         " return el.data.find((t) => t.meta === 'ring').x[0]; }")
    assert ring == pytest.approx(probe.state(page, "latent_points")["x"][current], abs=1e-3)
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1) + np.eye(len(points)) * 1e9
    gaps[current, :] = 0  # never the current sequence; a point beside it has little room by its distance to it
    target = int(np.argmax(gaps.min(1)))  # the point with the most room around it
    x, y = points[target]
    page.mouse.move(x, y)
    readout = page.locator("#latent-plotly .hoverlayer .hovertext")
    readout.wait_for(timeout=5000)
    text = readout.text_content()
    p = probe.state(page, "latent_points")
    assert p["id"][target] in text and p["class_names"][p["cls"][target]] in text and p["pair"][target] in text
    assert ("held out" if p["held"][target] else "seen in training") in text and f"AFD {p['afd'][target]:.3f}" in text
    page.mouse.click(x, y)
    probe.wait_state(page, f"s.get('sequence_index') === {target} && s.get('playing') === true")
    probe.wait_state(page, "s.get('frame') >= 2")  # it plays
    page.click("#play-button")
    probe.wait_state(page, "s.get('playing') === false")
    probe.shot(page, "studio-picked")


def test_box_selection_lists_the_sequences_and_a_row_opens_one(page):
    wait_for_map(page, afd=True)
    plot = page.locator("#latent-plotly .nsewdrag").first.bounding_box()
    page.mouse.move(plot["x"] + plot["width"] / 2, plot["y"] + plot["height"] / 2)  # the figure's tool bar shows on hover
    page.locator('#latent-plotly .modebar-btn[data-val="select"]').click()
    x0, x1 = plot["x"] + plot["width"] * 0.2, plot["x"] + plot["width"] * 0.8
    y0, y1 = plot["y"] + plot["height"] * 0.2, plot["y"] + plot["height"] * 0.8
    points = np.array(page.evaluate(POINT_PIXELS_JS))

    def within(margin):
        x_in = (points[:, 0] > x0 - margin) & (points[:, 0] < x1 + margin)
        return {int(i) for i in np.flatnonzero(x_in & (points[:, 1] > y0 - margin) & (points[:, 1] < y1 + margin))}

    assert len(within(-2)) > 5
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(x0 + (x1 - x0) * k / 10, y0 + (y1 - y0) * k / 10)
    page.mouse.up()
    probe.wait_state(page, "s.get('latent_rows').length > 0")
    selected = set(probe.state(page, "latent_selection"))
    assert within(-2) <= selected <= within(2), (sorted(within(-2) ^ selected), sorted(selected ^ within(2)))
    rows = probe.state(page, "latent_rows")
    assert sorted(r["i"] for r in rows) == sorted(selected)
    assert [r["afd"] for r in rows] == sorted((r["afd"] for r in rows), reverse=True)  # the worst first
    assert page.locator("#latent-selection .latent-row").count() == len(selected)
    probe.shot(page, "studio-map-selection")
    pick = rows[1]["i"] if rows[0]["i"] == probe.state(page, "sequence_index") else rows[0]["i"]
    page.locator("#latent-selection .latent-row").nth([r["i"] for r in rows].index(pick)).click()
    probe.wait_state(page, f"s.get('sequence_index') === {pick}")
    probe.wait_state(page, "s.get('playing') === true")  # a row plays its sequence, as a point click does
    probe.set_state(page, "playing", False)
    page.locator('#latent-plotly .modebar-btn[data-val="zoom"]').click()
    probe.set_state(page, "latent_selection", [])
    probe.wait_state(page, "s.get('latent_rows').length === 0")


def test_the_map_colours_by_afd_and_the_star_follows_the_sliders(page):
    wait_for_map(page, afd=True)
    page.locator("#latent-color-afd").click()
    page.wait_for_selector("#latent-plotly .colorbar", timeout=10000)
    page.locator("#latent-color").get_by_role("button", name="class").click()
    page.wait_for_function("() => document.querySelector('#latent-plotly').dataset.mode === 'class'", timeout=10000)
    assert page.locator("#latent-plotly .colorbar").count() == 0
    star_js = "() => { const t = document.getElementById('latent-plotly').data.find((t) => t.meta === 'star'); return [t.x[0], t.y[0]]; }"
    before = page.evaluate(star_js)
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    probe.set_state(page, f"w_{own}", -1.0)  # the opposite of its own class: the mix's latent moves
    page.wait_for_function(f"(b) => {{ const a = ({star_js})(); return a[0] !== b[0] || a[1] !== b[1]; }}", arg=before, timeout=10000)
    assert page.evaluate(star_js) == pytest.approx(probe.state(page, "latent_marks")["star"], abs=1e-6)
    page.click("#match-label")
    probe.wait_state(page, f"s.get('w_{own}') === 1")


def test_distance_chart_click_seeks_and_cursor_follows(page):
    """A click on the per-frame chart moves to that frame; the dotted cursor is drawn there."""
    n = probe.state(page, "num_frames")
    box = page.locator("#distance-seek").bounding_box()
    page.mouse.click(box["x"] + box["width"] * 0.75, box["y"] + box["height"] / 2)
    want = round((n - 1) * 0.75)
    page.wait_for_function(f"() => Math.abs(window.trame.state.get('frame') - {want}) <= 1", timeout=10000)
    cursor = page.locator("#distance-seek .imm-cursor").bounding_box()
    assert abs(cursor["x"] - (box["x"] + box["width"] * 0.75)) < box["width"] / max(1, n - 1) + 2


@pytest.mark.slow
def test_umap_fits_while_the_page_keeps_working(page):
    """The first UMAP fit runs in a separate process: the map says so, a slider still re-synthesizes meanwhile,
    then the UMAP map replaces the t-SNE one."""
    page.locator("#umap-button").click()
    probe.wait_state(page, "s.get('projection_busy') === true")
    assert page.locator("#latent-busy").is_visible()
    n = probe.state(page, "mix_count")
    probe.set_state(page, "w_1", 0.5 if probe.state(page, "w_1") != 0.5 else -0.5)
    probe.wait_state(page, f"s.get('mix_count') > {n}")
    assert probe.state(page, "projection_busy")  # the page answered while the fit ran (importing numba alone takes longer)
    probe.wait_state(page, "s.get('projection_busy') === false && s.get('latent_points').method === 'umap'", timeout_ms=240000)
    page.wait_for_function("() => document.querySelector('#latent-plotly').dataset.method === 'umap'", timeout=10000)
    assert page.locator(probe.LATENT_POINTS).count() > 10 and page.locator("#latent-busy").count() == 0
    page.get_by_role("button", name="t-SNE").click()
    page.wait_for_function("() => document.querySelector('#latent-plotly').dataset.method === 'tsne'", timeout=10000)


def test_dragging_the_view_turns_the_camera_and_keys_stay_out_of_vtk(page):
    """A drag on the 3D view reaches the server's interactor (a new picture from another angle); keys pressed with the
    view focused do not (VTK's default 'w' would draw wireframes, 'r' would reset the camera)."""
    probe.watch_view_images(page)
    before = probe.view_pixels(page)
    n = probe.images_seen(page)
    probe.drag_view(page, 25, 4, steps=8)
    probe.wait_for_new_image(page, n)
    probe.wait_for_view_at_rest(page)  # the sharper still picture that follows an interaction
    turned = probe.view_pixels(page)
    assert (np.abs(turned.astype(int) - before.astype(int)).max(-1) > 40).sum() > 500
    n = probe.images_seen(page)
    page.keyboard.press("w")
    page.keyboard.press("3")
    time.sleep(0.6)  # no event to wait for: time in which a key that reached VTK would have asked for a picture
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


def test_playback_sends_a_picture_once_the_page_showed_the_one_before_drafts_while_playing_full_size_paused(page):
    """explorer/rendering/view_stream.py: while the page does not report a picture shown, the view holds the next
    (at most one a ACK_TIMEOUT_S); reported, it plays on; playing, its pictures are PLAYBACK_SCALE of the view's width
    (stretched over it), and once paused a full-size one follows."""
    from explorer.rendering.view_stream import ACK_TIMEOUT_S
    from explorer.ui.playback import PLAYBACK_SCALE

    # pictures reaching the page (trame-rca makes a blob URL for each); a switch that keeps the view's image loads
    # from the view's acknowledgement (a capture listener on the document runs before the view's own; an element's
    # load never reaches the window)
    page.evaluate(f"""() => {{ window.__pics = 0; window.__muted = false; window.__playSizes = [];
        if (!window.__picsOn) {{ window.__picsOn = true; const make = URL.createObjectURL;
            URL.createObjectURL = (b) => {{ if (b && String(b.type).startsWith('image/')) window.__pics++; return make(b); }};
            document.addEventListener('load', e => {{ if (window.__muted && e.target.tagName === 'IMG') e.stopPropagation(); }}, true); }}
        const i = document.querySelector('{probe.VIEW_IMG}');
        i.addEventListener('load', () => window.__playSizes.push([i.naturalWidth, i.clientWidth, window.trame.state.get('playing')]));
    }}""")
    probe.set_state(page, "loop", True)
    seconds = 2.0
    try:
        page.evaluate("() => { window.__muted = true; }")
        page.click("#play-button")
        probe.wait_state(page, "s.get('playing') === true")
        n0 = page.evaluate("() => window.__pics")
        time.sleep(seconds)
        muted = page.evaluate("() => window.__pics") - n0
        page.evaluate("() => { window.__muted = false; window.__playSizes = []; }")
        page.wait_for_function("(n) => window.__pics > n", arg=n0 + muted, timeout=60000)  # acknowledged: it plays on
        n1 = page.evaluate("() => window.__pics")
        time.sleep(seconds)
        acknowledged = page.evaluate("() => window.__pics") - n1
    finally:
        page.click("#play-button")
        probe.set_state(page, "loop", False)
    probe.wait_state(page, "s.get('playing') === false")
    page.wait_for_function("() => window.__playSizes.some(([n, w, playing]) => !playing && n === w)", timeout=10000)
    assert muted <= seconds / ACK_TIMEOUT_S + 2 < acknowledged, (muted, acknowledged)
    sizes = page.evaluate("() => window.__playSizes")
    playing = [(n, w) for n, w, p in sizes if p]
    assert len(playing) >= 5 and all(abs(n - round(w * PLAYBACK_SCALE)) <= 1 for n, w in playing), sizes


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
    shown = probe.state(page, "sequence_title").split(" · ")[0]
    assert shown in page.locator(".v-input:has(#sequence-picker)").inner_text() and page.locator(".legend-ground_truth").count() == 1
    page.locator("input[type=file]").set_input_files(str(leader))
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=20000)
    page.wait_for_selector("#uploaded-chip", timeout=10000)
    assert "my_leader.bvh" in probe.state(page, "sequence_title") and "no ground truth" in probe.state(page, "afd_text")
    assert "my_leader.bvh: reacting with the mix on the sliders" in probe.state(page, "notice")
    # neither the sequence menu nor the view's legend still names what was on screen before
    page.wait_for_selector(".legend-ground_truth", state="detached", timeout=5000)
    assert probe.state(page, "sequence_index") is None and shown not in page.locator(".v-input:has(#sequence-picker)").inner_text()
    assert probe.state(page, "num_frames") == len(sample_data.canonical(12)[0])
    probe.wait_for_view_at_rest(page)
    probe.shot(page, "studio-uploaded")
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


def test_a_long_takes_own_reaction_is_made_while_the_page_answers(page, tmp_path, sample_data):
    """A long uploaded leader: a slider draws the default's draft at once, and its own reaction (its teacher's, in
    windows: seconds) is made on a worker thread, the page answering a slider meanwhile and showing that it computes;
    then the view rests on it, with no error."""
    from imm_model.data.bvh import write_bvh

    leader = tmp_path / "long_take.bvh"
    write_bvh(leader, np.concatenate([sample_data.world(i)[0] for i in range(0, 60, 10)]))
    n = probe.state(page, "mix_count")
    page.locator("input[type=file]").set_input_files(str(leader))
    page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n, timeout=60000)
    assert probe.state(page, "num_frames") > 100  # beyond the longest training clip (46 frames): made in windows
    probe.wait_state(page, "!s.get('computing')", 120000)
    slider = f".slider-{probe.state(page, 'class_names')[1].replace(' ', '_')}"
    answered_while_computing = []
    for key in ("Home", "End") if probe.state(page, "w_1") > 0.5 else ("End", "Home"):  # each press moves it
        n = probe.state(page, "mix_count")
        probe.press_slider(page, slider, key)
        page.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n, timeout=60000)
        answered_while_computing.append(probe.state(page, "computing"))
    assert answered_while_computing[-1], answered_while_computing  # the second press came during the first's reaction
    probe.wait_state(page, "!s.get('computing')", 120000)
    probe.wait_for_view_at_rest(page)
    assert probe.state(page, "error") == ""


def _load_sequence(page, index: int) -> None:
    """Pick a sequence as the page does and wait for the server's answer (the page's own sequence_index changes at
    once; the label and the review follow from the server)."""
    n = probe.state(page, "mix_count")
    probe.set_state(page, "sequence_index", index)
    probe.wait_state(page, f"s.get('mix_count') > {n} && s.get('sequence_uploaded') === false")


def test_keyboard_drives_frames_playback_and_sliders(page):
    _load_sequence(page, 1)  # a dataset sequence (an uploaded leader has no class to match)
    probe.press_key(page, "Home")
    probe.wait_state(page, "s.get('frame') === 0")
    probe.press_key(page, "ArrowRight")
    probe.press_key(page, "ArrowRight")
    probe.wait_state(page, "s.get('frame') === 2")
    probe.press_key(page, "End")
    probe.wait_state(page, "s.get('frame') === s.get('num_frames') - 1")
    probe.press_key(page, "3")
    probe.wait_state(page, "s.get('key_slider') === 2")
    before = probe.state(page, "w_2")
    probe.press_key(page, "ArrowUp")
    probe.wait_state(page, f"Math.abs(s.get('w_2') - {min(1.0, before + 0.1)}) < 1e-6")
    probe.press_key(page, "m")
    probe.wait_state(page, "s.get('w_2') === 0 || s.get('w_2') === 1")
    probe.press_key(page, "?")
    page.wait_for_selector("#keys-card", state="visible", timeout=5000)
    page.keyboard.press("Escape")
    page.wait_for_selector("#keys-card", state="hidden", timeout=5000)
    probe.press_key(page, " ")
    probe.wait_state(page, "s.get('playing') === true")
    probe.press_key(page, " ")
    probe.wait_state(page, "s.get('playing') === false")


def test_keys_still_work_after_choosing_a_speed(page):
    """The speed menu keeps the focus after a choice (a read-only field): the studio's keys must still reach it."""
    page.locator(".v-select:has(#speed-select)").click()
    page.locator(".v-overlay .v-list-item", has_text="2×").click()
    probe.wait_state(page, "s.get('speed') === 2")
    # the menu closes and hands the focus back to its field, where it stays
    page.wait_for_function("() => document.activeElement && document.activeElement.id === 'speed-select'"
                           " && document.activeElement.getAttribute('aria-expanded') === 'false'", timeout=5000)
    page.keyboard.press(" ")  # not probe.press_key: that would blur the menu's field first
    probe.wait_state(page, "s.get('playing') === true")
    page.keyboard.press(" ")
    probe.wait_state(page, "s.get('playing') === false")
    probe.set_state(page, "speed", 1.0)  # back to real time for the tests after this one


def test_a_class_filter_narrows_the_list_and_opens_a_sequence_under_its_class(page):
    """Choosing a class in the filter opens the first sequence of that class under that class (the mix the user had
    was for another class); the list holds only that class."""
    _load_sequence(page, 2 if probe.state(page, "sequence_index") != 2 else 3)
    names = probe.state(page, "class_names")
    current = names.index(probe.state(page, "sequence_title").split(" · ")[1])
    target = (current + 3) % len(names)
    n = probe.state(page, "mix_count")
    probe.set_state(page, "w_1", 0.4)
    probe.set_state(page, "w_4", -0.6)
    probe.wait_state(page, f"s.get('mix_count') > {n}")
    mix = [probe.state(page, f"w_{i}") for i in range(len(names))]
    assert mix[1] == 0.4 and mix[4] == -0.6
    page.locator(".v-select", has_text="Class").first.click()
    page.locator(".v-overlay .v-list-item", has_text=names[target]).first.click()
    probe.wait_state(page, f"s.get('sequence_title').endsWith({names[target]!r})")
    probe.wait_state(page, f"{list(range(len(names)))}.every((i) => s.get('w_' + i) === (i === {target} ? 1 : 0))")
    items = probe.state(page, "sequence_items")
    assert items and all(names[target] in it["title"] for it in items)
    probe.set_state(page, "class_filter", "")
    probe.wait_state(page, "s.get('sequence_items').length > 100")
    page.click("#match-label")


def test_screenshot_downloads_the_view_as_png(page, tmp_path):
    """The picture carries the legend and the label along its top (explorer/rendering/annotation.py); the view on
    the page does not (its legend is the page's own)."""
    from PIL import Image

    from explorer.rendering.palette import LEADER

    with page.expect_download(timeout=20000) as download:
        page.locator("#screenshot").click()
    path = tmp_path / "view.png"
    download.value.save_as(path)
    with Image.open(path) as im:
        assert im.format == "PNG" and min(im.size) > 100
        png = np.asarray(im.convert("RGB"))
    strip = png[: png.shape[0] // 6]
    dark = int((strip.max(-1) < 100).sum())  # the label's dark text
    assert dark > 200 and probe.count_colors(strip, [LEADER])[0] > 20
    view = probe.view_pixels(page)[: strip.shape[0]]
    assert int((view.max(-1) < 100).sum()) < dark / 4


def test_pin_a_mix_then_compare_swap_and_clear(page):
    """A/B: the pinned mix shows as a purple figure with its own line on the distance chart; swap puts it back on
    the sliders; clear removes it."""
    from explorer.rendering.palette import PINNED

    _load_sequence(page, 2)
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    other = (own + 3) % len(names)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] < 50
    page.locator("#pin-mix").click()
    probe.wait_state(page, "!!s.get('pinned_text')")
    probe.set_state(page, f"w_{other}", 1.0)
    pinned_line = "s.get('distance_chart').includes('data-series=\"pinned\"')"
    probe.wait_state(page, f"s.get('ab_text').includes('apart') && {pinned_line}")
    probe.wait_for_view_at_rest(page)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] > 300
    page.locator("#swap-mix").click()  # the pinned mix (own class only) back on the sliders
    probe.wait_state(page, f"s.get('w_{other}') === 0 && s.get('w_{own}') === 1")
    assert probe.state(page, "pinned_text") != "" and "+1" in probe.state(page, "pinned_text")
    page.locator("#clear-pin").click()
    probe.wait_state(page, f"s.get('pinned_text') === '' && !{pinned_line}")
    probe.wait_for_view_at_rest(page)
    assert probe.count_colors(probe.view_pixels(page), [PINNED])[0] < 50


def test_interpenetrating_limbs_are_marked(page, sample_data):
    """A sequence whose synthesized hug goes into the leader: the count in words, shaded frames on the chart, and
    orange limbs in the view at such a frame."""
    from explorer.rendering.palette import WARNING
    from imm_model.evaluation.plausibility import closest_distances
    from imm_model.inference import ReactionModel

    model = ReactionModel.load()  # the frame where the network's own hug goes deepest into the leader
    model.raw = True
    leader = sample_data.canonical(5)[0]
    follower = model.synthesize_canonical(leader, np.eye(6, dtype=np.float32)[sample_data.actions[5]])
    deepest = int(np.argmin(closest_distances(leader, follower, sample_data.skeleton)))

    probe.set_state(page, "scene_layout", "overlay")
    _load_sequence(page, 5)
    probe.wait_state(page, "s.get('contact_text').includes('interpenetrate in')")
    count = probe.state(page, "mix_count")
    page.locator("#clean-up").click()  # the network's own follower, re-synthesized
    probe.wait_state(page, f"s.get('clean_up') === false && s.get('mix_count') > {count}")
    assert probe.state(page, "contact_text").startswith("bodies interpenetrate in")
    assert page.locator("#distance-chart rect.penetration").count() >= 1
    probe.set_state(page, "frame", deepest)
    probe.wait_state(page, f"s.get('frame') === {deepest}")
    probe.wait_for_view_at_rest(page)
    assert probe.count_colors(probe.view_pixels(page), [WARNING])[0] > 100
    probe.shot(page, "studio-contact")
    count = probe.state(page, "mix_count")
    page.locator("#clean-up").click()
    probe.wait_state(page, f"s.get('clean_up') === true && s.get('mix_count') > {count}")



PANELS = {"3D view": ".imm-scene", "error chart": "#distance-chart", "latent map": "#latent-plot"}
PANEL_BOXES_JS = """(sels) => Object.fromEntries(Object.entries(sels).map(([k, s]) => {
    const b = document.querySelector(s).getBoundingClientRect(); return [k, [b.left, b.top, b.right, b.bottom]]; }))"""


@pytest.mark.parametrize("width,height", [(1280, 720), (1366, 768), (1920, 1080)])
def test_the_view_chart_and_map_fit_the_window(browser, studio, width, height):
    """From 1366x768 up the 3D view, the error chart and the latent map are all inside the window with the page body
    unscrolled; at 1280x720 too, or reachable by scrolling the main column inside the window. The body never scrolls
    or wraps a panel off the right edge."""
    page = probe.open_studio(browser, studio.url, width, height)
    try:
        wait_for_map(page)
        body = page.evaluate("() => [document.documentElement.scrollWidth, document.documentElement.scrollHeight]")
        assert body[0] <= width and body[1] <= height, body
        boxes = page.evaluate(PANEL_BOXES_JS, PANELS)
        if width < 1366:  # the column may scroll inside the main area: bring each panel in, then judge it
            for name, sel in PANELS.items():
                page.locator(sel).scroll_into_view_if_needed()
                boxes[name] = page.evaluate(PANEL_BOXES_JS, {name: sel})[name]
        probe.shot(page, f"studio-{width}x{height}")
        for name, (left, top, right, bottom) in boxes.items():
            assert right - left > 300 and bottom - top > 150, (name, boxes)
            assert left >= 0 and top >= 0 and right <= width and bottom <= height, (name, boxes)
        assert page.evaluate("() => [window.scrollX, window.scrollY]") == [0, 0]
    finally:
        page.close()


def test_side_by_side_from_the_side_keeps_the_three_figures_apart(page):
    """The side camera in the side-by-side layout shows leader, ground truth and synthesized left to right, apart
    (it used to look along the line they stand on, stacking them and their captions)."""
    from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED
    from tests.studio_probe import color_mask

    n = probe.images_seen(page)
    probe.set_state(page, "scene_layout", "side_by_side")
    probe.wait_for_new_image(page, n)
    n = probe.images_seen(page)
    page.locator("#camera-side").click()
    probe.wait_for_new_image(page, n)
    probe.wait_for_view_at_rest(page)  # the still picture after the interactive one
    img = probe.view_pixels(page)
    probe.shot(page, "studio-side-by-side-side")
    try:
        centres = [np.flatnonzero(color_mask(img, c).any(0)).mean() for c in (LEADER, GROUND_TRUTH, SYNTHESIZED)]
        assert np.all(np.diff(centres) > 0.12 * img.shape[1]), centres
    finally:
        probe.set_state(page, "scene_layout", "overlay")
        page.locator("#camera-default").click()


def test_opens_on_the_diffusion_model_draws_variations_and_the_gan_is_one_click_away(page):
    """The studio opens on the diffusion model (the default, docs/experiments/default-model.md) and the chip says so;
    "new variation" draws another seed's follower; three variations stand side by side; one click brings the paper's
    GAN, which draws another follower without a seed, and one more the diffusion model, and its follower, back."""
    from explorer.rendering.palette import SYNTHESIZED
    from tests.studio_probe import color_mask

    def still_green():
        probe.wait_for_view_at_rest(page)  # the still picture after the draft
        return color_mask(probe.view_pixels(page), SYNTHESIZED)

    def figures(mask) -> int:  # green figures side by side: runs of image columns with green in them
        rows = np.flatnonzero(mask.any(1))
        gap = np.flatnonzero(np.diff(rows) > 3)  # the legend and the captions above the figures, empty rows between
        body = mask[rows[gap[-1] + 1]:] if len(gap) else mask
        cols = np.convolve(body.sum(0) > 2, np.ones(9), "same") > 0  # a figure's own gaps of a few pixels closed
        return int((np.diff(cols.astype(int)) == 1).sum() + cols[0])

    _load_sequence(page, 3)
    probe.set_state(page, "scene_layout", "overlay")
    chip = page.locator("#model-chip")
    probe.wait_state(page, "s.get('model_name') === 'diffusion' && s.get('seeded') && !s.get('computing')")
    assert "the diffusion model · seed" in chip.inner_text() and page.locator("#variation-controls").count() == 1
    # the bundled three by the names the studio was given, each within the drawer, the default first
    buttons = [page.locator(f"#model-{name}") for name in ("diffusion", "gan", "retrieval")]
    drawer = page.locator("#compare-row").bounding_box()  # a row as wide as the drawer
    boxes = [button.bounding_box() for button in buttons]
    for box in boxes:
        assert box is not None and box["x"] + box["width"] <= drawer["x"] + drawer["width"] + 1, box
    assert [(b["y"], b["x"]) for b in boxes] == sorted((b["y"], b["x"]) for b in boxes), boxes  # in the switch's order
    assert "model=" not in probe.state(page, "url_query")  # the model the studio opens with is left out of a link
    diffusion = still_green()
    seed, n = probe.state(page, "seed"), probe.state(page, "mix_count")
    page.locator("#new-variation").click()
    probe.wait_state(page, f"s.get('seed') !== {seed} && s.get('mix_count') > {n} && !s.get('computing')")
    assert f"seed {probe.state(page, 'seed')}" in chip.inner_text()
    query = probe.state(page, "url_query")
    assert f"&seed={probe.state(page, 'seed')}&" in query and "model=" not in query, query  # a link keeps the seed
    assert int((diffusion ^ still_green()).sum()) > 100, "a new variation drew the same follower"
    probe.shot(page, "studio-diffusion-variation")

    page.locator("#variation-count").get_by_role("button", name="3").click()  # three seeds side by side
    probe.wait_state(page, "s.get('variation_count') === 3 && s.get('scene_layout') === 'side_by_side' && !s.get('computing')")
    three = figures(still_green())
    probe.shot(page, "studio-diffusion-three-variations")
    page.locator("#variation-count").get_by_role("button", name="1").click()
    probe.wait_state(page, "s.get('variation_count') === 1 && !s.get('computing')")
    assert (three, figures(still_green())) == (3, 1), "three variations do not show three followers"

    probe.set_state(page, "scene_layout", "overlay")
    seed = probe.state(page, "seed")
    variation = still_green()
    n = probe.state(page, "mix_count")
    page.locator("#model-gan").click()  # the GAN in one click
    probe.wait_state(page, f"s.get('model_title') === \"the paper's GAN\" && !s.get('seeded') && s.get('mix_count') > {n} "
                           "&& !s.get('computing')")
    assert page.locator("#variation-controls").count() == 0 and "seed" not in chip.inner_text()
    query = probe.state(page, "url_query")
    assert "&model=gan" in query and "seed=" not in query, query
    assert int((variation ^ still_green()).sum()) > 100, "the follower did not change with the model"
    page.locator("#model-diffusion").click()  # and back in one click
    probe.wait_state(page, f"s.get('model_name') === 'diffusion' && s.get('seed') === {seed} && !s.get('computing')")
    assert f"the diffusion model · seed {seed}" in chip.inner_text() and "model=" not in probe.state(page, "url_query")
    back = still_green()
    assert int((back ^ variation).sum()) < 0.1 * int(variation.sum()), "the diffusion model's follower is not the one it drew"


def test_the_spread_slider_redraws_the_follower_and_enters_the_link(page):
    """The bundled diffusion model, the one the studio opens with, reads a noised leader: its spread slider shows with
    it (not with the GAN), a moved slider redraws the follower with the same seed, and a link carries the value."""
    from explorer.rendering.palette import SYNTHESIZED
    from tests.studio_probe import color_mask

    def still_green():
        probe.wait_for_view_at_rest(page)  # the still picture after the draft
        return color_mask(probe.view_pixels(page), SYNTHESIZED)

    _load_sequence(page, 6 if probe.state(page, "sequence_index") != 6 else 7)
    probe.set_state(page, "scene_layout", "overlay")
    probe.wait_state(page, "s.get('model_name') === 'diffusion' && !s.get('computing')")
    assert page.locator("#spread-row").is_visible() and probe.state(page, "spread_available")
    seed, default = probe.state(page, "seed"), probe.state(page, "spread")
    assert 0 < default < 1
    probe.wait_state(page, f"s.get('url_query').endsWith('&spread={default:g}')")
    before = still_green()
    n = probe.state(page, "mix_count")
    probe.press_slider(page, "#spread-row", "End")
    probe.wait_state(page, f"s.get('spread') === 1 && s.get('mix_count') > {n} && !s.get('computing') "
                           f"&& s.get('url_query').endsWith('&seed={seed}&spread=1')")  # the same seed, and a link has it
    assert int((before ^ still_green()).sum()) > 100, "the spread did not change the follower"
    probe.shot(page, "studio-diffusion-spread")
    probe.set_state(page, "spread", default)
    probe.wait_state(page, f"s.get('spread') === {default} && !s.get('computing')")
    page.locator("#model-gan").click()
    probe.wait_state(page, "s.get('model_name') === 'gan' && !s.get('spread_available') && !s.get('computing')")
    try:
        page.wait_for_selector("#spread-row", state="detached", timeout=5000)  # the GAN has no spread
        assert "spread=" not in probe.state(page, "url_query")
    finally:
        page.locator("#model-diffusion").click()
        probe.wait_state(page, "s.get('model_name') === 'diffusion' && s.get('spread_available') && !s.get('computing')")


@pytest.mark.slow
@pytest.mark.parametrize("width,height", [(1366, 768), (1280, 720)])
def test_other_models_followers_beside_the_current_one_at_laptop_size_and_in_the_link(browser, studio, width, height):
    """At laptop sizes, "compare with" draws the GAN's and the retrieval baseline's followers beside the diffusion
    model's (the one the studio opens with, its caption with its seed), side by side, each under its model's caption;
    the link carries the choice and opens the same comparison in a new tab."""
    from explorer.rendering.palette import COMPARED

    captions = ["the paper's GAN", "1-NN retrieval"]
    page = probe.open_studio(browser, studio.url, width, height, timeout_ms=90000)
    other = None
    try:
        for name in ("gan", "retrieval"):
            button = page.locator(f"#compare-{name}")
            box = button.bounding_box()
            assert box and box["x"] >= 0 and box["x"] + box["width"] <= 330, (name, box)  # inside the drawer
            button.click()
            probe.wait_state(page, f"s.get('compare_models').includes('{name}') && !s.get('computing')", 60000)
        probe.wait_state(page, f"s.get('scene_layout') === 'side_by_side' && {captions!r}.every("
                               "c => s.get('view_captions').includes(c))", 60000)
        shown = probe.state(page, "view_captions")
        assert "the diffusion model" in shown[2] and shown[-2:] == captions, shown
        probe.wait_state(page, "s.get('url_query').includes('compare=gan,retrieval')", 30000)
        page.wait_for_function("() => location.search.includes('compare=gan,retrieval')", timeout=30000)
        deadline = time.monotonic() + 30  # the other models' followers reach the picture
        while probe.count_colors(probe.view_pixels(page), [COMPARED])[0] < 300 and time.monotonic() < deadline:
            page.wait_for_timeout(200)
        assert probe.count_colors(probe.view_pixels(page), [COMPARED])[0] >= 300
        probe.shot(page, f"studio-compare-models-{width}x{height}")

        other = probe.open_studio(browser, studio.url + probe.state(page, "url_query"), width, height, timeout_ms=90000)
        probe.wait_state(other, f"{captions!r}.every(c => s.get('view_captions').includes(c))", 60000)
        assert probe.state(other, "compare_models") == ["gan", "retrieval"]
    finally:
        page.close()
        if other is not None:
            other.close()
