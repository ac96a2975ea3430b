"""The wheel carries the library, the studio and sample_data/: installed into a fresh venv outside the checkout, it
runs `imm generate` and `imm explore` on the bundled data and models.

The fresh venv borrows the test interpreter's installed dependencies (a .pth naming its site-packages, whose own .pth
files, the checkout's editable install among them, are not read), so that the test needs no network and no minutes of
installing torch; imm-studio itself comes from the wheel only.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import sysconfig
import time
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """-> the bin folder of a fresh venv with the wheel of this checkout installed."""
    tmp = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp)],
                   check=True, capture_output=True, timeout=300)
    wheel = next(tmp.glob("imm_studio-*.whl"))
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    site = Path(subprocess.check_output([venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                        text=True).strip())
    (site / "borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([venv / "bin" / "python", "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel)],
                   check=True, capture_output=True, timeout=300)
    return venv / "bin"


def _env(tmp: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "IMM_SAMPLE_DIR")}
    return env | {"IMM_CACHE_DIR": str(tmp / "cache"), "OMP_NUM_THREADS": "1"}


@pytest.mark.slow
def test_the_installed_wheel_generates_from_its_own_copy_of_the_bundle(installed, tmp_path):
    where = subprocess.check_output([installed / "python", "-c", "import imm_model, explorer, imm_model.paths as p; "
                                     "print(imm_model.__file__, explorer.__file__, p.SAMPLE_DIR, sep='\\n')"],
                                    cwd=tmp_path, env=_env(tmp_path), text=True).split()
    venv = installed.parent.resolve()
    assert all(Path(w).resolve().is_relative_to(venv) for w in where), where  # nothing read from the checkout
    assert (Path(where[2]) / "imm_sbu.safetensors").is_file() and (Path(where[2]) / "imm_diffusion.safetensors").is_file()
    out = tmp_path / "reaction.bvh"
    run = subprocess.run([installed / "imm", "generate", "--sequence", "s01s02/03/001", "--label", "kicking=1", "--out", str(out)],
                         cwd=tmp_path, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert out.stat().st_size > 1000 and (tmp_path / "reaction.leader.bvh").is_file()


@pytest.mark.slow
def test_the_installed_wheel_serves_the_studio(installed, tmp_path):
    proc = subprocess.Popen([installed / "imm", "explore", "--port", "0", "--no-browser"], cwd=tmp_path, env=_env(tmp_path),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        deadline, url = time.monotonic() + 90, None
        while url is None and time.monotonic() < deadline and proc.poll() is None:
            line = proc.stdout.readline()
            if m := re.search(r"ready at (http://\S+)", line):
                url = m.group(1)
        assert url, f"no address printed (exit {proc.poll()})"
        with urllib.request.urlopen(url, timeout=30) as page:  # the page shell with the studio's scripts in it
            assert page.status == 200 and "<script>" in page.read().decode()
    finally:
        os.killpg(proc.pid, 15)
        proc.wait(30)
