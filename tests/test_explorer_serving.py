"""The studio in headless Chromium as people reach it: a link that reopens a view, one port through a relay (an SSH
tunnel) or behind a path-prefix proxy, local (vtk.js) rendering, five tabs at once, and a tab opened during a burst of claims (fixtures in
tests/conftest.py)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests import studio_probe as probe
from tests.relays import PrefixProxy, TcpRelay

pytestmark = [pytest.mark.browser, pytest.mark.timeout(240)]


@pytest.mark.slow
def test_a_link_reopens_the_same_picture(studio, browser, page):
    """The address bar follows the view; the copied link, opened in a new tab (a new studio process), shows the
    same sequence, mix, frame, layout and camera: the two pictures match."""
    probe.press_key(page, " ") if probe.state(page, "playing") else None
    probe.set_state(page, "w_3", 0.5)
    probe.set_state(page, "scene_layout", "side_by_side")
    page.get_by_role("button", name="top").click()
    page.locator("#clean-up").click()  # the network's own follower: the link carries it as raw=1
    probe.set_state(page, "frame", 7)
    probe.wait_state(page, "s.get('url_query').includes('frame=7') && s.get('url_query').includes('camera=top')")
    probe.wait_state(page, "s.get('url_query').includes('raw=1')")
    probe.wait_state(page, "s.get('url_query').includes('layout=side_by_side') && s.get('url_query').includes(':0.5')")
    assert "frame=7" in page.url  # the address bar itself
    page.locator("#copy-link").click()
    probe.wait_state(page, "!!s.get('share_link')")
    link = probe.state(page, "share_link")
    assert link.startswith(studio.url) and "/s/" not in link, link
    page.keyboard.press("Escape")  # close the link's card, which covers a corner of the view
    query = probe.state(page, "url_query")
    other = probe.open_studio(browser, link, timeout_ms=90000)
    try:
        probe.wait_state(other, f"s.get('url_query') === {query!r}", timeout_ms=30000)
        assert probe.state(other, "clean_up") is False
        probe.wait_for_view_at_rest(page)  # the last picture of both views
        probe.wait_for_view_at_rest(other)
        a, b = probe.view_pixels(page).astype(float), probe.view_pixels(other).astype(float)
        probe.shot(page, "studio-link-sender")
        probe.shot(other, "studio-link-receiver")
        assert a.shape == b.shape
        assert np.abs(a - b).mean() < 2.0, np.abs(a - b).mean()
    finally:
        other.close()
    probe.set_state(page, "scene_layout", "overlay")
    page.locator("#clean-up").click()
    probe.wait_state(page, "s.get('clean_up') === true && !s.get('url_query').includes('raw=')")
    page.get_by_role("button", name="reset").first.click()


def test_a_bad_link_names_what_it_ignored(browser, studio):
    other = probe.open_studio(browser, studio.url + "?seq=nope&scale=7&layout=overlay&raw=yes", timeout_ms=90000)
    try:
        probe.wait_state(other, "s.get('error').startsWith('link:')")
        error = probe.state(other, "error")
        assert "no sequence 'nope'" in error and "scale '7' is outside" in error and "raw 'yes' is not 0 or 1" in error
    finally:
        other.close()


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


@pytest.mark.slow
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
            # plotly.js from the launcher's /imm/static/; the map of a cold cache, as the other cold starts wait for it
            probe.wait_for_latent_points(pg, 60000)
            pg.close()
    finally:
        proxy.close()


def test_local_rendering_draws_in_the_page_and_follows_a_slider(browser, tmp_path):
    """--render local (vtk.js in the browser, trame-vtk): the page draws the scene on a canvas and a slider move
    re-synthesizes without an error (the streamed view's draft pictures do not apply to it)."""
    with probe.StudioProcess("--render", "local", cache_dir=tmp_path) as studio:
        pg = browser.new_page(viewport={"width": 1400, "height": 900})
        pg.goto(studio.url, timeout=90000)
        pg.wait_for_selector(".v-main canvas", timeout=60000)
        names = probe.state(pg, "class_names")
        n_mix = probe.state(pg, "mix_count")
        probe.press_slider(pg, f".slider-{names[1].replace(' ', '_')}", "End")
        pg.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=15000)
        assert probe.state(pg, "error") == "" and names[1] in probe.state(pg, "label_text")
        assert not [ln for ln in studio.lines if "Traceback" in ln]
        pg.close()


@pytest.mark.slow
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
        probe.wait_state(pages[0], f"s.get('label_text') !== {texts[0]!r}")
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
        pages[-1].screenshot(path=str(probe.ARTIFACTS / "studio-client5.png"))
        assert max(delays) < 3.0, f"slider -> picture per client: {np.round(delays, 2)} s"
    finally:
        for pg in pages:
            pg.close()


@pytest.mark.slow
def test_a_hostile_upload_is_one_red_line_and_closed_tabs_leave_no_error(studio, browser, tmp_path):
    """Through the page: an .npz of 0.5 MB that unpacks to 540 MB is read within the upload's budget (its own
    process, explorer/serving/upload_reader.py) and answered by the red one-line alert; the view and the slider keep
    working. Tabs closed while playing (pictures in flight) leave no error in the studio's log."""
    from tests.test_studio_hardening import hostile_uploads

    pg = probe.open_studio(browser, studio.url, timeout_ms=90000)
    try:
        title = probe.state(pg, "sequence_title")
        hostile = tmp_path / "zero_frames.npz"
        hostile.write_bytes(hostile_uploads()["zero_frames.npz"])
        t0 = time.monotonic()
        pg.locator("input[type=file]").set_input_files(str(hostile))
        probe.wait_state(pg, "(s.get('error') || '').includes('zero_frames.npz')", timeout_ms=20000)
        assert time.monotonic() - t0 < 15.0
        alert = pg.locator("#error-alert")
        assert alert.is_visible() and "zero_frames.npz" in alert.inner_text()
        assert "\n" not in probe.state(pg, "error") and probe.state(pg, "sequence_title") == title
        names = probe.state(pg, "class_names")
        n_mix = probe.state(pg, "mix_count")
        probe.press_slider(pg, f".slider-{names[1].replace(' ', '_')}", "End")
        pg.wait_for_function("(n) => window.trame.state.get('mix_count') > n", arg=n_mix, timeout=15000)
        serving = _play_until_pictures_flow(pg, studio)
    finally:
        pg.close()
    for _ in range(2):
        other = probe.open_studio(browser, studio.url, timeout_ms=90000)
        serving |= _play_until_pictures_flow(other, studio)
        other.close()
    # the closed tabs' processes retired (RECONNECT_GRACE_S after the close) and ended: what they logged is all there
    deadline = time.monotonic() + 60
    while any(pid in _studio_processes(studio) and pid not in _serving_a_tab(studio) for pid in serving):
        assert time.monotonic() < deadline, "a closed tab's studio process did not end"
        time.sleep(0.2)
    lines = studio.read_log()
    assert not [ln for ln in lines if "Traceback" in ln or "never retrieved" in ln], lines[-20:]


def _studio_processes(studio) -> set[int]:
    """The studio processes (children of the launcher's zygote) alive now."""
    from pathlib import Path

    def children(pid: int) -> set[int]:
        try:
            return {int(c) for task in Path(f"/proc/{pid}/task").iterdir() for c in (task / "children").read_text().split()}
        except OSError:
            return set()

    return {p for zygote in children(studio.proc.pid) for p in children(zygote)}


def _serving_a_tab(studio) -> set[int]:
    """The studio processes with a websocket from the launcher open: each serves an open tab (a spare has none)."""
    import os

    established = set()  # socket inodes of established TCP connections
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            established |= {row.split()[9] for row in list(f)[1:] if row.split()[3] == "01"}
    serving = set()
    for pid in _studio_processes(studio):
        try:
            links = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        except OSError:
            continue
        if any(link.startswith("socket:[") and link[8:-1] in established for link in links):
            serving.add(pid)
    return serving


def _play_until_pictures_flow(pg, studio) -> set[int]:
    """Start playback and wait for a few of its pictures (pictures in flight when the tab closes) -> the studio
    processes then serving a tab, this one among them."""
    probe.watch_view_images(pg)
    n = probe.images_seen(pg)
    probe.press_key(pg, " ") if not probe.state(pg, "playing") else None
    probe.wait_for_new_image(pg, n + 3, timeout_ms=60000)
    return _serving_a_tab(studio)


def _network_log(page) -> dict[str, dict]:
    """The page's HTTP requests as Chromium's network log sees them: URL, bytes over the wire, from the cache."""
    cdp = page.context.new_cdp_session(page)
    cdp.send("Network.enable")
    log: dict[str, dict] = {}

    def sent(e):
        log[e["requestId"]] = {"url": e["request"]["url"].split("?")[0], "cached": False}

    def cached(e):
        if e["requestId"] in log:
            log[e["requestId"]]["cached"] = True

    def received(e):
        if e["requestId"] in log and e["response"].get("fromDiskCache"):
            log[e["requestId"]]["cached"] = True

    def finished(e):
        if e["requestId"] in log:
            log[e["requestId"]]["bytes"] = e["encodedDataLength"]

    for event, handler in (("requestWillBeSent", sent), ("requestServedFromCache", cached),
                           ("responseReceived", received), ("loadingFinished", finished)):
        cdp.on(f"Network.{event}", handler)
    return log  # filled in as the page loads


def _libraries(log: dict[str, dict]) -> list[dict]:
    """What the page loads beside itself: plotly, vue, vuetify and its fonts, trame's client."""
    return [x for x in log.values() if x["url"].endswith((".js", ".css", ".woff2", ".ttf"))]


def test_a_second_tab_takes_plotly_and_trames_files_from_the_browsers_cache(studio, browser):
    """plotly.js (1.2 MB) and trame's client files (vue, vuetify and its fonts: 2.3 MB) are served by the launcher at
    one path for every tab, not under the tab's own /s/<id>/: a second tab in the same browser takes every one of them
    from the cache, downloads next to nothing, and draws its map."""
    context = browser.new_context(viewport={"width": 1400, "height": 900})  # a cache of its own, empty
    try:
        tabs = []
        for _ in range(2):
            pg = context.new_page()
            log = _network_log(pg)
            pg.goto(studio.url, timeout=90000)
            probe.wait_for_latent_points(pg, 60000)
            deadline = time.monotonic() + 5  # the network log's last events arrive as Playwright waits
            while not all("bytes" in x for x in _libraries(log)) and time.monotonic() < deadline:
                pg.wait_for_timeout(100)
            tabs.append((pg.url, _libraries(log), sum(x.get("bytes", 0) for x in log.values())))
        (first_url, first, first_bytes), (second_url, second, second_bytes) = tabs
        assert first_url != second_url and sorted(x["url"] for x in first) == sorted(x["url"] for x in second)
        assert len(first) >= 8 and all(x["url"].startswith(studio.url + "static/") for x in first), first
        plotly = [x for x in first if "/plotly-" in x["url"]]  # fetched once after the first picture, run from the cache
        downloaded = [x for x in plotly if x["bytes"] >= 1000]
        assert len(downloaded) == 1 and not downloaded[0]["cached"] and downloaded[0]["bytes"] > 1_000_000, plotly
        assert all(x["cached"] and x["bytes"] < 1000 for x in second), [x for x in second if not x["cached"]]
        assert first_bytes > 3_000_000 and second_bytes < first_bytes / 50, (first_bytes, second_bytes)
    finally:
        context.close()


def test_the_static_paths_answer_cache_headers_and_unknown_names_404(studio, page):
    """/static/<name> (plotly.js) and /static/<key>/<path> (trame's client files, the key the page's): immutable for a
    year with an ETag (a revalidation is 304); no token or cookie needed, but another web origin or host name is
    refused; an unknown name, the page itself or a path out of the folder is a plain 404, with no traceback."""
    import re
    import urllib.error
    import urllib.request

    from explorer.serving.page_shell import PLOTLY_JS
    from explorer.trame_adapter import client_www

    def get(path, **headers):
        request = urllib.request.Request(studio.url + path, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=30) as r:
                return r.status, r.headers, r.read()
        except urllib.error.HTTPError as err:
            return err.code, err.headers, err.read()

    vue = page.evaluate("() => [...document.scripts].map((s) => s.src).find((src) => src.endsWith('/vue.global.js'))")
    key = re.fullmatch(re.escape(studio.url) + r"static/([0-9a-f]{16})/vue\.global\.js", vue)[1]
    vuetify = [u for u in probe.state(page, "trame__scripts") if "vuetify" in u][0]  # as trame's client loads it
    assert vuetify.startswith(f"../../static/{key}/"), vuetify
    for path, content in ((f"static/{PLOTLY_JS.name}", PLOTLY_JS.read_bytes()),
                          (f"static/{key}/vue.global.js", (client_www() / "vue.global.js").read_bytes()),
                          (vuetify.removeprefix("../../"), None)):
        status, headers, body = get(path)
        assert status == 200 and (body == content if content else len(body) > 100_000), (path, status)
        assert headers["Cache-Control"] == "public, max-age=31536000, immutable" and "javascript" in headers["Content-Type"]
        assert get(path, **{"If-None-Match": headers["ETag"]})[0] == 304
        assert get(path, Origin="http://evil.example.com")[0] == 403
        assert get(path, Host="rebound.example.com")[0] == 403  # a DNS-rebinding page's own name
    for unknown in ("static/plotly.min.js", "static/nope.js", "static/", "static/a/b.js", "static/..%2Fclaim",
                    f"static/{key}/index.html", f"static/{key}/nope.js", f"static/{key}/", f"static/{'0' * 16}/vue.global.js",
                    f"static/{key}/assets/..%2F..%2F..%2Fclaim", f"static/{key}/.%2E/index.html"):
        status, _, body = get(unknown)
        assert status == 404 and len(body) < 100, (unknown, status, body[:100])
    assert not [ln for ln in studio.read_log() if "Traceback" in ln or "Error handling request" in ln]


def test_a_tab_opened_while_claims_are_rate_limited_tries_again_and_gets_its_studio(studio, browser):
    """Claims posted in a burst (a script, or many tabs) use up the rate limit: the front page tries its claim again
    a second later instead of showing 'too many new tabs'. (The burst's claims ask for no page: retired within 5 s.)"""
    import http.client
    from concurrent.futures import ThreadPoolExecutor
    from urllib.parse import urlsplit

    u = urlsplit(studio.url)

    def claim(_) -> int:
        conn = http.client.HTTPConnection(u.hostname, u.port, timeout=60)
        conn.request("POST", "/claim", headers={"Origin": studio.url.rstrip("/")})
        status = conn.getresponse().status
        conn.close()
        return status

    with ThreadPoolExecutor(8) as pool:
        burst = [pool.submit(claim, i) for i in range(8)]  # the refused ones are answered at once
        while sum(f.done() for f in burst) < 4:
            time.sleep(0.01)
        pg = browser.new_page()
        pg.goto(studio.url)  # its claim comes within the second the limit needs to let one more through
        try:
            probe.wait_for_view(pg, 90000)
            assert "/s/" in pg.url
        finally:
            pg.close()
        assert 429 in [f.result() for f in burst]


@pytest.mark.parametrize("stuck_before", ["page", "websocket"])
def test_a_stuck_studio_process_is_replaced_and_its_tab_goes_to_a_fresh_one(browser, tmp_path, monkeypatch, stuck_before):
    """A tab's studio process that stops answering (stopped here with SIGSTOP) before its page is served, or after the
    page and before its websocket: the launcher ends it after IMM_STUDIO_ANSWER_TIMEOUT, says so with its stacks, and
    the tab goes to the front page for a fresh studio with the view its address names."""
    import contextlib
    import os
    import signal

    monkeypatch.setenv("IMM_STUDIO_ANSWER_TIMEOUT", "3")
    with probe.StudioProcess(cache_dir=tmp_path) as studio:
        (spare,) = _studio_processes(studio)  # the first tab's studio process
        pg = browser.new_page()
        if stuck_before == "page":
            os.kill(spare, signal.SIGSTOP)
        else:  # once its page is served, as the page opens its websocket (trame's loading.tpl may still be on its way)

            def stop_then_connect(ws):
                if spare in _studio_processes(studio):
                    os.kill(spare, signal.SIGSTOP)
                ws.connect_to_server()

            pg.route_web_socket("**/ws", stop_then_connect)
        try:
            pg.goto(studio.url + "?frame=5")
            probe.wait_for_view(pg, 90000)
            probe.wait_state(pg, "s.get('frame') === 5")  # the address's view, in the fresh studio
            assert "/s/" in pg.url
        finally:
            pg.close()
            with contextlib.suppress(ProcessLookupError):  # a stopped process that was not ended would outlive the studio
                os.kill(spare, signal.SIGCONT)
        deadline = time.monotonic() + 10
        while spare in _studio_processes(studio):
            assert time.monotonic() < deadline, "the stuck studio process was not ended"
            time.sleep(0.1)
        lines = studio.read_log()
        notice = [ln for ln in lines if ln.startswith(probe.NOTICE)]
        assert len(notice) == 1 and "did not answer" in notice[0] and " 3 s" in notice[0], lines[-10:]
        probe.StudioProcess.noticed.remove(studio)  # expected here: not a fault for the run's summary


def test_a_page_whose_layout_never_comes_is_loaded_again_and_keeps_its_studio(browser, studio):
    """trame's client draws the page once each of its stylesheets has loaded: one that never arrives (held here, the
    first time it is asked for) would leave the tab on "Loading..." for ever. The page loads itself again after 20 s,
    keeping its studio (the same address), and shows its view; the studio's log names the file it waited for."""
    asked = []

    def hold_the_first(route):
        asked.append(route.request.url)
        if len(asked) > 1:
            route.continue_()  # (the first is never answered)

    pg = browser.new_page()
    pg.route("**/vuetify3.css", hold_the_first)
    try:
        pg.goto(studio.url)
        pg.wait_for_url("**/s/**")
        token = pg.url.split("/s/")[1].split("/")[0]
        probe.wait_for_view(pg, 90000)
        assert len(asked) == 2 and pg.url.split("/s/")[1].split("/")[0] == token
    finally:
        pg.close()
    said = [ln for ln in studio.read_log() if ln.startswith("a tab's page was loaded again")]
    assert len([ln for ln in said if "vuetify3.css" in ln]) == 1, said  # the launcher names what held the page
    if len(said) == 1:  # expected here: not a fault for the run's summary (another page's, on a busy machine, stays)
        probe.StudioProcess.noticed.remove(studio)
