"""How long a browser tab waits for its studio process: forked from the loaded zygote (what `imm explore` does) against
a process started from scratch for the tab (what wslink's launcher does: one `subprocess.Popen` of the app per
session, which then loads the libraries, data, models and latent map itself).

    python benchmarks/studio_process_start.py --runs 3

Prints, per run, the fresh process's time to its first READY (the zygote's own start plus its first fork: everything
a per-session process has to do before it serves) and the forked processes' times to READY, then the medians and
their ratio. Both are measured in the same run, on the bundled data and models.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from explorer.serving.worker import PREFIX  # noqa: E402
from imm_model.paths import SAMPLE_DATA, SAMPLE_MODELS  # noqa: E402


def wait_for(proc: subprocess.Popen, kind: str, wid: str | None = None) -> None:
    """Read the zygote's lines until `IMM-WORKER <kind> [<wid>]`."""
    for line in proc.stdout:
        words = line.split()
        if words[:2] == [PREFIX, kind] and (wid is None or words[2:3] == [wid]):
            return
        if words[:2] == [PREFIX, "ERROR"]:
            raise SystemExit(f"studio_process_start: error: {' '.join(words[2:])}")
    raise SystemExit("studio_process_start: error: the zygote ended before it said " + kind)


def one_run(tabs: int, cache_dir: Path) -> tuple[float, list[float]]:
    """-> (seconds from start to the first process READY, [seconds from 'spawn' to READY] for `tabs` more)."""
    cmd = [sys.executable, "-m", "explorer.serving.zygote", "--data", str(SAMPLE_DATA), "--cache-dir", str(cache_dir),
           "--export-dir", str(cache_dir / "exports")]
    cmd += [arg for name, path in SAMPLE_MODELS.items() if path.is_file() for arg in ("--model", f"{name}={path}")]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow"}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    try:
        wait_for(proc, "LOADED")
        proc.stdin.write("spawn 0 secret-0\n")
        proc.stdin.flush()
        wait_for(proc, "READY", "0")
        fresh = time.perf_counter() - t0
        forked = []
        for k in range(1, tabs + 1):
            t1 = time.perf_counter()
            proc.stdin.write(f"spawn {k} secret-{k}\n")
            proc.stdin.flush()
            wait_for(proc, "READY", str(k))
            forked.append(time.perf_counter() - t1)
        return fresh, forked
    finally:
        proc.stdin.close()
        proc.wait(30)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--tabs", type=int, default=3, help="forked processes per run, one after the other")
    ap.add_argument("--cache-dir", type=Path, default=Path.home() / ".cache" / "imm-studio",
                    help="the latent maps (warm: the studio's own cache, as a second start finds it)")
    args = ap.parse_args()
    fresh, forked = [], []
    for r in range(args.runs):
        f, k = one_run(args.tabs, args.cache_dir)
        fresh.append(f)
        forked += k
        print(f"run {r + 1}: a fresh process READY after {f:.2f} s; forked: {', '.join(f'{x:.2f}' for x in k)} s", flush=True)
    mf, mk = statistics.median(fresh), statistics.median(forked)
    print(f"median: fresh {mf:.2f} s ({len(fresh)} starts), forked {mk:.2f} s ({len(forked)} forks); "
          f"a tab waits {mf / mk:.1f}x longer for a process started for it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
