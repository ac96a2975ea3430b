"""Whether a studio process's first slider moves cost more than its later ones because it was forked: the zygote's
loading done here (explorer/serving/zygote.py: the libraries, the data, the models, `gc.freeze`), then a child forked
from it builds a session and a scene, draws a first picture (as a tab's page load does) and makes slider moves as
`benchmarks/slider_stages.py` does (the label, the draft's synthesis, the clean-up, the reads-as panel, the scene, the
render, the JPEG encode), each timed with the minor page faults it caused (copy-on-write copies of the parent's pages).

    .venv/bin/python benchmarks/forked_first_moves.py [--moves 12] [--children 2]

Prints, per child, each move's milliseconds and page faults, in order.
"""

from __future__ import annotations

import argparse
import gc
import os
import resource
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks.slider_stages

import numpy as np  # noqa: E402


def moves_in_a_child(loaded, count: int) -> list[tuple[float, int]]:
    """In the forked child: a session and a scene, a first picture, then `count` moves -> [(ms, page faults)]."""
    from benchmarks.slider_stages import moves, one_move
    from explorer.rendering.pictures import screenshot
    from explorer.rendering.scene import Scene, floor_height
    from explorer.session.session import Session

    data, models, _, reader, part_readers = loaded
    session = Session(data, {"diffusion": models["diffusion"]}, index=int(np.flatnonzero(data.held_out)[0]), reader=reader,
                      part_readers=part_readers)
    scene = Scene(data.skeleton, floor_height(data.leader, data.follower, data.skeleton))
    scene.set_sequence(session.leader, session.ground_truth, session.synth)
    screenshot(scene)  # the page's first picture
    out = []
    for label in moves(data.class_names, count, session.part_labels, np.random.default_rng(1)):
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        start = time.perf_counter()
        one_move(session, scene, label, defaultdict(list), draft=True)
        out.append((1000 * (time.perf_counter() - start), resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults))
    scene.close()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=12)
    ap.add_argument("--children", type=int, default=2)
    args = ap.parse_args()
    if args.moves < 1 or args.children < 1:
        ap.error("--moves and --children must be at least 1")
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    from threadpoolctl import threadpool_limits

    from explorer.serving import worker
    from explorer.serving.zygote import preload
    from imm_model.paths import SAMPLE_DATA, SAMPLE_MODELS

    threadpool_limits(1)
    argv = ["--data", str(SAMPLE_DATA)]
    for name, path in SAMPLE_MODELS.items():
        argv += ["--model", f"{name}={path}"]
    loaded = worker.load_everything(worker.parse_args(argv))
    preload()
    gc.freeze()
    for child in range(1, args.children + 1):
        read, write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: what a tab's studio process does; it never returns into the parent's loop
            os.close(read)
            try:
                line = " ".join(f"{ms:.1f}/{faults}" for ms, faults in moves_in_a_child(loaded, args.moves))
            except Exception as err:  # noqa: BLE001 - said in the parent's one line
                line = f"failed: {type(err).__name__}: {err}"
            os.write(write, line.encode())
            os._exit(0)
        os.close(write)
        with os.fdopen(read) as pipe:
            line = pipe.read()
        os.waitpid(pid, 0)
        print(f"child {child}, move ms / page faults in order: {line}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
