"""One studio process = one user: serves the page for the data, model and latent map it was given, on its own
loopback port.

Forked per browser tab by the zygote (explorer/serving/zygote.py), which loaded everything once. It says
`IMM-WORKER READY <id> <port> <page folder>` (or `ERROR <id> <message>`) to the launcher. The launcher ends it when its tab has
gone (through the zygote: explorer/serving/launcher.py); it exits by itself when the zygote goes away (its stdin closes).
"""

from __future__ import annotations

import argparse
import gc
import os
import re
import sys
import threading
from pathlib import Path
from typing import TextIO

PREFIX = "IMM-WORKER"
MODEL_NAME = re.compile(r"[A-Za-z0-9_-]{1,32}")  # what the switch and the view's link (model=) call a model


class Channel:
    """Lines to the launcher, `IMM-WORKER <kind> [<worker id>] <words>`, each written whole (one write of a short
    line to a pipe is atomic, so processes sharing the pipe never interleave)."""

    def __init__(self, out: TextIO, worker_id: str | None = None):
        self.out, self.worker_id = out, worker_id

    def __call__(self, kind: str, *words: object) -> None:
        ids = () if self.worker_id is None else (self.worker_id,)
        self.out.write(" ".join([PREFIX, kind, *ids, *map(str, words)]) + "\n")
        self.out.flush()


def say_line(kind: str, *words: object) -> None:
    Channel(sys.stdout)(kind, *words)


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m explorer.serving.zygote")
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--model", action="append", required=True, type=model_argument, metavar="NAME=CHECKPOINT",
                   help="a model by name, in the switch's order (the first opens the studio)")
    p.add_argument("--cache-dir", type=Path, default=None)
    p.add_argument("--export-dir", type=Path, default=Path("imm-exports"))
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=0)
    p.add_argument("--render", choices=("remote", "local"), default="remote")
    p.add_argument("--sequence", default=None, help="sequence id or index to open first")
    p.add_argument("--judge", type=Path, default=None,
                   help="'reads as' classifier (default: the bundled one and its body-part judges; a custom one reads the "
                        "whole body only; 'none' hides the panel)")
    return p.parse_args(argv)


def model_argument(text: str) -> tuple[str, Path]:
    """'NAME=CHECKPOINT' -> (name, path); a name is what the switch and the view's link call the model."""
    name, sep, path = text.partition("=")
    if not sep or not path or not MODEL_NAME.fullmatch(name):
        raise argparse.ArgumentTypeError(f"{text[:80]!r}: expected NAME=CHECKPOINT, NAME of 1-32 letters, digits, '-' or '_'")
    return name, Path(path)


def load_everything(args: argparse.Namespace):
    """Data, the models by name and the first one's latent embeddings; raises IMMError/OSError with one-line messages."""
    from explorer.session.latent import LatentMap, cache_key, default_cache_dir
    from imm_model.data.dataset import InteractionDataset

    data = InteractionDataset.load(args.data)
    models = load_models(args.model, data)
    cache_dir = args.cache_dir or default_cache_dir()
    first, checkpoint = next(iter(models.values())), args.model[0][1]
    # The studio fits a missing projection after the page opens (a cold cache's t-SNE costs ~3 s here)
    latent = LatentMap.build(first, data, cache_dir, cache_key(checkpoint, args.data), methods=())
    return data, models, latent, load_reader(args.judge), load_part_readers(args.judge)


def load_models(named: list[tuple[str, Path]], data) -> dict:
    """{name: model}, each loaded, checked against the data and warmed by one synthesis here, in the zygote (~50 ms
    for the diffusion model, paid once rather than at every tab's first switch; the weights shared by the forked tabs)."""
    from explorer.session.session import load_model

    models = {}
    for name, path in named:
        if name in models:
            raise ValueError(f"--model {name}: given twice; give each model a name of its own")
        model = models[name] = load_model(path, data)
        for drawing in filter(None, (model, model.draft)):  # a slider's first draft too
            drawing.synthesize_canonical(data.canonical(0)[0], drawing.label_vector([0.0] * len(model.class_names)))
    return models


def load_reader(path: Path | None):
    """The 'reads as' classifier, or None when asked for none or when the bundled one is absent. A body-part judge is
    refused (CheckpointError, one line): the panel would show its reading of one part as the whole follower's."""
    from imm_model.errors import CheckpointError
    from imm_model.paths import SAMPLE_JUDGE
    from imm_model.reads_as import ReadsAs

    if path is not None and str(path) == "none":
        return None
    if path is None and not SAMPLE_JUDGE.exists():
        return None
    reader = ReadsAs.load(path or SAMPLE_JUDGE)
    if reader.part is not None:
        raise CheckpointError(f"{path or SAMPLE_JUDGE}: a judge of the {reader.part} body alone; --judge takes one that reads "
                              "the whole follower (imm data build-judge --inputs follower)")
    return reader


def load_part_readers(path: Path | None) -> dict:
    """The body-part judges {"upper": ..., "lower": ...} beside the bundled judge; none with --judge none or a custom
    --judge (a judge of other data would not match them), nor where they are absent."""
    from imm_model.paths import SAMPLE_LOWER_JUDGE, SAMPLE_UPPER_JUDGE
    from imm_model.reads_as import ReadsAs

    if path is not None:
        return {}
    return {part: ReadsAs.load(p) for part, p in (("upper", SAMPLE_UPPER_JUDGE), ("lower", SAMPLE_LOWER_JUDGE)) if p.exists()}


def start_index(data, sequence: str | None) -> int:
    if sequence is None:
        held = [i for i in range(len(data)) if data.held_out[i]]
        return held[0] if held else 0  # open on a sequence the model never saw: the honest default
    if sequence.isdigit() and int(sequence) < len(data):
        return int(sequence)
    if sequence in data.sequence_ids:
        return data.index_of(sequence)
    raise ValueError(f"--sequence {sequence!r}: no such sequence (an id such as {data.sequence_ids[0]}, or an index 0..{len(data) - 1})")


def serve(data, models, latent, reader, part_readers, args: argparse.Namespace, *, secret: str, say: Channel, uploads=None) -> int:
    """Serve one tab (`models` by name, the first opening it); `uploads` reads its uploaded files out of this process
    (explorer/serving/upload_reader.py)."""
    from explorer.serving.page_shell import use_page_shell
    from explorer.session.latent import default_cache_dir
    from explorer.session.session import Session
    from explorer.trame_adapter import guard_client_input, make_server, set_secret
    from explorer.ui.app import Studio

    server = make_server("imm-studio")
    set_secret(server, secret)  # wslink's default secret is public: every process gets its own
    session = Session(data, models, args.start, reader, part_readers)
    session.upload_reader = uploads
    Studio(server, session, latent, export_dir=args.export_dir, render=args.render)

    def refused(why: str) -> None:  # a message the page cannot have sent: the tab hears why, and stays
        server.state.error = f"refused a message from this page: {why}"
        server.state.flush()

    guard_client_input(server, refused)
    shell = use_page_shell(server, args.cache_dir or default_cache_dir())  # the launcher serves its shared files

    def stdin_watch():
        sys.stdin.read()  # the zygote writes nothing: end of file means it is gone
        os._exit(0)

    threading.Thread(target=stdin_watch, daemon=True).start()

    def ready(**_) -> None:
        gc.freeze()  # the page, scene and server objects built since the fork: out of every later full collection
        say("READY", server.port, shell)

    server.controller.on_server_ready.add(ready)
    server.start(host=args.host, port=args.port, open_browser=False, show_connection_info=False, disable_logging=True)
    return 0
