"""Where a tab's first slider move spends the time its later moves do not: each move split into stages timed in the
page, in the studio process and in the launcher, for the first move of each tab against the later ones.

    .venv/bin/python benchmarks/first_move_stages.py [--tabs 6] [--moves 4] [--rest 3]

Starts a studio with the bundled models whose processes write a timestamp (wall clock, ms) as a message arrives, as the
new mix is synthesized, as the picture is rendered and encoded and as it goes out (the launcher's too, as its proxy
sends it on) (a `sitecustomize` module wrapping
those functions, written to a temporary folder put on PYTHONPATH: the studio's code is not changed). Then opens `--tabs`
tabs one after another in headless chromium (each closed before the next opens), makes `--moves` class-slider moves in
each, as `explorer_latency.py` does (0.25 s apart; with `--rest S` the last move of each tab comes S seconds after the
one before), and prints each move's stages and their medians, the first moves and the rested ones apart:

  page -> sent         the key to the page's websocket message
  sent -> server       the message through the launcher's proxy to the studio process
  server -> synthesis  the message handled until the mix's synthesis starts
  synthesis            the session's new follower (the draft's)
  -> render            until the picture's render starts
  render               the picture rendered (at the draft's size)
  render -> sent       encoded and handed to the websocket
  sent -> relayed      until the launcher's proxy sends it on to the page
  relayed -> picture   from the proxy's send to the page's image URL
  picture -> shown     decoded and shown
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from benchmarks.explorer_latency import WIRE_JS  # noqa: E402
from tests import studio_probe as probe  # noqa: E402

# Wraps, in every studio process, what a move goes through; each call writes "<ms> <pid> <what> in|out".
STAMPS_MODULE = '''
import functools, inspect, os, time
_fd = os.open(os.environ["IMM_STAMPS"], os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
def _stamp(what):
    os.write(_fd, f"{time.time() * 1000:.2f} {os.getpid()} {what}\\n".encode())
def _wrap(owner, name, label):
    fn = getattr(owner, name)
    if inspect.iscoroutinefunction(fn):
        async def wrapped(*a, **k):
            _stamp(label + " in")
            try:
                return await fn(*a, **k)
            finally:
                _stamp(label + " out")
    else:
        def wrapped(*a, **k):
            _stamp(label + " in")
            try:
                return fn(*a, **k)
            finally:
                _stamp(label + " out")
    setattr(owner, name, functools.wraps(fn)(wrapped))
import aiohttp.web_ws as _web_ws
_wrap(_web_ws.WebSocketResponse, "send_bytes", "websocket out")  # the studio's (wslink) and the launcher's (the proxy)
import explorer.serving.worker as _worker
_start_index = _worker.start_index
def _patched(*a, **k):  # the zygote calls this once it has loaded, before it imports the page's modules
    from explorer.serving.zygote import preload
    preload()
    from wslink.protocol import WslinkHandler
    from trame_rca.encoders.image_encoder import RcaImageEncoder
    from explorer import trame_adapter
    from explorer.rendering.view_stream import PictureGate
    from explorer.session.session import Session
    _wrap(WslinkHandler, "onMessage", "message")
    _wrap(Session, "set_label", "synthesis")
    _wrap(trame_adapter._wrapping_scheduler(), "_render_frame", "render")
    _wrap(RcaImageEncoder, "encode", "encode")
    _wrap(PictureGate, "_send", "send")
    return _start_index(*a, **k)
_worker.start_index = _patched
'''

STAGES = ("page -> sent", "sent -> server", "server -> synthesis", "synthesis", "-> render", "render", "render -> sent",
          "sent -> relayed", "relayed -> picture", "picture -> shown", "total")
EPOCH_MS = "(performance.timeOrigin + performance.now())"


def moves(page, count: int, rest_s: float = 0.0) -> list[dict]:
    """`count` class-slider moves -> each one's page times (epoch ms): key, sent, picture in, shown; the last one
    `rest_s` after the one before when given."""
    page.evaluate(f"""(sel) => {{ if (window.__immMoves) return; const m = window.__immMoves = {{keys: [], shown: []}};
        document.addEventListener('keydown', () => m.keys.push({EPOCH_MS}), true);
        document.querySelector(sel).addEventListener('load', () => m.shown.push({EPOCH_MS})); }}""", probe.VIEW_IMG)
    page.evaluate(WIRE_JS.replace("performance.now()", EPOCH_MS))
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    css = f".slider-{names[(own + 1) % len(names)].replace(' ', '_')}"
    out = []
    for k in range(count):
        if rest_s and k == count - 1:
            time.sleep(rest_s)
        n_shown, n_key = page.evaluate("() => [window.__immMoves.shown.length, window.__immMoves.keys.length]")
        probe.press_slider(page, css, "End" if k % 2 == 0 else "Home")
        page.wait_for_function("([k, n]) => { const m = window.__immMoves; return m.keys.length > k && "
                               "m.shown.slice(n).some(t => t > m.keys[k]); }", arg=[n_key, n_shown], timeout=10000)
        out.append(page.evaluate("""([k, n]) => { const m = window.__immMoves, key = m.keys[k];
            const shown = m.shown.slice(n).find(t => t > key), ins = window.__immWire.pictures.filter(t => t > key && t <= shown);
            return {key, sent: window.__immWire.sent.find(t => t > key), picture: ins[ins.length - 1], shown}; }""",
                                 [n_key, n_shown]))
        time.sleep(0.25)  # idle between moves: one change at a time, as explorer_latency.py
    return out


def stages(move: dict, stamps: list[tuple[float, int, str]]) -> dict | None:
    """One move's STAGES in ms, from its page times and the processes' stamps (None when a stamp is missing)."""
    key = move["key"]
    events = [(t - key, pid, what) for t, pid, what in stamps if key - 5 <= t <= move["shown"] + 5]

    def first(what: str, after: float = -1e9, not_pid: int | None = None) -> float:
        return next(t for t, p, w in events if w == what and t >= after and p != not_pid)

    try:
        sent = move["sent"] - key
        arrived = first("message in", sent)
        synth_in = first("synthesis in", arrived)
        synth_out = first("synthesis out", synth_in)
        render_in = first("render in", synth_out)
        render_out = first("render out", render_in)
        out = first("send in", render_out)
        studio = next(p for t, p, w in events if w == "send in" and t == out)
        relayed = first("websocket out in", out, not_pid=studio)  # the launcher's next send after the studio's
    except (StopIteration, TypeError):
        return None
    picture, shown = move["picture"] - key, move["shown"] - key
    return dict(zip(STAGES, (sent, arrived - sent, synth_in - arrived, synth_out - synth_in, render_in - synth_out,
                             render_out - render_in, out - render_out, relayed - out, picture - relayed, shown - picture,
                             shown), strict=True))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tabs", type=int, default=6, help="tabs, one after another (each closed before the next opens)")
    ap.add_argument("--moves", type=int, default=4, help="slider moves in each tab")
    ap.add_argument("--rest", type=float, default=0.0, help="seconds the page rests before each tab's last move")
    args = ap.parse_args()
    if args.tabs < 1 or args.moves < 2 + (args.rest > 0) or args.rest < 0:
        ap.error("--tabs must be at least 1, --moves at least 2 (3 with --rest: a first, a later and a rested move), "
                 "--rest at least 0")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "sitecustomize.py").write_text(STAMPS_MODULE)
        stamp_file = Path(tmp) / "stamps.log"
        os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, (tmp, os.environ.get("PYTHONPATH"))))
        os.environ["IMM_STAMPS"] = str(stamp_file)
        results = []
        with sync_playwright() as pw, probe.StudioProcess(cache_dir=Path(tmp) / "cache", timeout=120) as studio:
            browser = probe.launch_chromium(pw)
            for tab in range(args.tabs):
                page = probe.open_studio(browser, studio.url)
                results += [(tab, k, m) for k, m in enumerate(moves(page, args.moves, args.rest))]
                page.close()
        stamps = []
        for line in stamp_file.read_text().splitlines():
            t, pid, what = line.split(None, 2)
            stamps.append((float(t), int(pid), what))
    rows: dict[str, list[dict]] = {"first": [], "later": [], "rested": []}
    for tab, k, move in results:
        split = stages(move, stamps)
        if split is None:
            print(f"tab {tab + 1} move {k + 1}: a stage went unstamped; left out")
            continue
        rows["first" if k == 0 else "rested" if args.rest and k == args.moves - 1 else "later"].append(split)
        print(f"tab {tab + 1} move {k + 1}: " + ", ".join(f"{n} {v:.1f}" for n, v in split.items()))
    print("medians (ms):")
    for kind, split in rows.items():
        if split:
            print(f"  {kind} moves ({len(split)}): " + ", ".join(f"{n} {statistics.median(s[n] for s in split):.1f}" for n in STAGES))
    return 0


if __name__ == "__main__":
    sys.exit(main())
