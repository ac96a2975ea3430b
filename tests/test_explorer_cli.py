"""`imm explore` with bad input: a one-line message and exit code 2, never a traceback."""

from __future__ import annotations

import dataclasses
import socket
import subprocess
import sys

import pytest

from imm_model.paths import SAMPLE_CHECKPOINT

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
    for opt in ("--data", "--checkpoint", "--port", "--host", "--no-browser"):
        assert opt in out.stdout


def test_missing_data_file(tmp_path):
    assert_one_line_error(run_explore("--data", str(tmp_path / "nope.npz")), "data file not found", "nope.npz")


def test_missing_checkpoint(tmp_path):
    assert_one_line_error(run_explore("--checkpoint", str(tmp_path / "nope.safetensors")), "checkpoint not found")


def test_unknown_start_sequence_and_bad_judge(tmp_path):
    assert_one_line_error(run_explore("--sequence", "nonexistent", "--cache-dir", str(tmp_path)), "no such sequence")
    assert_one_line_error(run_explore("--judge", str(tmp_path / "nope.safetensors")), "judge not found")


def test_corrupt_checkpoint(tmp_path):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"\x00" * 64)
    assert_one_line_error(run_explore("--checkpoint", str(bad), "--cache-dir", str(tmp_path)), "bad.safetensors")


@pytest.mark.skipif(not SAMPLE_CHECKPOINT.exists(), reason="bundled checkpoint missing")
def test_checkpoint_not_matching_data_classes(tmp_path, sample_data):
    other = dataclasses.replace(sample_data, class_names=tuple(f"class_{i}" for i in range(len(sample_data.class_names))))
    path = tmp_path / "other_classes.npz"
    other.save(path)
    assert_one_line_error(run_explore("--data", str(path), "--cache-dir", str(tmp_path)), "do not match the data's", "class_0")


@pytest.mark.skipif(not SAMPLE_CHECKPOINT.exists(), reason="bundled checkpoint missing")
def test_checkpoint_not_matching_data_skeleton(tmp_path, sample_data):
    sk = sample_data.skeleton
    other_sk = dataclasses.replace(sk, name="renamed", joint_names=tuple(f"j{i}" for i in range(sk.num_joints)))
    path = tmp_path / "other_skeleton.npz"
    dataclasses.replace(sample_data, skeleton=other_sk).save(path)
    assert_one_line_error(run_explore("--data", str(path), "--cache-dir", str(tmp_path)), "skeleton", "renamed")


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


@pytest.mark.skipif(not SAMPLE_CHECKPOINT.exists(), reason="bundled checkpoint missing")
def test_launcher_redirects_and_reports_full_in_the_page(tmp_path):
    """Each visit gets its own studio process; past --max-clients the page says so in one line."""
    import http.client
    from urllib.parse import urlsplit

    from explorer.probe import StudioProcess

    with StudioProcess("--max-clients", "1", cache_dir=tmp_path) as studio:
        u = urlsplit(studio.url)
        conn = http.client.HTTPConnection(u.hostname, u.port, timeout=60)
        conn.request("GET", "/")
        first = conn.getresponse()
        first.read()
        assert first.status == 302
        worker = urlsplit(first.getheader("Location"))
        assert worker.port != u.port
        page = http.client.HTTPConnection(worker.hostname, worker.port, timeout=30)
        page.request("GET", "/index.html")
        assert page.getresponse().status == 200
        conn.request("GET", "/")
        second = conn.getresponse()
        body = second.read().decode()
        assert second.status == 503
        assert "maximum of 1 clients" in body
