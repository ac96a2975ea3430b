"""Time to load the full raw SBU set (282 files) and K3HI (312 sequences), and the bundled file.

    python benchmarks/data_load.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import os
import time

from imm_model.data import load_k3hi, load_sbu
from imm_model.data.dataset import InteractionDataset
from imm_model.paths import SAMPLE_DATA, k3hi_raw_root, sbu_raw_root


def best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"cpu threads available: {os.cpu_count()}")
    sbu = sbu_raw_root()
    if sbu.is_dir():
        t = best_of(lambda: load_sbu(sbu, classes="all"), args.repeats)
        print(f"raw SBU, all 8 classes (282 files, 6822 frames): {t * 1000:.0f} ms (best of {args.repeats})")
    k3hi = k3hi_raw_root()
    if k3hi.is_dir():
        t = best_of(lambda: load_k3hi(k3hi), args.repeats)
        print(f"raw K3HI (312 sequences, 624 .mat files):   {t * 1000:.0f} ms (best of {args.repeats})")
    t = best_of(lambda: InteractionDataset.load(SAMPLE_DATA), args.repeats)
    print(f"bundled sample file (197 sequences):           {t * 1000:.1f} ms (best of {args.repeats})")


if __name__ == "__main__":
    main()
