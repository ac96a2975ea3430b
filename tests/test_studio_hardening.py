"""A studio that cannot be pinned or drained: uploads read within a time and memory budget, a closed (or hung) tab's
process ended within seconds, websocket messages capped before the studio allocates them and before it unpacks them,
only the page's state keys set by a client and its text logged capped, claims only from the page, rate-limited and
unable to hold the slots, exports capped per tab, every studio process gone within seconds of SIGTERM or Ctrl+C,
--max-clients validated, the Origin check aware of HTTPS reverse proxies. Browserless: raw
wslink clients stand in for tabs (the page itself is in tests/test_explorer_serving.py)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import os
import re
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from imm_model.paths import SAMPLE_DATA, SAMPLE_GAN

pytest.importorskip("trame")

FIXTURE_BVH = Path(__file__).parent / "fixtures" / "bvh" / "cmu_01_01.bvh"


def hostile_uploads() -> dict[str, bytes]:
    """Leader files that claim more than they hold, or hold what no reader should loop or allocate on."""
    text = FIXTURE_BVH.read_text()
    frames = int(re.search(r"Frames:\s*(\d+)", text).group(1))
    zeros = io.BytesIO()
    np.savez_compressed(zeros, leader=np.zeros((3_000_000, 15, 3), np.float32))  # 0.5 MB that unpacks to 540 MB
    return {
        "short_motion.bvh": re.sub(r"Frames:\s*\d+", f"Frames: {frames + 1}", text, count=1).encode(),
        "billion_frames.bvh": re.sub(r"Frames:\s*\d+", "Frames: 1000000000", text, count=1).encode(),
        "slow_frames.bvh": re.sub(r"Frame Time:\s*\S+", "Frame Time: 1e12", text, count=1).encode(),
        "nan_frame_time.bvh": re.sub(r"Frame Time:\s*\S+", "Frame Time: nan", text, count=1).encode(),
        "zero_frames.npz": zeros.getvalue(),
        "garbage.txt": b"\x00\xff" * 5000,
        "truncated.bvh": text[: len(text) // 3].encode(),
        "nan_offset.bvh": text.replace("0.00000", "nan", 3).encode(),
    }


# ---- uploads read in a child process ---------------------------------------------------------------------------


@pytest.fixture()
def budget(monkeypatch):
    from explorer.serving import upload_reader
    monkeypatch.setattr(upload_reader, "TIME_BUDGET_S", 1.5)
    return upload_reader


def _spin(name, content):
    while True:
        pass


def _hog(name, content):
    return [np.empty(64 << 20, np.uint8) for _ in range(100)]  # 6.4 GB, asked for 64 MB at a time


def _crash(name, content):
    os.kill(os.getpid(), signal.SIGSEGV)


def test_an_upload_reader_that_hangs_or_hogs_is_stopped_and_the_next_upload_is_read(budget):
    """The time budget holds even if a reader never returns; the memory budget even if it allocates without end; a
    crash is one line too; and after each the same reader reads a good file as the studio itself would."""
    from explorer.session.session import load_model
    from explorer.session.uploads import read_upload
    from imm_model.data.dataset import InteractionDataset

    data = InteractionDataset.load(SAMPLE_DATA)
    model = load_model(SAMPLE_GAN, data)
    hostile = {"spin.bvh": _spin, "hog.bvh": _hog, "crash.bvh": _crash}

    def read(name, content):  # the helper is forked now: what it runs is fixed here
        return hostile.get(name, lambda n, c: read_upload(n, c, model))(name, content)

    reader = budget.UploadReader(read)
    try:
        for name, needle in (("spin.bvh", "took longer than 1.5 s"), ("hog.bvh", "more than the 500 MB"),
                             ("crash.bvh", "stopped on it")):  # fmt: skip
            t0 = time.monotonic()
            with pytest.raises(Exception) as err:
                reader(name, b"x")
            assert time.monotonic() - t0 < 6.0
            message = str(err.value)
            assert needle in message and message.startswith(f"{name}: ") and "\n" not in message, message
        leader = reader("take.bvh", FIXTURE_BVH.read_bytes())
        expected = read_upload("take.bvh", FIXTURE_BVH.read_bytes(), model)
        np.testing.assert_array_equal(leader.canonical, expected.canonical)
        np.testing.assert_array_equal(leader.world, expected.world)
        np.testing.assert_array_equal(leader.frame.origin, expected.frame.origin)
        assert leader.frame.mode == expected.frame.mode
        with pytest.raises(Exception, match="short_motion.bvh: the MOTION block"):
            reader("short_motion.bvh", hostile_uploads()["short_motion.bvh"])
    finally:
        reader.close()


# ---- websocket messages capped before allocation --------------------------------------------------------------


def _chunk(message_id: int, offset: int, total: int, content: bytes = b"") -> bytes:
    return message_id.to_bytes(4, "little") + offset.to_bytes(4, "little") + total.to_bytes(4, "little") + content


def test_the_proxy_refuses_chunks_that_claim_too_much():
    from explorer.serving.proxy import MAX_MESSAGE_BYTES, InboundBudget

    budget = InboundBudget()
    assert "claiming 1073741824 bytes" in budget.admit(1, _chunk(7, 0, 1 << 30, b"x"))
    upload = 20_000_000  # the largest upload, in wslink's 4 MB chunks, with small messages between
    for offset in range(0, upload, 4 << 20):
        assert budget.admit(1, _chunk(8, offset, upload, b"\0" * min(4 << 20, upload - offset))) is None
        assert budget.admit(1, _chunk(9 + offset, 0, 3, b"abc")) is None
    assert not budget.pending  # each message done: nothing owed
    assert budget.admit(1, _chunk(10, 0, upload, b"x")) is None
    assert "at once" in budget.admit(2, _chunk(11, 0, upload, b"x"))  # a second websocket of the same studio
    budget.forget(1)  # its websocket closed: the studio dropped what it was receiving on it
    assert "beyond the end" in budget.admit(2, _chunk(12, 5, 8, b"abcd"))
    assert budget.admit(2, _chunk(13, 0, 99, b"x")) is None
    assert "differs" in budget.admit(2, _chunk(13, 1, 98, b"x"))
    assert "shorter than a chunk header" in budget.admit(2, b"\x01\x02")
    budget.forget(2)
    assert budget.admit(2, _chunk(14, 0, MAX_MESSAGE_BYTES, b"x")) is None
    assert "at once" in budget.admit(2, _chunk(15, 0, 1, b""))


# ---- who may claim a studio process, and from which origin ------------------------------------------------------


def _request(path: str = "/claim", method: str = "POST", host: str = "localhost:8080", **headers):
    from aiohttp.test_utils import make_mocked_request

    return make_mocked_request(method, path, headers={"Host": host, **{k.replace("_", "-"): v for k, v in headers.items()}})


def _launcher(**config):
    from explorer.serving.launcher import LaunchConfig, Launcher

    return Launcher(LaunchConfig(data=SAMPLE_DATA, models=(("gan", SAMPLE_GAN),), **config))


def test_the_origin_check_accepts_the_scheme_the_page_was_served_over():
    plain, behind = _launcher(), _launcher(base_url="https://lab.example.org/imm/")
    assert plain.access.authorized(_request(Origin="http://localhost:8080"))
    assert not plain.access.authorized(_request(Origin="https://localhost:8080"))  # nothing says the page came over TLS
    assert plain.access.authorized(_request(Origin="https://localhost:8080", X_Forwarded_Proto="https"))
    assert not plain.access.authorized(_request(Origin="https://evil.example.com", X_Forwarded_Proto="https"))
    assert behind.access.authorized(_request(Origin="https://localhost:8080"))  # --base-url is https
    assert behind.access.authorized(_request(Origin="https://lab.example.org"))  # a proxy that does not pass Host through
    assert not behind.access.authorized(_request(Origin="https://evil.example.org"))


def test_static_files_need_no_token_but_the_studios_origin_and_host_names():
    """/static/ (plotly.js, trame's client files) is public: with --token it is served without the token, on any host
    name the token admits; without a token only on this studio's host names; never to another web origin."""
    plain, tokened = _launcher(), _launcher(token="a-long-token", host="0.0.0.0")
    assert plain.access.public(_request(method="GET")) and not plain.access.public(_request(method="GET", host="rebound.example.com:8080"))
    assert not plain.access.authorized(_request(method="GET", host="rebound.example.com:8080"))
    assert tokened.access.public(_request(method="GET", host="lab.example.org:8080"))
    assert not tokened.access.authorized(_request(method="GET"))
    for front in (plain, tokened):
        assert not front.access.public(_request(method="GET", Origin="http://evil.example.com"))


def test_claims_need_the_page_and_are_rate_limited(monkeypatch):
    """A bare POST (no Origin, no cookie) is refused; the page's Origin or, without one, its cookie is admitted; past
    the burst, claims are refused until the bucket refills."""
    from explorer.serving import access as access_module
    from explorer.serving.access import PAGE_COOKIE
    from explorer.serving.pool import Worker

    async def go():
        front = _launcher()

        async def take():
            return Worker("1", "secret")

        front.pool.take = take
        statuses = [(await front.claim(_request())).status for _ in range(10)]
        assert statuses == [403] * 10
        page = await front.handle(_request("/", "GET"))
        cookie = page.cookies[PAGE_COOKIE].value
        admitted = [(await front.claim(_request(Origin="http://localhost:8080"))).status,
                    (await front.claim(_request(Cookie=f"{PAGE_COOKIE}={cookie}"))).status]  # fmt: skip
        assert admitted == [200, 200]
        assert (await front.claim(_request(Cookie=f"{PAGE_COOKIE}=guessed"))).status == 403
        burst = [(await front.claim(_request(Origin="http://localhost:8080"))).status for _ in range(4)]
        assert burst == [200, 200, 429, 429]  # 4 at once, then one per CLAIM_EVERY_S
        await asyncio.sleep(access_module.CLAIM_EVERY_S * 1.2)
        assert (await front.claim(_request(Origin="http://localhost:8080"))).status == 200

    monkeypatch.setattr(access_module, "CLAIM_EVERY_S", 0.3)
    asyncio.run(go())


@pytest.mark.parametrize("count", ["0", "-3"])
def test_max_clients_below_one_is_refused_in_one_line(count, capsys):
    from imm_model.cli import main

    assert main(["explore", "--no-browser", "--port", "0", "--max-clients", count]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"imm explore: error: --max-clients must be at least 1 (one browser tab), not {count}"


# ---- a running studio, reached by raw wslink clients ------------------------------------------------------------


def _zygote_children(studio) -> list[int]:
    """The studio processes: the zygote's children (each upload helper is a child of its studio process)."""
    pid = studio.proc.pid
    zygote = int(Path(f"/proc/{pid}/task/{pid}/children").read_text().split()[0])
    return [int(p) for p in Path(f"/proc/{zygote}/task/{zygote}/children").read_text().split()]


def _memory_mb(pid: int, field: str = "VmRSS") -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024
    raise ValueError(field)


def _gone(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[1].split()[0] == "Z"
    except OSError:
        return True


class RawTab:
    """A tab as the studio sees it, without a browser: claim, websocket through the launcher, wslink hello (the proxy
    puts the secret in), trame's state; uploads as the page sends them."""

    def __init__(self, url: str):
        self.url = url
        self.origin = url.rstrip("/")
        self.ids = 0  # rpc and chunk message ids

    async def open(self):
        import aiohttp

        self.http = aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True))  # the claim's cookie: its tab's key
        async with self.http.post(self.url + "claim", headers={"Origin": self.origin}) as r:
            assert r.status == 200, await r.text()
            self.path = (await r.json())["url"]
        return await self.connect()

    async def connect(self, compress: int = 0):
        """The websocket to this tab's studio process (again, after a reload); `compress` asks for permessage-deflate
        as a browser does."""
        self.ws = await self.http.ws_connect(self.url + self.path + "ws", headers={"Origin": self.origin}, max_msg_size=0,
                                             compress=compress)
        hello = await self.call("system:c0:0", "wslink.hello", [{"secret": "the proxy puts the real one in"}])
        self.client = hello["result"]["clientID"]
        self.state = (await self.call(self._id(), "trame.state.get", []))["result"]["state"]
        return self

    def _id(self) -> str:
        self.ids += 1
        return f"rpc:{self.client}:{self.ids}"

    async def send(self, rpc_id: str, method: str, args: list) -> None:
        """One wslink message in one chunk (the studio accepts any chunk size up to the proxy's caps)."""
        import msgpack

        body = msgpack.packb({"wslink": "1.0", "id": rpc_id, "method": method, "args": args, "kwargs": {}})
        self.ids += 1
        await self.ws.send_bytes(_chunk(self.ids, 0, len(body), body))

    async def call(self, rpc_id: str, method: str, args: list) -> dict:
        await self.send(rpc_id, method, args)
        while True:
            message = await self.receive(60)
            if message.get("id") == rpc_id:
                return message

    async def receive(self, timeout: float) -> dict:
        import msgpack

        msg = await self.ws.receive(timeout=timeout)
        assert msg.data is not None and not isinstance(msg.data, int), f"websocket closed: {msg}"
        return msgpack.unpackb(msg.data[12:])

    async def upload(self, name: str, content: bytes, timeout: float = 20.0) -> str:
        """-> the page's one-line alert for it (state `error`), asserting that nothing else of the view changed."""
        file = {"name": name, "size": len(content), "type": "", "lastModified": 0, "content": content}
        await self.send(self._id(), "trame.state.update", [[{"key": "upload_file", "value": file}]])
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = await self.receive(deadline - time.monotonic())
            changed = message.get("result") if message.get("id", "").startswith("publish:trame.state.topic") else None
            if changed and changed.get("error"):
                assert "sequence_title" not in changed and "num_frames" not in changed, changed  # the view is kept
                return changed["error"]
        raise TimeoutError(f"no alert for {name}")

    async def close(self) -> None:
        await self.ws.close()
        await self.http.close()

    async def page_status(self, query: str = "") -> tuple[int, str]:
        """GET this tab's page as a reload does -> (status, where a redirect points)."""
        async with self.http.get(self.url + self.path + "index.html" + query, allow_redirects=False) as r:
            return r.status, r.headers.get("Location", "")


def _post_claim(url: str, headers: dict[str, str]) -> tuple[int, bytes]:
    """POST /claim with `headers` -> (status, body)."""
    import http.client
    from urllib.parse import urlsplit

    u = urlsplit(url)
    conn = http.client.HTTPConnection(u.hostname, u.port, timeout=30)
    conn.request("POST", "/claim", headers=headers)
    response = conn.getresponse()
    answer = response.status, response.read()
    conn.close()
    return answer


def _claim_status(url: str) -> int:
    return _post_claim(url, {"Origin": url.rstrip("/")})[0]


def _first_claim_after(url: str, since: float, limit_s: float = 15.0) -> float:
    """Seconds from `since` to the sending of the first claim that got a studio process."""
    while time.monotonic() - since < limit_s:
        sent = time.monotonic()
        if _claim_status(url) == 200:
            return sent - since
        time.sleep(0.5)
    raise AssertionError(f"no studio process was free within {limit_s} s")


@pytest.fixture(scope="module")
def small_studio(tmp_path_factory):
    if not SAMPLE_GAN.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_GAN}")
    from tests.studio_probe import StudioProcess

    old = os.environ.get("IMM_STUDIO_CLAIM_TIMEOUT")
    os.environ["IMM_STUDIO_CLAIM_TIMEOUT"] = "3"  # the claims these tests make without connecting
    try:
        with StudioProcess("--max-clients", "2", cache_dir=tmp_path_factory.mktemp("cache")) as s:
            yield s
    finally:
        os.environ.pop("IMM_STUDIO_CLAIM_TIMEOUT") if old is None else os.environ.__setitem__("IMM_STUDIO_CLAIM_TIMEOUT", old)


def _connected(studio) -> set[int]:
    """The studio processes with an open connection (a tab's websocket through the launcher; spares have none)."""
    established = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for row in Path(table).read_text().splitlines()[1:]:
            fields = row.split()
            if fields[3] == "01":  # ESTABLISHED
                established.add(fields[9])
    connected = set()
    for pid in _zygote_children(studio):
        try:
            sockets = {os.readlink(fd.path)[8:-1] for fd in os.scandir(f"/proc/{pid}/fd")}
        except OSError:  # it has just exited
            continue
        if sockets & established:
            connected.add(pid)
    return connected


async def _open_tab(studio) -> tuple[RawTab, int]:
    """A new tab and the pid of its studio process."""
    before = _connected(studio)
    tab = await RawTab(studio.url).open()
    (pid,) = _connected(studio) - before
    return tab, pid


def test_ten_bare_claims_leave_a_real_tab_served_at_once(small_studio):
    statuses = [_claim_status_bare(small_studio.url) for _ in range(10)]
    assert statuses == [403] * 10

    async def go():
        t0 = time.monotonic()
        tab = await RawTab(small_studio.url).open()
        opened = time.monotonic() - t0
        await tab.close()
        return opened

    assert asyncio.run(go()) < 10.0  # a warm spare: no slot was taken by the bare posts


def _claim_status_bare(url: str) -> int:
    return _post_claim(url, {})[0]


def test_a_gigabyte_chunk_header_does_not_raise_a_studio_process(small_studio):
    """A 13-byte message whose header claims 1 GiB: the proxy closes that websocket; the process it was for grows
    by less than 50 MB (wslink alone would allocate the gigabyte at once)."""
    import aiohttp

    async def go():
        tab, pid = await _open_tab(small_studio)
        before = _memory_mb(pid)
        await tab.ws.send_bytes(_chunk(77, 0, 1 << 30, b"x"))
        await asyncio.sleep(1.0)
        after = _memory_mb(pid)
        try:
            while (closed := await tab.ws.receive(timeout=10)).type == aiohttp.WSMsgType.BINARY:
                pass  # pictures of the view, sent before the proxy closed the websocket
        finally:
            await tab.close()
        return closed, before, after, pid

    closed, before, after, pid = asyncio.run(go())
    assert after - before < 50, (before, after)
    assert closed.data == 1009 and "claiming 1073741824 bytes" in closed.extra, closed
    _assert_ends_within(pid, 5.0)  # the tab has gone: its process too


def _assert_ends_within(pid: int, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while not _gone(pid):
        assert time.monotonic() < deadline, f"studio process {pid} outlived its tab by {seconds} s"
        time.sleep(0.1)


@pytest.mark.slow
def test_hostile_uploads_get_one_line_and_a_hung_tab_is_ended_within_seconds(small_studio):
    """Both slots taken by tabs that upload the eight hostile files (each answered in one line within the budget,
    the view kept, the studio process's peak memory bounded); one tab's process then hangs for good (SIGSTOP: no
    SIGTERM reaches it). Both tabs close: their slots are free within 5 s, the hung process is gone, and a further
    tab is served."""
    first: list[int] = []

    async def go():
        tab, pid = await _open_tab(small_studio)
        first.append(pid)
        tabs = [tab, (await _open_tab(small_studio))[0]]  # the second slot
        peak_before = _memory_mb(pid, "VmHWM")
        uploads = list(hostile_uploads().items())
        t0 = time.monotonic()
        alerts = await asyncio.gather(*(_upload_all(tab, uploads[i::2]) for i, tab in enumerate(tabs)))
        took = time.monotonic() - t0
        peak_after = _memory_mb(pid, "VmHWM")
        assert _claim_status(small_studio.url) == 503  # both slots are taken
        os.kill(pid, signal.SIGSTOP)
        for tab in tabs:
            await tab.close()
        in_upload_order = [alerts[i % 2][i // 2] for i in range(len(uploads))]
        return in_upload_order, took, peak_before, peak_after, time.monotonic()

    try:
        alerts, took, peak_before, peak_after, closed = asyncio.run(go())
        free_after = _first_claim_after(small_studio.url, closed)
        _assert_ends_within(first[0], closed + 5.0 - time.monotonic())
    finally:
        if first and not _gone(first[0]):
            os.kill(first[0], signal.SIGKILL)
    for name, alert in zip(hostile_uploads(), alerts, strict=True):
        assert alert.startswith(name + ": ") and "\n" not in alert, alert
    assert took < 4 * 12, took  # four uploads per tab, each within the 10 s budget
    assert peak_after - peak_before < 200, (peak_before, peak_after)
    assert free_after < 5.0, free_after


async def _upload_all(tab: RawTab, uploads: list[tuple[str, bytes]]) -> list[str]:
    return [await tab.upload(name, content) for name, content in uploads]


def test_a_reload_finds_its_own_session_and_an_ended_one_keeps_the_view(small_studio):
    """A tab whose page is asked for again after its websocket closed (a reload) keeps its process past the close's
    grace; a tab that only closed loses it, and its link then leads to a fresh studio with the link's view."""
    from explorer.serving.pool import RECONNECT_GRACE_S

    async def go():
        tab, pid = await _open_tab(small_studio)
        await tab.ws.close()
        assert (await tab.page_status())[0] == 200  # the reload's page
        await asyncio.sleep(RECONNECT_GRACE_S + 1.5)  # its scripts load and run
        await tab.connect()
        assert pid in _connected(small_studio) and not _gone(pid)  # the same process: the session is kept
        await tab.ws.close()
        _assert_ends_within(pid, RECONNECT_GRACE_S + 3.0)
        status, where = await tab.page_status("?seq=3&frame=7")
        await tab.http.close()
        return status, where

    assert asyncio.run(go()) == (302, "../../?seq=3&frame=7")


def test_the_pictures_are_sent_without_deflate_even_when_the_browser_asks(small_studio):
    """A browser asks for permessage-deflate; the proxy declines it (JPEG pictures gain nothing from it, and a tab
    closing mid-compression would leave an unretrieved send error), and the tab still works."""

    async def go():
        tab = RawTab(small_studio.url)
        aiohttp = __import__("aiohttp")
        tab.http = aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True))
        async with tab.http.post(tab.url + "claim", headers={"Origin": tab.origin}) as r:
            tab.path = (await r.json())["url"]
        await tab.connect(compress=15)
        negotiated, frames = tab.ws.compress, tab.state.get("num_frames")
        await tab.close()
        return negotiated, frames

    negotiated, frames = asyncio.run(go())
    assert negotiated == 0 and frames and frames > 0, (negotiated, frames)


# ---- what one websocket message may make a studio process hold or log -------------------------------------------


def _in_chunks(message_id: int, body: bytes, size: int = 4 << 20) -> list[bytes]:
    """A message in chunks as the page's client sends a large one (4 MB each)."""
    return [_chunk(message_id, offset, len(body), body[offset:offset + size]) for offset in range(0, len(body), size)]


async def _alert(tab: RawTab, timeout: float = 30.0) -> str:
    """The next one-line alert the page is shown (state `error`)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        message = await tab.receive(deadline - time.monotonic())
        changed = message.get("result") if message.get("id", "").startswith("publish:trame.state.topic") else None
        if changed and changed.get("error"):
            return changed["error"]
    raise TimeoutError("no alert")


def _log_lines_with(studio, marker: str, count: int, timeout: float = 20.0) -> list[str]:
    deadline = time.monotonic() + timeout
    while len(found := [ln for ln in list(studio.lines) if marker in ln]) < count and time.monotonic() < deadline:
        time.sleep(0.1)
    return found


def test_a_message_is_measured_from_its_headers_before_it_is_unpacked():
    """Every msgpack type is stepped over at its true size (a count off by one anywhere would shift the rest); a
    16 MB array of 16 M empty maps, many arrays each small, and 2,000,000 levels of nesting are refused; the page's
    largest message (a 20 MB upload) is not."""
    import msgpack

    from explorer.trame_adapter import MAX_MESSAGE_DEPTH, MAX_MESSAGE_OBJECTS, message_shape_problem

    every_type = [0, 127, -1, -32, 200, 70_000, 2**40, -100, -40_000, -2**40, 1.5, None, True, False, "", "x" * 31,
                  "y" * 40, "z" * 300, "w" * 70_000, b"", b"b" * 300, b"c" * 70_000, msgpack.ExtType(1, b"1"),
                  msgpack.ExtType(2, b"22"), msgpack.ExtType(3, b"4444"), msgpack.ExtType(4, b"8" * 8),
                  msgpack.ExtType(5, b"6" * 16), msgpack.ExtType(6, b"e" * 3), msgpack.ExtType(7, b"f" * 300),
                  msgpack.ExtType(8, b"g" * 70_000), {"k": [[]]}, list(range(20)), {str(i): i for i in range(20)},
                  [0] * 70_000]  # fmt: skip
    body = msgpack.packb(every_type, use_single_float=False)
    values = 1 + len(every_type) + 3 + 20 + 40 + 70_000  # the list, its items, {"k": [[]]}'s 3, the inner lists' items
    assert message_shape_problem(body, max_objects=values) is None
    assert "more than" in message_shape_problem(body, max_objects=values - 1)
    assert message_shape_problem(msgpack.packb([1.5], use_single_float=True), max_objects=2) is None

    maps = b"\xdd" + (16_000_000).to_bytes(4, "big") + b"\x80" * 16_000_000
    assert message_shape_problem(maps) == f"it holds more than {MAX_MESSAGE_OBJECTS} values"
    assert "values" in message_shape_problem(msgpack.packb([[{}] * 1000] * 200))  # each list under any per-list limit
    deep = b"\x91" * 2_000_000 + b"\xc0"
    assert message_shape_problem(deep) == f"it is nested more than {MAX_MESSAGE_DEPTH} levels deep"
    assert message_shape_problem(b"\x91" * (MAX_MESSAGE_DEPTH - 1) + b"\xc0") is None
    upload = {"wslink": "1.0", "id": "rpc:c0:9", "method": "trame.state.update", "kwargs": {},
              "args": [[{"key": "upload_file", "value": {"name": "take.bvh", "size": 20_000_000, "type": "",
                                                         "lastModified": 0, "content": b"\0" * 20_000_000}}]]}  # fmt: skip
    assert message_shape_problem(msgpack.packb(upload)) is None


def test_a_message_that_would_unpack_to_too_much_is_refused_in_one_line_and_the_tab_stays(small_studio):
    """16 M empty maps in one 16 MB message (gigabytes once unpacked) and a message nested 2,000,000 deep: each is
    refused in one line, shown to the page, while the process grows by less than 150 MB; the tab then still answers."""

    async def go():
        tab, pid = await _open_tab(small_studio)
        before = _memory_mb(pid, "VmHWM")
        maps = b"\xdd" + (16_000_000).to_bytes(4, "big") + b"\x80" * 16_000_000
        alerts = []
        for message_id, body in ((901, maps), (902, b"\x91" * 2_000_000 + b"\xc0")):
            for chunk in _in_chunks(message_id, body):
                await tab.ws.send_bytes(chunk)
            alerts.append(await _alert(tab))
        peak = _memory_mb(pid, "VmHWM")
        answer = await tab.call(tab._id(), "trame.state.get", [])
        await tab.close()
        return alerts, peak - before, answer, pid

    alerts, grown, answer, pid = asyncio.run(go())
    _assert_ends_within(pid, 5.0)  # its slot is free for the next test
    assert alerts == ["refused a message from this page: it holds more than 100000 values",
                      "refused a message from this page: it is nested more than 64 levels deep"], alerts
    assert grown < 150, grown
    assert answer["result"]["state"]["num_frames"] > 0
    assert not [ln for ln in small_studio.lines if "Traceback" in ln or "StackError" in ln], small_studio.lines


def test_a_client_sets_only_the_pages_state_keys_and_its_text_is_logged_capped(small_studio):
    """2000 new state keys are not kept (a key the page has, sent with them, is); a 100 k-character text frame, error
    report and trigger name are logged in one line of a few hundred characters each."""

    async def go():
        tab, pid = await _open_tab(small_studio)
        junk = [{"key": f"junk{i}_" + "x" * 100, "value": "y" * 1000} for i in range(2000)]
        await tab.send(tab._id(), "trame.state.update", [[*junk, {"key": "show_keys", "value": True}]])
        await tab.ws.send_str("text-frame-marker" + "T" * 100_000)
        await tab.call(tab._id(), "trame.error.client", ["page-error-marker" + "E\n" * 50_000])
        await tab.call(tab._id(), "trame.trigger", ["trigger-marker" + "N" * 100_000, [], {}])
        state = (await tab.call(tab._id(), "trame.state.get", []))["result"]["state"]
        await tab.close()
        return state, pid

    state, pid = asyncio.run(go())
    _assert_ends_within(pid, 5.0)
    assert not [key for key in state if key.startswith("junk")]
    assert state["show_keys"] is True
    for marker in ("text-frame-marker", "page-error-marker", "trigger-marker", "junk0_"):
        (line,) = _log_lines_with(small_studio, marker, 1)
        assert len(line) < 500, line


def test_a_frame_larger_than_a_studio_takes_is_refused_by_the_proxy(small_studio):
    """A 12 MB frame (the studio process takes 10 MB): the proxy closes that websocket as too big, itself, and
    nothing in the log says an error went unretrieved."""
    import aiohttp

    async def go():
        tab, pid = await _open_tab(small_studio)
        body = b"\xc6" + (12_000_000).to_bytes(4, "big") + b"\0" * 12_000_000
        with contextlib.suppress(ConnectionError):  # the proxy may close before the whole frame is written
            await tab.ws.send_bytes(_chunk(903, 0, len(body), body))
        while (closed := await tab.ws.receive(timeout=30)).type == aiohttp.WSMsgType.BINARY:
            pass  # pictures sent before the close
        await tab.close()
        return closed, pid

    closed, pid = asyncio.run(go())
    assert closed.type == aiohttp.WSMsgType.CLOSE and closed.data == 1009, closed
    _assert_ends_within(pid, 10.0)
    assert not [ln for ln in small_studio.lines if "never retrieved" in ln or "Traceback" in ln], small_studio.lines


# ---- slots --------------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_a_script_posting_claims_cannot_keep_a_tab_from_a_studio(small_studio):
    """A local script with the page's Origin posts 4 claims a second for 8 s and never asks for a page: before, it
    held both slots and the next tab got 503. The next tab gets a studio, and it works."""
    import aiohttp

    statuses = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < 8.0:
        statuses.append(_claim_status(small_studio.url))
        time.sleep(0.25)
    assert statuses.count(200) >= 4, statuses  # the script did get studios

    async def go():  # the front page's claim, tried again a second after a rate-limited answer, with its cookie
        tab = RawTab(small_studio.url)
        tab.http = aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True))
        deadline = time.monotonic() + 15
        while True:
            async with tab.http.post(tab.url + "claim", headers={"Origin": tab.origin}) as r:
                if r.status != 429 or time.monotonic() > deadline:
                    assert r.status == 200, await r.text()
                    tab.path = (await r.json())["url"]
                    break
            await asyncio.sleep(1.0)
        await tab.connect()
        frames = tab.state.get("num_frames")
        await tab.close()
        return frames

    assert asyncio.run(go()) > 0


# ---- exports ------------------------------------------------------------------------------------------------------


def test_one_tab_may_export_only_so_often_and_save_only_so_much(tmp_path, monkeypatch):
    """Past EXPORTS_PER_MINUTE, an export is refused in one line before any work; past SAVED_BYTES a tab's exports
    are downloads only, said in the notice, and nothing more lands in the export folder."""
    from types import SimpleNamespace

    from explorer.ui import exports as exports_module

    monkeypatch.setattr(exports_module, "SAVED_BYTES", 5_000)
    made = []
    session = SimpleNamespace(files=SimpleNamespace(name=lambda ext: f"take.{ext}", bvh=lambda character: made.append(1) or b"b" * 1000))
    triggers = {}
    page = SimpleNamespace(session=session, state=SimpleNamespace(notice=""), guarded=lambda fn: fn,
                           trigger=lambda name: (lambda fn: triggers.__setitem__(name, fn)))  # fmt: skip
    exports_module.Exports(page, None, tmp_path, attach=bytes)
    downloads = [triggers["export_bvh"]("follower") for _ in range(exports_module.EXPORTS_PER_MINUTE)]
    assert downloads == [b"b" * 1000] * exports_module.EXPORTS_PER_MINUTE
    assert len(list(tmp_path.iterdir())) == 5 and page.state.notice.startswith("download only"), page.state.notice
    with pytest.raises(ValueError, match=r"^export refused: at most 20 exports a minute from one tab \(try again in \d+ s\)$"):
        triggers["export_bvh"]("follower")
    assert len(made) == exports_module.EXPORTS_PER_MINUTE  # refused before the file was made


# ---- stopping -----------------------------------------------------------------------------------------------------


def _descendants(pid: int) -> list[int]:
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        try:
            children = [int(c) for task in Path(f"/proc/{parent}/task").iterdir() for c in (task / "children").read_text().split()]
        except OSError:  # it has just exited
            continue
        found += children
        todo += children
    return found


@pytest.mark.slow
def test_sigterm_with_two_tabs_open_leaves_no_studio_process_after_5_s(tmp_path):
    """It took 32 s: the web server waited on the tabs' open relays before the studio processes were stopped."""
    from tests.studio_probe import StudioProcess

    with StudioProcess("--max-clients", "3", cache_dir=tmp_path) as studio:

        async def go():
            tabs = [(await _open_tab(studio))[0] for _ in range(2)]
            processes = _descendants(studio.proc.pid)  # the zygote, the studio processes and their upload readers
            studio.proc.send_signal(signal.SIGTERM)
            deadline = time.monotonic() + 5.0
            while (studio.proc.poll() is None or not all(map(_gone, processes))) and time.monotonic() < deadline:
                await asyncio.sleep(0.05)
            for tab in tabs:
                await tab.http.close()
            return studio.proc.poll(), len(processes), [p for p in processes if not _gone(p)]

        code, count, left = asyncio.run(go())
    assert count >= 4 and code == 0 and not left, (count, code, left)


def test_a_late_layout_note_is_one_capped_printable_line_and_only_from_the_tabs_own_page(small_studio):
    """POST /s/<token>/layout-late (a page about to reload because its layout never came): the tab's own page is
    answered 204 and its note logged in one line, at most 600 characters of it, control characters made printable;
    a bare POST, another browser (no cookie) or an unknown token is refused 403 and logs nothing."""
    import aiohttp

    from tests.studio_probe import StudioProcess

    async def go():
        tab, _ = await _open_tab(small_studio)
        note = tab.url + tab.path + "layout-late"
        try:
            async with tab.http.post(note, data=b"\x1b[31m/evil.css\n" + b"x" * 5000, headers={"Origin": tab.origin}) as r:
                own = r.status
            async with aiohttp.ClientSession() as stranger:  # no cookie of the claiming browser
                async with stranger.post(note, data=b"/y.css", headers={"Origin": tab.origin}) as r:
                    other = r.status
            async with tab.http.post(tab.url + "s/unknown-token/layout-late", data=b"/z.css", headers={"Origin": tab.origin}) as r:
                unknown = r.status
        finally:
            await tab.close()
        return own, other, unknown

    assert asyncio.run(go()) == (204, 403, 403)
    said = [ln for ln in small_studio.read_log() if ln.startswith("a tab's page was loaded again")]
    assert len(said) == 1 and "\x1b" not in said[0] and "?[31m/evil.css?xxx" in said[0], said
    assert said[0].count("x") < 700 and "/y.css" not in said[0] and "/z.css" not in said[0]
    StudioProcess.noticed.remove(small_studio)  # expected here: not a fault for the run's summary


def test_a_closing_tab_leaves_no_traceback_in_the_log(small_studio):
    """Tabs closed while pictures were streaming to them (the tests above): the proxy logs no unretrieved
    connection-reset error or any other traceback."""
    assert not [ln for ln in small_studio.lines if "Traceback" in ln or "never retrieved" in ln], small_studio.lines
