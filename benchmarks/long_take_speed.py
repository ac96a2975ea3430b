"""What a long take costs the default model: a leader longer than the training clips is made in windows by the
default's teacher (imm_model/families/diffusion/windows.py), each window's sampler steps resampled RESAMPLE times; a
moving slider draws it with the student's own windows (its draft). Times, interleaved in one run on one thread, the
take as it ships, the same take with each step taken once (resample 0), and the draft, on real leaders joined end to
end.

    .venv/bin/python benchmarks/long_take_speed.py [--frames 257] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

from imm_model import paths
from imm_model.data.bundle import load_any
from imm_model.families.diffusion.windows import RESAMPLE
from imm_model.inference import ReactionModel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=257)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    if args.frames <= 46 or args.repeats < 1:
        ap.error("--frames must be beyond the longest training clip (46) and --repeats at least 1")
    data = load_any(paths.SAMPLE_DATA)
    model = ReactionModel.load(paths.SAMPLE_DEFAULT)
    leader = np.concatenate([data.world(i)[0] for i in range(0, len(data), 7)])[: args.frames]
    label = {"pushing": 1.0}
    runs = {f"as shipped (resample {RESAMPLE})": (model, RESAMPLE), "resample 0": (model, 0), "the draft": (model.draft, 0)}
    times: dict[str, list[float]] = {name: [] for name in runs}
    with threadpool_limits(1):
        for _ in range(args.repeats):
            for name, (m, resample) in runs.items():
                (m.takes or m).resample = resample
                start = time.perf_counter()
                m.synthesize(leader, label, seed=0)
                times[name].append(time.perf_counter() - start)
    base = np.median(times["resample 0"])
    print(f"a {len(leader)}-frame take, one thread, median of {args.repeats}:")
    for name, t in times.items():
        print(f"  {name}: {np.median(t):.2f} s ({np.median(t) / base:.2f}x resample 0)")


if __name__ == "__main__":
    main()
