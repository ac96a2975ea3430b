"""Bad input to the studio benchmark's --checkpoint: one line naming the problem, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARK = Path(__file__).resolve().parents[1] / "benchmarks" / "explorer_latency.py"


def run_benchmark(checkpoint: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCHMARK), "--checkpoint", str(checkpoint), "--trials", "1"],
                          capture_output=True, text=True, timeout=300)


def test_a_missing_checkpoint_is_one_line_before_anything_starts(tmp_path):
    out = run_benchmark(tmp_path / "nowhere.safetensors")
    assert out.returncode != 0
    assert "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1].endswith(f"checkpoint not found: {tmp_path / 'nowhere.safetensors'}")
    assert "model:" not in out.stdout  # refused before any studio or browser started


def test_a_corrupt_checkpoint_ends_the_run_in_one_line(tmp_path):
    if not os.path.exists("/usr/bin/chromium"):
        pytest.skip("needs /usr/bin/chromium (apt-get install -y chromium)")
    pytest.importorskip("playwright.sync_api")
    corrupt = tmp_path / "corrupt.safetensors"
    corrupt.write_bytes(b"\xff" * 2000)  # not a safetensors header
    out = run_benchmark(corrupt)
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("explorer_latency: studio did not start:") and "not a readable safetensors checkpoint" in last


@pytest.mark.parametrize("script, args, says", [
    ("online_reactor.py", ["--live-steps", "0"], "--live-steps, --leaders, --repeats and --threads must be at least 1"),
    ("online_reactor.py", ["--online-windows", "1"], "--online-windows at least 2"),
    ("page_render_cost.py", ["--repeats", "1"], "--repeats must be at least 2"),
    ("page_load_profile.py", ["--loads", "0"], "--loads and --top must be at least 1"),
    ("forked_first_moves.py", ["--moves", "0"], "--moves and --children must be at least 1"),
    ("first_move_stages.py", ["--moves", "2", "--rest", "3"], "--tabs must be at least 1, --moves at least 2 (3 with --rest"),
    ("plotly_bundle.py", ["--rounds", "0"], "--rounds must be at least 1"),
    ("plotly_bundle.py", ["--other", "no/such/plotly.min.js"], "--other: no file no/such/plotly.min.js"),
    ("latent_map_fit.py", ["--busy", "-1"], "--busy must be at least 0 and --rounds at least 1"),
    ("latent_map_fit.py", ["--rounds", "0"], "--busy must be at least 0 and --rounds at least 1"),
])
def test_out_of_range_benchmark_arguments_are_one_line_before_anything_loads(script, args, says):
    out = subprocess.run([sys.executable, str(BENCHMARK.parent / script), *args], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert says in out.stderr.strip().splitlines()[-1]
