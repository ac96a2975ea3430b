"""IMM Studio latency benchmark (headless Chromium through Playwright, remote rendering).

    .venv/bin/python benchmarks/explorer_latency.py [--trials 40] [--play-seconds 5] [--json out.json] [--checkpoint CK]
    .venv/bin/python benchmarks/explorer_latency.py --models [--trials 20]   # only 7. below
    .venv/bin/python benchmarks/explorer_latency.py --sliders-only [--trials 20]   # only 2.'s first series, by stage
    .venv/bin/python benchmarks/explorer_latency.py --playback-only [--play-seconds 5] [--playback-scales 1,0.5] [--rounds 3]
        # only 3.'s page figure, for each size of the pictures while playing, back to back in one page

Every studio it starts serves the bundled model, or CK (a generator checkpoint, e.g. a wider recipe's).

Measures, and prints with the machine's thread count and load:
  1. start-to-interactive of `imm explore`: process start -> first 3D picture in the page, cold
     (empty latent cache: embeddings + t-SNE recomputed) and warm (cache filled);
  2. slider -> redrawn follower: a class slider is moved with the keyboard; time from the key event
     to the `load` of the next view image in the page (performance.now() in the page), p50/p95, with the
     'reads as' panel and, in a second studio in the same run, without it (--judge none); the first series split
     into the key to its state sent (the page), sent to picture in (the server and the wire) and picture in to shown;
  3. playback: pictures the page actually displays per second while playing at 2x (30 fps target),
     and the server's render capability (update + render + JPEG per frame, same view size) in fps.
  4. the same slider latency with a mix pinned (A/B compare: two followers in the view), and with five tabs open
     at once (each tab its own studio process);
  5. memory with 5 tabs: RSS, PSS and USS of each studio process (one per tab, plus the warm spare) and of the
     zygote they are forked from, and the PSS of all of them together (`--memory-only`: just this).
  6. where a slider's time goes on the server, stage by stage (benchmarks/slider_stages.py), beside 2.'s key to picture.
  7. (`--models`) the model switch: slider latency with the diffusion model (the default), with the paper's GAN
     switched on, and with three diffusion variations side by side; the time from a click on "new variation" to its
     picture.
Bars (on an idle machine): slider p95 <= 60 ms from the first change after start with the 'reads as' panel on,
<= 100 ms with A/B, <= 100 ms with 5 tabs; warm start <= 3 s, cold <= 5 s; >= 28 pictures/s displayed at 2x;
>= 30 fps render capability; RSS per tab <= 300 MB.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
from tests import studio_probe as probe  # noqa: E402

VIEW_SIZE = (1400, 900)


def start_to_interactive(browser, cache_dir: Path, model: tuple[str, ...]) -> tuple[float, float, float, probe.StudioProcess]:
    """-> (address printed, first picture, latent map shown) in seconds after start, and the studio. On a cold cache
    the map is fitted after the page opens; waiting for it also leaves the cache full for the next start."""
    page = browser.new_page(viewport=dict(zip(("width", "height"), VIEW_SIZE, strict=True)))  # open before the start, as a user's
    t0 = time.monotonic()
    studio = probe.StudioProcess(*model, cache_dir=cache_dir, timeout=120)
    page.goto(studio.url, timeout=120000)
    probe.wait_for_view(page, 120000)
    interactive = time.monotonic() - t0
    page.wait_for_selector(probe.LATENT_POINTS, timeout=120000)
    mapped = time.monotonic() - t0
    page.close()
    return studio.ready_s, interactive, mapped, studio


# The page's share of a change, timed in the page: every websocket message it sends and every picture it turns into an
# image URL (trame-rca hands each JPEG to the <img> as a blob URL), so that a change splits into the key to its state
# sent (the page's own work: the slider, Vue's re-render), sent to picture in (the server and the wire), and picture in
# to picture shown (the decode)
WIRE_JS = """() => { if (window.__immWire) return; const wire = window.__immWire = {sent: [], pictures: []};
    const send = WebSocket.prototype.send;
    WebSocket.prototype.send = function (data) { wire.sent.push(performance.now()); return send.call(this, data); };
    const url = URL.createObjectURL;
    URL.createObjectURL = function (blob) { wire.pictures.push(performance.now()); return url.call(URL, blob); }; }"""
PAGE_STAGES = ("key -> state sent", "sent -> picture in", "picture in -> shown")


def slider_latency(page, trials: int, stages: dict | None = None) -> np.ndarray:
    """Key to redrawn picture (ms) for `trials` slider changes; `stages`, when given, gets each change's PAGE_STAGES."""
    page.evaluate(
        """() => { window.__immKeys = []; if (window.__immKeysOn) return; window.__immKeysOn = true;
        document.addEventListener('keydown', () => window.__immKeys.push(performance.now()), true); }"""
    )
    page.evaluate(WIRE_JS)
    names = probe.state(page, "class_names")
    own = [i for i in range(len(names)) if probe.state(page, f"w_{i}") == 1.0][0]
    css = f".slider-{names[(own + 1) % len(names)].replace(' ', '_')}"
    out = []
    for k in range(trials):
        n_img = probe.images_seen(page)
        n_key = page.evaluate("() => window.__immKeys.length")
        probe.press_slider(page, css, "End" if k % 2 == 0 else "Home")
        # the first picture decoded after the key event (an earlier one still in flight does not count)
        page.wait_for_function(
            "([k, n]) => window.__immKeys.length > k && window.__immImages.slice(n).some(t => t > window.__immKeys[k])",
            arg=[n_key, n_img],
            timeout=10000,
        )
        times = page.evaluate(
            """([k, n]) => { const key = window.__immKeys[k], shown = window.__immImages.slice(n).find(t => t > key);
            const sent = window.__immWire.sent.find(t => t > key), ins = window.__immWire.pictures.filter(t => t > key && t <= shown);
            return [shown - key, sent === undefined ? null : sent - key, ins.length ? ins[ins.length - 1] - key : null]; }""",
            [n_key, n_img],
        )
        out.append(times[0])
        if stages is not None and None not in times:
            shown, sent, picture = times
            for name, ms in zip(PAGE_STAGES, (sent, picture - sent, shown - picture), strict=True):
                stages.setdefault(name, []).append(round(ms, 1))
        time.sleep(0.25)  # idle between trials: measure one change, not a queue
    return np.array(out, float)


def _say_stages(stages: dict) -> None:
    print("  where it went, in the page: " + "; ".join(
        f"{name} p50 {np.percentile(ms, 50):.0f} / p95 {np.percentile(ms, 95):.0f} ms" for name, ms in stages.items()))


def displayed_fps(page, seconds: float) -> tuple[float, int]:
    probe.set_state(page, "speed", 2.0)
    probe.set_state(page, "loop", True)
    time.sleep(0.3)
    page.click("#play-button")
    time.sleep(0.5)  # warm-up
    n1, t1 = probe.images_seen(page), time.monotonic()
    time.sleep(seconds)
    n2, t2 = probe.images_seen(page), time.monotonic()
    page.click("#play-button")
    time.sleep(0.5)
    return (n2 - n1) / (t2 - t1), n2 - n1


def render_capability(frames: int = 60, size=(1052, 497)) -> float:
    """Server side, no browser: per frame = move points + render + JPEG (quality 80), in fps."""
    import vtk

    from explorer.rendering.scene import Scene, floor_height
    from imm_model.data.dataset import InteractionDataset
    from imm_model.paths import SAMPLE_DATA

    d = InteractionDataset.load(SAMPLE_DATA)
    i = int(np.argmax(d.lengths))
    leader, gt = d.canonical(i)
    sc = Scene(d.skeleton, floor_height(d.leader, d.follower, d.skeleton), size)
    sc.set_sequence(leader, gt, gt)
    sc.camera.set("default")
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(sc.render_window)
    grab.ReadFrontBufferOff()
    grab.ShouldRerenderOff()  # read the frame just rendered (the filter would render it again otherwise)
    jpeg = vtk.vtkJPEGWriter()
    jpeg.SetInputConnection(grab.GetOutputPort())
    jpeg.WriteToMemoryOn()
    jpeg.SetQuality(80)
    sc.render()
    t, c = time.perf_counter(), time.process_time()
    for f in range(frames):
        sc.set_frame(f % len(leader))
        sc.render()
        grab.Modified()
        jpeg.Write()
    wall_ms = (time.perf_counter() - t) / frames * 1000
    cpu_ms = (time.process_time() - c) / frames * 1000  # all of this process's threads (llvmpipe's too)
    sc.close()
    return 1000.0 / wall_ms, 1000.0 / cpu_ms


def _children(pid: int) -> list[int]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(c) for c in path.read_text().split()] if path.exists() else []


def _smaps_mb(pid: int) -> dict[str, float]:
    """RSS; PSS (shared pages divided among the processes sharing them: the processes' PSS add up to what they use
    together); USS (pages this process alone holds: what one more tab costs), in MB."""
    kb = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines()[1:]:
        name, value = line.split(":", 1)
        kb[name] = int(value.split()[0])
    return {"rss": kb["Rss"] / 1024, "pss": kb["Pss"] / 1024, "uss": (kb["Private_Clean"] + kb["Private_Dirty"]) / 1024}


def studio_memory(launcher_pid: int) -> dict:
    """Memory of the zygote (explorer/serving/zygote.py, the launcher's child) and of each studio process it forked."""
    kids = _children(launcher_pid)
    zygotes = [k for k in kids if _children(k)]
    tabs = [k for k in kids if k not in zygotes] + [c for z in zygotes for c in _children(z)]  # the former: no zygote
    readers = [h for t in tabs for h in _children(t)]  # each studio process's upload reader (explorer/serving/upload_reader.py)
    return {"zygote": [_smaps_mb(z) for z in zygotes], "tabs": [_smaps_mb(t) for t in tabs], "readers": [_smaps_mb(h) for h in readers]}


def print_memory(memory: dict, tabs: int) -> None:
    procs = memory["tabs"]
    total_pss = sum(m["pss"] for m in memory["zygote"] + procs + memory["readers"])
    col = lambda key, ms=procs: ", ".join(f"{m[key]:.0f}" for m in ms)  # noqa: E731
    print(f"memory with {tabs} tabs open: {len(procs)} studio processes (one per tab + the warm spare) forked from one "
          f"loaded zygote ({col('rss', memory['zygote'])} MB RSS)\n"
          f"  per studio process: RSS {col('rss')} MB; PSS {col('pss')} MB; USS (its own pages) {col('uss')} MB\n"
          f"  in all (PSS: zygote, studio processes, upload readers): {total_pss:.0f} MB = {total_pss / tabs:.0f} MB per tab   "
          "[goal <= 300 MB per tab]")


def _p(lat: np.ndarray) -> dict:
    return {"p50": float(np.percentile(lat, 50)), "p95": float(np.percentile(lat, 95)), "max": float(lat.max()), "n": len(lat),
            "ms": [round(float(x), 1) for x in lat]}  # every change, to pool several runs


def _say(what: str, lat: np.ndarray, bar: str) -> None:
    print(f"{what} ({len(lat)} changes): p50 {np.percentile(lat, 50):.0f} ms, p95 {np.percentile(lat, 95):.0f} ms, "
          f"max {lat.max():.0f} ms   [bar {bar}]")


def measure_models(browser, studio: probe.StudioProcess, trials: int, res: dict) -> None:
    """6.: the same slider, first with the diffusion model (the one the studio opens with), then with the paper's GAN
    switched on, then with the diffusion model back and three of its variations drawn."""
    page = probe.open_studio(browser, studio.url, *VIEW_SIZE)
    probe.watch_view_images(page)
    # a fresh cache's latent-map fit runs in a process of its own for its first seconds: the first series would
    # measure the fit's share of the cores, not the model's
    probe.wait_state(page, "!s.get('projection_busy')", 180000)
    probe.wait_state(page, "s.get('model_name') === 'diffusion' && !s.get('computing')")
    res["models_slider_ms_diffusion"] = _p(lat := slider_latency(page, trials))
    _say("slider -> redrawn follower, the diffusion model (the default)", lat, "p95 <= 100 ms")
    page.locator("#model-gan").click()
    probe.wait_state(page, "s.get('model_name') === 'gan' && !s.get('computing')")
    res["models_slider_ms_gan"] = _p(lat := slider_latency(page, trials))
    _say("  ... the paper's GAN", lat, "p95 <= 100 ms")
    page.locator("#model-diffusion").click()
    probe.wait_state(page, "s.get('model_name') === 'diffusion' && !s.get('computing')")
    clicks = []
    for _ in range(max(3, trials // 4)):
        n, seed = probe.images_seen(page), probe.state(page, "seed")
        t0 = page.evaluate("() => performance.now()")
        page.locator("#new-variation").click()
        probe.wait_state(page, f"s.get('seed') !== {seed} && !s.get('computing')")
        probe.wait_for_new_image(page, n)
        clicks.append(page.evaluate("([n, t0]) => window.__immImages.slice(n).find(t => t > t0) - t0", [n, t0]))
        time.sleep(0.25)
    res["models_new_variation_ms"] = _p(lat := np.array(clicks, float))
    _say("  ... 'new variation' click -> its picture", lat, "none")
    page.locator("#variation-count").get_by_role("button", name="3").click()
    probe.wait_state(page, "s.get('variation_count') === 3 && !s.get('computing')")
    res["models_slider_ms_diffusion_3"] = _p(lat := slider_latency(page, trials))
    _say("  ... three diffusion variations side by side", lat, "none")
    page.close()


def measure_start(browser, cache: Path, res: dict, model: tuple[str, ...]) -> probe.StudioProcess:
    for kind, bar in (("cold", 5), ("warm", 3)):
        ready, inter, mapped, studio = start_to_interactive(browser, cache, model)
        res[f"{kind}_ready_s"], res[f"{kind}_interactive_s"], res[f"{kind}_map_s"] = ready, inter, mapped
        print(f"start-to-interactive, {kind} latent cache: {inter:.1f} s (URL printed after {ready:.1f} s, latent map shown "
              f"after {mapped:.1f} s)   [bar <= {bar} s]")
        if kind == "cold":
            studio.stop()
    return studio


def first_slider_series(browser, studio: probe.StudioProcess, trials: int, res: dict):
    """Slider latency with the 'reads as' panel in a new page, split by stage; the page."""
    page = probe.open_studio(browser, studio.url, *VIEW_SIZE)
    probe.watch_view_images(page)
    res["slider_ms_page_stages"] = stages = {}
    res["slider_ms"] = _p(lat := slider_latency(page, trials, stages))
    _say("slider -> redrawn follower", lat, "p95 <= 60 ms idle, the panel on")
    _say_stages(stages)
    return page


def measure_sliders(browser, studio: probe.StudioProcess, cache: Path, trials: int, res: dict, model: tuple[str, ...]):
    """Slider latency with the 'reads as' panel, then with a mix pinned, then in a studio without the panel."""
    page = first_slider_series(browser, studio, trials, res)
    page.locator("#pin-mix").click()
    page.wait_for_function("() => !!window.trame.state.get('pinned_text')", timeout=10000)
    res["slider_ms_ab"] = _p(lat := slider_latency(page, trials))
    _say("  ... with a mix pinned (A/B)", lat, "p95 <= 100 ms")
    page.locator("#clear-pin").click()
    # the same without the 'reads as' panel, in the same run (its cost is the difference; the machine is noisy)
    bare = probe.StudioProcess(*model, "--judge", "none", cache_dir=cache, timeout=120)
    try:
        bare_page = probe.open_studio(browser, bare.url, *VIEW_SIZE)
        probe.watch_view_images(bare_page)
        res["slider_ms_without_reads_as"] = _p(lat := slider_latency(bare_page, trials))
        _say("  ... without the 'reads as' panel", lat, "p95 <= 60 ms")
        bare_page.close()
    finally:
        bare.stop()
    return page


def measure_tabs(browser, studio: probe.StudioProcess, trials: int, res: dict, tabs: int = 5) -> None:
    """`tabs` tabs open at once (one studio process each): slider latency in each in turn, and memory."""
    pages = [probe.open_studio(browser, studio.url, *VIEW_SIZE, timeout_ms=120000) for _ in range(tabs)]
    try:
        res["memory_mb"] = studio_memory(studio.proc.pid)
        print_memory(res["memory_mb"], tabs)
        if not trials:
            return
        lats = []
        for page in pages:
            probe.watch_view_images(page)
            lats.append(slider_latency(page, max(4, trials // tabs)))
        res["slider_ms_5_tabs"] = _p(lat := np.concatenate(lats))
        _say(f"slider with {tabs} tabs open", lat, "p95 <= 100 ms")
    finally:
        for page in pages:
            page.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--play-seconds", type=float, default=5.0)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--memory-only", action="store_true", help="only the memory of 5 tabs (CPU load does not skew it)")
    ap.add_argument("--checkpoint", type=Path, default=None, help="the one model every studio serves (default: the bundled ones)")
    ap.add_argument("--models", action="store_true", help="only the model switch's latencies (7.)")
    ap.add_argument("--playback-only", action="store_true", help="only the pictures/s the page displays at 2x (3.)")
    ap.add_argument("--playback-scales", default="", help="with --playback-only: sizes of the pictures while playing, "
                    "fractions of the view's (e.g. 1,0.75,0.5), each measured in turn, --rounds times")
    ap.add_argument("--rounds", type=int, default=3, help="with --playback-scales: rounds over the sizes")
    ap.add_argument("--sliders-only", action="store_true", help="only 2.'s first series, with its split by stage")
    args = ap.parse_args()
    if args.checkpoint and not args.checkpoint.is_file():
        ap.error(f"checkpoint not found: {args.checkpoint}")  # one line, before any studio or browser starts
    model = ("--model", f"model={args.checkpoint}") if args.checkpoint else ()
    from playwright.sync_api import sync_playwright

    res: dict = {"threads": os.cpu_count(), "load_before": os.getloadavg(), "checkpoint": str(args.checkpoint or "bundled")}
    print(f"model: {res['checkpoint']}")
    print(f"machine: {os.cpu_count()} hardware threads, load average {os.getloadavg()[0]:.2f} (other work on the cores skews all numbers)")
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        cache = Path(tmp) / "cache"
        def playback_alone(studio) -> None:
            page = probe.open_studio(browser, studio.url, *VIEW_SIZE)
            probe.watch_view_images(page)
            probe.wait_state(page, "!s.get('projection_busy')", 180000)  # the map's fit off the cores first
            if args.playback_scales:
                measure_playback_scales(page, args.play_seconds, [float(x) for x in args.playback_scales.split(",")],
                                        args.rounds, res)
            else:
                measure_playback(page, args.play_seconds, res)

        alone = (lambda st: measure_models(browser, st, args.trials, res)) if args.models else \
            playback_alone if args.playback_only else \
            (lambda st: first_slider_series(browser, st, args.trials, res)) if args.sliders_only else \
            (lambda st: measure_tabs(browser, st, 0, res)) if args.memory_only else None
        if alone is not None:  # one part of the benchmark, in one studio
            studio = probe.StudioProcess(*model, cache_dir=cache, timeout=120)
            try:
                alone(studio)
            finally:
                studio.stop()
                browser.close()
            if args.json and not args.memory_only:
                args.json.write_text(json.dumps(res, indent=2))
            return 0
        studio = measure_start(browser, cache, res, model)
        try:
            page = measure_sliders(browser, studio, cache, args.trials, res, model)
            measure_playback(page, args.play_seconds, res)
            page.close()
            measure_tabs(browser, studio, args.trials, res)
        finally:
            studio.stop()
            browser.close()
    measure_render(res)
    measure_stages(res)
    res["load_after"] = os.getloadavg()
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    return 0


def measure_playback(page, seconds: float, res: dict) -> None:
    fps, n = displayed_fps(page, seconds)
    res["displayed_fps"] = fps
    print(f"playback at 2x (30 fps target): page displayed {fps:.1f} pictures/s ({n} in {seconds:g} s)   [bar >= 28]")


def measure_playback_scales(page, seconds: float, scales: list[float], rounds: int, res: dict) -> None:
    """Pictures per second displayed at 2x for each size of the pictures while playing (the page's playback_scale),
    the sizes taken in turn, round after round, so that the machine's other work weighs on each alike."""
    from explorer.ui.playback import PLAYBACK_SCALE

    runs: dict[float, list[float]] = {x: [] for x in scales}
    for _ in range(rounds):
        for x in scales:
            probe.set_state(page, "playback_scale", x)
            runs[x].append(displayed_fps(page, seconds)[0])
    probe.set_state(page, "playback_scale", PLAYBACK_SCALE)
    res["displayed_fps_by_scale"] = {str(x): v for x, v in runs.items()}
    base = float(np.median(runs[scales[-1]]))
    for x, v in runs.items():
        m = float(np.median(v))
        print(f"playback at 2x, pictures at {x:g} of the view's size: page displayed {m:.1f} pictures/s median of "
              f"{', '.join(f'{f:.1f}' for f in v)} ({m / base:.2f}x of {scales[-1]:g})   [bar >= 28]")


def measure_stages(res: dict) -> None:
    """Where a slider's time goes on the server, stage by stage (benchmarks/slider_stages.py, in this process): the
    page's key-to-picture time above less these is the websocket, the decoding and the showing."""
    from benchmarks.slider_stages import stage_table

    res["slider_stages"] = lines = stage_table(moves_per_model=20)
    print("slider stages on the server (label -> network -> clean-up -> beside -> reads as -> scene -> render -> "
          "encode; then delivered: the figures above):")
    print("\n".join(f"  {line}" for line in lines))


def measure_render(res: dict) -> None:
    wall_fps, cpu_fps = render_capability()
    res["render_capability_fps"] = {"wall": wall_fps, "per_cpu_second": cpu_fps}
    print(f"server render capability (update + render + JPEG q80, 1052x497): {wall_fps:.0f} fps wall clock, "
          f"{cpu_fps:.0f} frames per CPU-second   [bar >= 30 fps]")
    try:  # the same with this process ahead of background work (root only), to separate code from contention
        os.nice(-10)
        wall_fps, _ = render_capability()
        res["render_capability_fps_prioritized"] = {"wall": wall_fps}
        print(f"  ... at nice -10 (ahead of other work on the machine): {wall_fps:.0f} fps wall clock")
    except PermissionError:
        pass


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except RuntimeError as err:  # a studio that would not start (e.g. a corrupt checkpoint) says why in one line
        raise SystemExit(f"explorer_latency: {err}") from None
