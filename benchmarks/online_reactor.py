"""The online reactor's speed: the time of one `push` (a leader frame in, the follower's frame out) over real leaders
streamed frame by frame, against the time a frame lasts and the offline reaction of the same leaders in the same run.

    .venv/bin/python benchmarks/online_reactor.py [--checkpoint sample_data/imm_diffusion.safetensors] [--threads 1]
        [--leaders 10] [--repeats 4] [--online-windows 16 30] [--live-steps 7 4]

Each of the first `--leaders` sequences of the bundled data, played `--repeats` times in a row, is streamed into a fresh
reactor for each label (one class; three signed classes; a label per body part), interleaved with the offline
reaction of the same take, so that both meet the same load. Prints the median and p95 push, the share of pushes
slower than a frame at 15 fps (66.7 ms), and the offline reaction's time per frame. `--online-windows` times reactors
reading that many leader frames a push (windows.ONLINE_WINDOW), and `--live-steps` reactors taking that many sampler
steps a push (windows.LIVE_STEPS), each pair one after another on each take, so that they meet the same load. A model
with a live reactor beside it (live.py) is timed with it too, on the same takes: "live reactor" against the windows.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

from imm_model.data.dataset import InteractionDataset
from imm_model.families.diffusion import windows
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT

FRAME_MS = 1000 / 15


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(SAMPLE_DEFAULT))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--leaders", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=4)
    ap.add_argument("--online-windows", type=int, nargs="+", default=[windows.ONLINE_WINDOW],
                    help="leader frames a push reads (windows.ONLINE_WINDOW), each timed")
    ap.add_argument("--live-steps", type=int, nargs="+", default=[windows.LIVE_STEPS],
                    help="sampler steps a push takes (windows.LIVE_STEPS), each timed")
    args = ap.parse_args()
    if min(args.live_steps) < 1 or min(args.online_windows) < 2 or args.leaders < 1 or args.repeats < 1 or args.threads < 1:
        ap.error("--live-steps, --leaders, --repeats and --threads must be at least 1, --online-windows at least 2")
    threadpool_limits(args.threads)
    data = InteractionDataset.load(SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    names = model.class_names
    labels = {"one class": {names[1]: 1.0}, "three signed classes": {names[0]: 1.0, names[1]: -1.0, names[3]: 0.5}}
    if model.part_labels:
        labels[f"upper:{names[2]}, lower:-{names[1]}"] = {f"upper:{names[2]}": 1.0, f"lower:{names[1]}": -1.0}
    takes = [np.concatenate([data.world(i)[0]] * args.repeats) for i in range(args.leaders)]
    print(f"checkpoint {args.checkpoint}; threads {args.threads}; {len(takes)} takes of {sum(map(len, takes))} frames; "
          f"lookahead {windows.LOOKAHEAD} frames")
    source = model.takes or model  # the model whose live reactor (or windows) react live
    live = source.live
    for title, label in labels.items():
        variants = ([("live reactor", None, None)] if live is not None else []) + [
            ("windows", w, s) for w in args.online_windows for s in args.live_steps]
        pushes, offline = {v: [] for v in variants}, []
        for take in takes:
            for kind, w, s in variants:
                source.live = live if kind == "live reactor" else None
                if kind == "windows":
                    windows.ONLINE_WINDOW, windows.LIVE_STEPS = w, s
                reactor = model.online(label)
                for frame in take:
                    t = time.perf_counter()
                    reactor.push(frame)
                    pushes[kind, w, s].append((time.perf_counter() - t) * 1000)
                reactor.flush()
            source.live = live
            t = time.perf_counter()
            model.synthesize(take, label)
            offline.append((time.perf_counter() - t) * 1000 / len(take))
        for (kind, w, s), times in pushes.items():
            times = np.array(times)
            what = kind if w is None else f"window {min(w, model.window)}, {s} steps"
            print(f"{title}, {what}: push median {np.median(times):.1f} ms, p95 "
                  f"{np.percentile(times, 95):.1f} ms, {(times > FRAME_MS).mean():.1%} slower than a frame")
        print(f"{title}: offline {np.median(offline):.2f} ms a frame")


if __name__ == "__main__":
    main()
