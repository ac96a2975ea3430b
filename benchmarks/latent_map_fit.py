"""How long the studio's latent-map fit takes beside busy processes, at the studio's priority and at BACKGROUND_NICE.

    .venv/bin/python benchmarks/latent_map_fit.py [--busy 2] [--rounds 2] [--method tsne]

Embeds the bundled data with the default model into a fresh cache file, then times the fitting process the studio runs
(`python -m explorer.session.latent <cache> tsne`), each round from a cache without the map: idle, then beside
`--busy` processes that spin at the studio's priority. The busy processes share this script's session, as a studio's
own tab processes share the fitter's (Linux's autogroup weighs nice only between the processes of one session).
Prints wall seconds per round for the fitter at the studio's priority and, for comparison, at BACKGROUND_NICE.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from explorer.session.latent import BACKGROUND_NICE, METHODS, LatentMap  # noqa: E402  (numpy only: no model loads)


def spin() -> None:
    while True:
        pass


def fit_seconds(cache: Path, latents, method: str, nice: int) -> float:
    cache.unlink(missing_ok=True)  # a save keeps what the file holds: a fresh file has the embeddings only
    LatentMap(latents, path=cache).save()
    start = time.monotonic()
    subprocess.run([sys.executable, "-m", "explorer.session.latent", str(cache), method], check=True,
                   preexec_fn=(lambda: os.nice(nice)) if nice else None)  # fmt: skip
    return time.monotonic() - start


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--busy", type=int, default=2, help="busy processes beside the fit (default 2: this machine's cores)")
    ap.add_argument("--rounds", type=int, default=2, help="fits per setting (default 2)")
    ap.add_argument("--method", choices=METHODS, default="tsne")
    args = ap.parse_args()
    if args.busy < 0 or args.rounds < 1:
        ap.error("--busy must be at least 0 and --rounds at least 1")
    from imm_model.data.dataset import InteractionDataset
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT

    autogroup = Path("/proc/sys/kernel/sched_autogroup_enabled")
    print(f"{os.cpu_count()} cores; autogroup {autogroup.read_text().strip() if autogroup.exists() else 'absent'}")
    data = InteractionDataset.load(SAMPLE_DATA)
    latents = LatentMap.build(ReactionModel.load(SAMPLE_DEFAULT), data, None, None, methods=()).latents
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "latent-bench.npz"
        for busy in sorted({0, args.busy}):
            spinners = [multiprocessing.Process(target=spin, daemon=True) for _ in range(busy)]
            for s in spinners:
                s.start()
            try:
                for nice, name in ((0, "the studio's priority"), (BACKGROUND_NICE, f"nice {BACKGROUND_NICE}")):
                    times = [fit_seconds(cache, latents, args.method, nice) for _ in range(args.rounds)]
                    print(f"{args.method} fit, {busy} busy processes beside it, at {name}: "
                          + ", ".join(f"{t:.1f}" for t in times) + " s")  # fmt: skip
            finally:
                for s in spinners:
                    s.terminate()
    return 0


if __name__ == "__main__":
    sys.exit(main())
