"""`imm explore` with bad input: a one-line message and exit code 2, never a traceback."""

from __future__ import annotations

import dataclasses
import socket
import subprocess
import sys
import time

import pytest

from imm_model.paths import SAMPLE_GAN, SAMPLE_JUDGE, SAMPLE_UPPER_JUDGE

pytest.importorskip("trame")


def run_explore(*args: str, timeout: float = 90) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "imm_model.cli", "explore", "--no-browser", "--port", "0", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def assert_one_line_error(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("imm explore: error: ")
    assert "Traceback" not in proc.stderr + proc.stdout
    for n in needles:
        assert n in lines[0], lines[0]


def test_help_lists_options():
    out = subprocess.run([sys.executable, "-m", "imm_model.cli", "explore", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for opt in ("--data", "--model", "--port", "--host", "--no-browser"):
        assert opt in out.stdout


def test_missing_data_file(tmp_path):
    assert_one_line_error(run_explore("--data", str(tmp_path / "nope.npz")), "data file not found", "nope.npz")


def test_missing_checkpoint(tmp_path):
    assert_one_line_error(run_explore("--model", f"mine={tmp_path / 'nope.safetensors'}"), "--model mine: checkpoint not found")


def test_unknown_start_sequence_and_bad_judge(tmp_path):
    assert_one_line_error(run_explore("--sequence", "nonexistent", "--cache-dir", str(tmp_path)), "no such sequence")
    assert_one_line_error(run_explore("--judge", str(tmp_path / "nope.safetensors")), "judge not found")


@pytest.mark.skipif(not SAMPLE_JUDGE.exists(), reason="bundled judge missing")
def test_a_judge_with_nan_weights_is_refused(tmp_path):
    """Its probabilities would all be NaN: the 'reads as' panel would read nothing, without a word."""
    import numpy as np
    import torch

    from imm_model.checkpoint import load_checkpoint, save_checkpoint

    arrays, meta = load_checkpoint(SAMPLE_JUDGE, framework="np")
    weights = {name: torch.from_numpy(np.full_like(a, np.nan) if a.dtype.kind == "f" else a) for name, a in arrays.items()}
    save_checkpoint(tmp_path / "nan.safetensors", weights, meta)
    assert_one_line_error(run_explore("--judge", str(tmp_path / "nan.safetensors"), "--cache-dir", str(tmp_path)),
                          "nan.safetensors: weights that are not finite numbers")


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
@pytest.mark.parametrize("given, words", [(["--model", "gan"], "expected NAME=CHECKPOINT"),
                                          (["--model", "a b=x.safetensors"], "expected NAME=CHECKPOINT"),
                                          (["--model", f"gan={SAMPLE_GAN}", "--model", f"gan={SAMPLE_GAN}"],
                                           "--model gan: given twice")])
def test_a_bad_model_option_is_one_line(tmp_path, given, words):
    assert_one_line_error(run_explore(*given, "--cache-dir", str(tmp_path)), words)


def test_corrupt_checkpoint(tmp_path):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"\x00" * 64)
    assert_one_line_error(run_explore("--model", f"bad={bad}", "--cache-dir", str(tmp_path)), "bad.safetensors")


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_checkpoint_not_matching_data_classes(tmp_path, sample_data):
    other = dataclasses.replace(sample_data, class_names=tuple(f"class_{i}" for i in range(len(sample_data.class_names))))
    path = tmp_path / "other_classes.npz"
    other.save(path)
    assert_one_line_error(run_explore("--data", str(path), "--cache-dir", str(tmp_path)), "do not match the data's", "class_0")


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_checkpoint_not_matching_data_skeleton(tmp_path, sample_data):
    sk = sample_data.skeleton
    other_sk = dataclasses.replace(sk, name="renamed", joint_names=tuple(f"j{i}" for i in range(sk.num_joints)))
    path = tmp_path / "other_skeleton.npz"
    dataclasses.replace(sample_data, skeleton=other_sk).save(path)
    assert_one_line_error(run_explore("--data", str(path), "--cache-dir", str(tmp_path)), "skeleton", "renamed")


def test_bad_base_url():
    assert_one_line_error(run_explore("--base-url", "ftp://example.org/imm/"), "--base-url must start with http")


def test_port_in_use():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        proc = subprocess.run(
            [sys.executable, "-m", "imm_model.cli", "explore", "--no-browser", "--port", str(port)],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert_one_line_error(proc, f"port {port}", "already in use")


def _claim(host: str, port: int, origin: str | None = "same", host_header: str | None = None, cookie: str | None = None):
    import http.client
    import json

    conn = http.client.HTTPConnection(host, port, timeout=60)
    headers = {"Host": host_header or f"{host}:{port}"}
    if origin is not None:
        headers["Origin"] = f"http://{host}:{port}" if origin == "same" else origin
    if cookie is not None:
        headers["Cookie"] = cookie
    conn.request("POST", "/claim", headers=headers)
    r = conn.getresponse()
    body = r.read().decode()
    if r.status != 200:
        return r.status, body
    answer = json.loads(body)
    answer["cookie"] = r.getheader("Set-Cookie").split(";")[0]  # the claiming browser's: its tab answers only it
    return r.status, answer


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_launcher_hands_out_processes_only_to_its_own_page(tmp_path):
    """Bare GETs take no studio process (twenty of them, then a claim still gets one at once); a claim from another
    web origin or for another host name is refused; a claim's studio is served on the launcher's own port; past
    --max-clients the page says so in one line."""
    import http.client
    from urllib.parse import urlsplit

    from tests.studio_probe import StudioProcess

    with StudioProcess("--max-clients", "1", cache_dir=tmp_path) as studio:
        u = urlsplit(studio.url)
        conn = http.client.HTTPConnection(u.hostname, u.port, timeout=60)
        for _ in range(20):
            conn.request("GET", "/")
            r = conn.getresponse()
            assert r.status == 200 and 'fetch("claim"' in r.read().decode()
        assert _claim(u.hostname, u.port, origin="http://evil.example.com")[0] == 403
        assert _claim(u.hostname, u.port, host_header=f"evil.example.com:{u.port}")[0] == 403  # DNS rebinding
        status, answer = _claim(u.hostname, u.port)
        assert status == 200 and answer["url"].startswith("s/")  # on the launcher's own port: single-port serving
        conn.request("GET", "/" + answer["url"] + "index.html")  # another browser (no claim cookie): a studio of its own
        elsewhere = conn.getresponse()
        assert elsewhere.status == 302 and elsewhere.getheader("Location") == "../../"
        elsewhere.read()
        conn.request("GET", "/" + answer["url"] + "index.html", headers={"Cookie": answer["cookie"]})
        page = conn.getresponse()
        assert page.status == 200 and "<base href" in page.read().decode()
        conn.request("GET", "/s/not-a-session/index.html")
        stale = conn.getresponse()
        stale.read()
        assert stale.status == 302  # an unknown or old link goes back to the front page
        status, body = _claim(u.hostname, u.port)
        assert status == 503 and "maximum of 1 clients" in body


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_a_lost_loader_is_one_line_not_a_hang(tmp_path):
    """The zygote killed (out of memory, say): its studio processes go with it, and a new tab is told so at once."""
    import os
    import signal
    from pathlib import Path
    from urllib.parse import urlsplit

    from tests.studio_probe import StudioProcess

    with StudioProcess(cache_dir=tmp_path) as studio:
        u = urlsplit(studio.url)
        zygote = int(Path(f"/proc/{studio.proc.pid}/task/{studio.proc.pid}/children").read_text().split()[0])
        os.kill(zygote, signal.SIGKILL)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            status, body = _claim(u.hostname, u.port)
            if status != 200:
                break
            time.sleep(0.2)  # the spare was still up: it exits when its stdin (from the dead zygote) closes
        assert status == 503 and "stopped with exit code" in body and "restart imm explore" in body, body
        assert studio.proc.poll() is None  # the launcher itself stays up and answers


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
@pytest.mark.slow
def test_a_claim_nobody_connects_to_is_released(tmp_path, monkeypatch):
    """A tab that claims a process, loads its page and never connects (closed at once) does not hold the only slot
    for long. (A claim whose page is never asked for goes sooner: tests/test_studio_hardening.py.)"""
    import time
    import urllib.request
    from urllib.parse import urlsplit

    from tests.studio_probe import StudioProcess

    monkeypatch.setenv("IMM_STUDIO_CLAIM_TIMEOUT", "2")
    with StudioProcess("--max-clients", "1", cache_dir=tmp_path) as studio:
        u = urlsplit(studio.url)
        status, answer = _claim(u.hostname, u.port)
        assert status == 200
        request = urllib.request.Request(studio.url + answer["url"], headers={"Cookie": answer["cookie"]})  # the claiming browser
        with urllib.request.urlopen(request, timeout=60) as page:
            assert page.status == 200
        assert _claim(u.hostname, u.port)[0] == 503
        deadline = time.monotonic() + 30
        while _claim(u.hostname, u.port)[0] != 200:
            assert time.monotonic() < deadline, "the unconnected claim was never released"
            time.sleep(1.0)



@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_a_token_guards_the_front_page_the_claim_and_the_studio(tmp_path):
    """With --token only the printed URL opens the studio; its cookie then admits the claim and the studio."""
    import http.client
    from urllib.parse import urlsplit

    from tests.studio_probe import StudioProcess

    with StudioProcess("--token", "s3cret-token", cache_dir=tmp_path) as studio:
        u = urlsplit(studio.url)
        assert u.query == "token=s3cret-token"
        conn = http.client.HTTPConnection(u.hostname, u.port, timeout=60)

        def get(path: str, cookie: str | None = None):
            conn.request("GET", path, headers={"Cookie": cookie} if cookie else {})
            r = conn.getresponse()
            r.read()
            return r

        assert get("/").status == 403 and get("/?token=wrong-token").status == 403
        first = get("/?token=s3cret-token")
        assert first.status == 200 and "HttpOnly" in first.getheader("Set-Cookie")
        cookie = first.getheader("Set-Cookie").split(";")[0]
        assert _claim(u.hostname, u.port)[0] == 403
        status, answer = _claim(u.hostname, u.port, cookie=cookie)
        assert status == 200
        assert get("/" + answer["url"] + "index.html").status == 403
        assert get("/" + answer["url"] + "index.html", cookie=f"{cookie}; {answer['cookie']}").status == 200


def test_a_network_host_needs_a_token_or_no_auth(capsys):
    import argparse

    from explorer.commands import access

    args = lambda **kw: argparse.Namespace(**({"host": "127.0.0.1", "token": None, "no_auth": False} | kw))  # noqa: E731
    assert access(args()) == (None, False)  # loopback: no token unless asked for
    token, no_auth = access(args(host="0.0.0.0"))
    assert len(token) >= 24 and not no_auth and "exposes the studio" in capsys.readouterr().err
    assert access(args(host="0.0.0.0", token="my-long-token")) == ("my-long-token", False)
    assert access(args(host="0.0.0.0", no_auth=True)) == (None, True) and "--no-auth" in capsys.readouterr().err
    with pytest.raises(ValueError, match="at least 8"):
        access(args(token="short"))


def _hello(port: int, secret: str) -> dict:
    """One wslink hello straight to a studio process's own port -> its answer."""
    import asyncio

    import aiohttp
    import msgpack

    from explorer.serving.proxy import HEADER

    async def go():
        body = msgpack.packb({"wslink": "1.0", "id": "system:c0:0", "method": "wslink.hello", "args": [{"secret": secret}]})
        frame = (7).to_bytes(4, "little") + (0).to_bytes(4, "little") + len(body).to_bytes(4, "little") + body
        async with aiohttp.ClientSession() as session, session.ws_connect(f"http://127.0.0.1:{port}/ws") as ws:
            await ws.send_bytes(frame)
            msg = await ws.receive(timeout=30)
            return msgpack.unpackb(msg.data[HEADER:])

    return asyncio.run(go())


@pytest.mark.skipif(not SAMPLE_GAN.exists(), reason="bundled checkpoint missing")
def test_a_studio_process_answers_only_its_own_secret(tmp_path):
    """Another local user who finds a studio process's loopback port cannot log in with wslink's public default;
    the proxy puts the process's own secret into the browser's hello. Also the zygote's protocol: studio processes
    forked on request, each with its own secret, and all gone when the launcher's end of the pipe closes."""
    from explorer.serving.proxy import with_secret
    from imm_model.paths import SAMPLE_DATA

    cmd = [sys.executable, "-m", "explorer.serving.zygote", "--data", str(SAMPLE_DATA), "--model", f"gan={SAMPLE_GAN}",
           "--cache-dir", str(tmp_path), "--port", "0"]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "IMM-WORKER LOADED"
        proc.stdin.write("spawn 7 the-process-secret\nspawn 8 another-secret\n")
        proc.stdin.flush()
        ready = dict(proc.stdout.readline().split()[2:4] for _ in range(2))  # READY <id> <port>, in either order
        assert set(ready) == {"7", "8"} and ready["7"] != ready["8"]
        assert "error" in _hello(int(ready["7"]), "wslink-secret")
        assert "error" in _hello(int(ready["7"]), "another-secret")
        assert _hello(int(ready["7"]), "the-process-secret")["result"]["clientID"]
        assert _hello(int(ready["8"]), "another-secret")["result"]["clientID"]
        proc.stdin.close()  # the launcher is gone: every studio process exits, then the zygote
        assert proc.wait(20) == 0
        for port in ready.values():  # each studio process shuts its server down; on a busy machine that takes a while
            deadline = time.monotonic() + 15
            with pytest.raises(OSError):
                while time.monotonic() < deadline:
                    socket.create_connection(("127.0.0.1", int(port)), timeout=5).close()
                    time.sleep(0.2)
    finally:
        proc.kill()
    import msgpack

    hello = msgpack.packb({"id": "system:c0:0", "method": "wslink.hello", "args": [{"secret": "wslink-secret"}]})
    frame = (9).to_bytes(4, "little") + (0).to_bytes(4, "little") + len(hello).to_bytes(4, "little") + hello
    rewritten = with_secret(frame, "s3")
    assert msgpack.unpackb(rewritten[12:])["args"][0]["secret"] == "s3" and rewritten[:4] == frame[:4]
    assert with_secret(b"\x00" * 20, "s3") == b"\x00" * 20  # anything else passes unchanged


def test_explore_without_fork_says_so_in_one_line(monkeypatch, capsys):
    """Windows has no fork(), which the studio's processes come from: one line, exit 2, nothing started."""
    import os

    from imm_model.cli import main

    monkeypatch.delattr(os, "fork")
    assert main(["explore", "--no-browser", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "needs a system with fork()" in err and len(err.strip().splitlines()) == 1


def test_explore_without_the_studio_extra_says_how_to_install_it(monkeypatch, capsys):
    import importlib.util

    from imm_model.cli import main

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "aiohttp" else real(name, *a))
    assert main(["explore", "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'imm-studio[studio]'" in err and "aiohttp" in err and len(err.strip().splitlines()) == 1


def test_the_next_spare_waits_for_quiet_tabs(monkeypatch):
    """A claimed spare is replaced once the websocket has been quiet, not in the middle of a user's slider moves;
    another tab asking starts it at once, and constant traffic (playback) delays it only up to a limit."""
    import asyncio

    from explorer.serving import pool
    from explorer.serving.launcher import LaunchConfig
    from explorer.serving.pool import WorkerPool
    from imm_model.paths import SAMPLE_DATA

    delay, quiet_s, latest = 0.05, 0.3, 2.5
    monkeypatch.setattr(pool, "SPARE_DELAY_S", delay)
    monkeypatch.setattr(pool, "SPARE_QUIET_S", quiet_s)
    monkeypatch.setattr(pool, "SPARE_LATEST_S", latest)

    async def until_due(traffic_s: float, wanted_after_s: float | None = None) -> tuple[float, float]:
        """-> (seconds from the claim until the next spare is due, seconds since the last message then)"""
        front = WorkerPool(LaunchConfig(data=SAMPLE_DATA, models=(("gan", SAMPLE_GAN),)))  # nothing is started
        t0 = time.monotonic()
        due = asyncio.ensure_future(front._spare_due())
        while time.monotonic() - t0 < traffic_s and not due.done():
            front.note_traffic()
            if wanted_after_s is not None and time.monotonic() - t0 > wanted_after_s:
                front.spare_wanted.set()
            await asyncio.sleep(0.05)  # a message every 50 ms
        await due
        now = time.monotonic()
        return now - t0, now - front.last_traffic

    # Lower bounds and which rule fired, no tight upper bounds: a busy machine only makes each wait longer (a stalled
    # process wakes the traffic's earlier timer first, so constant traffic never looks quiet).
    (quiet, _), (busy, busy_quiet), (asked, _), (endless, _) = (
        asyncio.run(until_due(*a)) for a in ((0,), (0.6,), (60, 0.2), (60,)))
    assert delay <= quiet < latest  # no traffic: SPARE_DELAY_S after the claim
    assert busy_quiet >= quiet_s and busy < latest  # 0.6 s of messages, then SPARE_QUIET_S of quiet
    assert 0.2 <= asked < latest  # another tab asked: at once, in the middle of the traffic
    assert latest <= endless < 60  # never quiet: SPARE_LATEST_S after the claim


@pytest.mark.skipif(not SAMPLE_UPPER_JUDGE.exists(), reason="bundled body-part judge missing")
def test_a_body_part_judge_is_refused_as_the_whole_followers_judge(tmp_path):
    """Its reading of the trunk and arms would be shown as the whole follower's."""
    assert_one_line_error(run_explore("--judge", str(SAMPLE_UPPER_JUDGE), "--cache-dir", str(tmp_path)),
                          "upper_judge.safetensors: a judge of the upper body alone; --judge takes one that reads the whole")


def test_control_characters_in_a_path_are_shown_escaped_on_one_line(tmp_path):
    """A newline or an escape sequence in a file name never splits the line nor acts on the terminal."""
    proc = run_explore("--model", f"mine={tmp_path}/a\nb\x1b[2J.safetensors")
    assert_one_line_error(proc, "--model mine: checkpoint not found", "a\\nb\\x1b[2J.safetensors")
    assert "\x1b" not in proc.stderr
    assert_one_line_error(run_explore("--data", f"{tmp_path}/x\ny.npz"), "data file not found", "x\\ny.npz")


def test_a_tab_gone_before_its_page_is_answered_leaves_no_error(caplog):
    """The launcher forwarding a tab's request to its studio process: a tab closed while the studio process is still
    answering (before the answer's headers could go out) is no error, and nothing is logged as one."""
    import asyncio
    import logging

    from aiohttp import web

    from explorer.serving.proxy import forward_http

    async def serve(handler) -> tuple[web.AppRunner, int]:
        app = web.Application()
        app.router.add_get("/{tail:.*}", handler)
        runner = web.AppRunner(app)
        await runner.setup()
        site = web.TCPSite(runner, "127.0.0.1", 0)
        await site.start()
        return runner, site._server.sockets[0].getsockname()[1]

    async def go() -> None:
        closed, forwarded = asyncio.Event(), asyncio.Event()

        async def studio_process(request):
            await closed.wait()  # answers only once the tab has gone
            await asyncio.sleep(0.1)
            return web.Response(text="the page")

        async def launcher(request):
            try:
                return await forward_http(request, studio_port, request.match_info["tail"], answer_s=10)
            finally:
                forwarded.set()

        studio, studio_port = await serve(studio_process)
        front, port = await serve(launcher)
        try:
            _, writer = await asyncio.open_connection("127.0.0.1", port)
            writer.write(b"GET /s/token/index.html HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            await writer.drain()
            writer.close()  # the tab is closed
            closed.set()
            await asyncio.wait_for(forwarded.wait(), 10)
            await asyncio.sleep(0.2)  # aiohttp finishes the request (and would log its error) after the handler returns
        finally:
            await front.cleanup()
            await studio.cleanup()

    with caplog.at_level(logging.DEBUG, logger="aiohttp"):
        asyncio.run(go())
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR or r.exc_info], [r.getMessage() for r in caplog.records]
