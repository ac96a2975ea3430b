"""Where a slider move's time goes on the server, stage by stage: the label, the network, the clean-up, the side-by-side
followers, the reads-as panel (and, for a mix by body part, the part judges), the scene, the render and the JPEG
encode of the picture, for the default diffusion model and the paper's GAN interleaved in one run (so that both meet
the same load). In process, no browser: what the page adds (the websocket, decoding and showing the picture) is what
`benchmarks/explorer_latency.py` measures from the key to the picture.

    .venv/bin/python benchmarks/slider_stages.py [--moves 40] [--threads 1]

Each move sets one class slider of the held-out sequence the studio opens with to a new value (the mixes a user makes:
one to three classes, signed; one move in five a label per body part, for a model that reads one), as the label mixer
does (`Session.set_label`), then draws the picture as the view stream does for a slider (at DRAFT_SCALE of the view,
INTERACTIVE_QUALITY). Prints per model and stage the median and p95 in ms, and the median total's ratio to the GAN's.
The default draws the picture with its draft (the bundled 2-step student) as the studio's sliders do, its own reaction
following once the sliders rest ("settle", off the picture's path); "diffusion, no draft" is the same model without.
"""

from __future__ import annotations

import argparse
import io
import time
from collections import defaultdict

import numpy as np
from PIL import Image
from threadpoolctl import threadpool_limits

from explorer.rendering.pictures import screenshot
from explorer.rendering.scene import Scene, floor_height
from explorer.rendering.view_stream import DRAFT_SCALE, INTERACTIVE_QUALITY
from explorer.session.session import Session, load_model
from imm_model.data.dataset import InteractionDataset
from imm_model.data.labels import Label
from imm_model.paths import SAMPLE_DATA, SAMPLE_DEFAULT, SAMPLE_GAN, SAMPLE_JUDGE, SAMPLE_LOWER_JUDGE, SAMPLE_UPPER_JUDGE
from imm_model.reads_as import ReadsAs

STAGES = ("label", "network", "clean-up", "beside", "reads as", "scene", "render", "encode")  # the picture's path
SETTLE = "settle"  # after the picture: the model's own reaction in place of its draft's (once the sliders rest)


def moves(names, count: int, part_labels: bool, rng) -> list[Label]:
    """The mixes a user makes, a slider at a time."""
    out = []
    for k in range(count):
        values = np.zeros(len(names))
        chosen = rng.choice(len(names), size=1 + k % 3, replace=False)
        values[chosen] = rng.choice([-1.0, -0.5, 0.5, 1.0], size=len(chosen))
        if part_labels and k % 5 == 4:
            lower = np.zeros(len(names))
            lower[(chosen[0] + 1) % len(names)] = 1.0
            out.append(Label.of_parts(values, lower, names))
        else:
            out.append(Label.of(values, names))
    return out


def one_move(session: Session, scene: Scene, label: Label, times: dict[str, list[float]], draft: bool) -> None:
    model = (session.model.draft_for(len(session.leader)) if draft else None) or session.model  # what draws the picture
    clock = time.perf_counter
    t0 = clock()
    vector = session.check_label(label)
    t1 = clock()
    raw = model._network([session.leader], model._label_array(vector, 1), [session.seed])[0]
    t2 = clock()
    model._clean(raw)
    t3 = clock()
    session.set_label(label, draft=draft)  # the network and clean-up again, and the followers drawn beside (none by default)
    t4 = clock()
    session.readings.reads_as()
    session.readings.reads_as_parts()
    t5 = clock()
    scene.set_synthesized(session.synth)
    scene.set_frame(0)
    t6 = clock()
    pixels = screenshot(scene)
    t7 = clock()
    Image.fromarray(pixels).save(io.BytesIO(), format="JPEG", quality=INTERACTIVE_QUALITY)
    t8 = clock()
    session.settle()
    times[SETTLE].append(1000 * (clock() - t8))
    network, cleanup = t2 - t1, t3 - t2
    for stage, seconds in zip(STAGES, (t1 - t0, network, cleanup, max(0.0, t4 - t3 - network - cleanup), t5 - t4, t6 - t5,
                                       t7 - t6, t8 - t7), strict=True):
        times[stage].append(1000 * seconds)


def stage_table(moves_per_model: int = 40, threads: int = 1) -> list[str]:
    """The stages of `moves_per_model` slider moves for each model, interleaved -> the lines `main` prints (also
    `benchmarks/explorer_latency.py`, beside the page's key-to-picture time)."""
    threadpool_limits(threads)
    data = InteractionDataset.load(SAMPLE_DATA)
    index = int(np.flatnonzero(data.held_out)[0]) if data.held_out.any() else 0
    parts = {part: ReadsAs.load(p) for part, p in (("upper", SAMPLE_UPPER_JUDGE), ("lower", SAMPLE_LOWER_JUDGE)) if p.exists()}
    sessions = {name: Session(data, {name: load_model(path, data)}, index=index, reader=ReadsAs.load(SAMPLE_JUDGE),
                              part_readers=parts)
                for name, path in (("diffusion", SAMPLE_DEFAULT), ("diffusion, no draft", SAMPLE_DEFAULT), ("gan", SAMPLE_GAN))}
    drafts = {name: name == "diffusion" for name in sessions}  # as the studio's sliders: the default's draft draws
    scene = Scene(data.skeleton, floor_height(data.leader, data.follower, data.skeleton))
    width, height = scene.render_window.GetSize()
    scene.render_window.SetSize(round(width * DRAFT_SCALE), round(height * DRAFT_SCALE))
    ses0 = next(iter(sessions.values()))
    scene.set_sequence(ses0.leader, ses0.ground_truth, ses0.synth)
    plans = {name: moves(data.class_names, moves_per_model, ses.part_labels, np.random.default_rng(1))  # the same moves each
             for name, ses in sessions.items()}
    times = {name: defaultdict(list) for name in sessions}
    for name, ses in sessions.items():  # a first move each, not timed: caches and the first render
        one_move(ses, scene, plans[name][0], defaultdict(list), drafts[name])
    for k in range(moves_per_model):  # interleaved: every model meets the same load
        for name, ses in sessions.items():
            one_move(ses, scene, plans[name][k], times[name], drafts[name])
    lines = [f"{moves_per_model} slider moves per model on sequence {data.sequence_ids[index]}, torch and BLAS threads "
             f"{threads}, picture {scene.render_window.GetSize()} px at JPEG quality {INTERACTIVE_QUALITY}"]
    totals = {name: np.sum([times[name][s] for s in STAGES], axis=0) for name in sessions}
    for name in sessions:
        cells = ", ".join(f"{s} {np.median(times[name][s]):.1f}/{np.percentile(times[name][s], 95):.1f}" for s in STAGES)
        after = times[name][SETTLE]
        settle = f"; then {SETTLE} {np.median(after):.1f}/{np.percentile(after, 95):.1f}" if drafts[name] else ""
        lines.append(f"{name}: median/p95 ms: {cells}; total {np.median(totals[name]):.1f}/"
                     f"{np.percentile(totals[name], 95):.1f} ({np.median(totals[name]) / np.median(totals['gan']):.2f}x "
                     f"the GAN's median){settle}")
    scene.close()
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=40)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    print("\n".join(stage_table(args.moves, args.threads)))


if __name__ == "__main__":
    main()
