"""Time of the studio's review across sequences (imm_model/evaluation/review.py, explorer/ui/review_panel.py) on the
bundled held-out split (fold s04), on one thread:

    OMP_NUM_THREADS=1 python benchmarks/review_table.py [--repeats 3] [--chunk 1 4 64] [--no-studio] [--no-library]

First, in the studio as a user sees it (headless Chromium, /usr/bin/chromium): from the click on "Review across
sequences" in a fresh tab to the first rows of the table on screen, and to the whole table (every model of the session,
the feature distances last), each row under its own class. Then the library alone: the classifiers' load (the
interaction classifier is trained and cached on first use, which this does not time) and, per model, the table's wall
time (best and median of the repeats; one batched synthesis each) and its rows.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--chunk", type=int, nargs="*", default=[],
                    help="also time the diffusion table with these rows per sampler call (review.CPU_SAMPLER_CHUNK)")
    ap.add_argument("--no-studio", action="store_true", help="skip the timing in the studio's page")
    ap.add_argument("--no-library", action="store_true", help="skip the library's per-model timing")
    args = ap.parse_args()
    if not args.no_studio:
        studio_first_table(args.repeats)
    if not args.no_library:
        library_tables(args)


# Set before the click: the time of the first table row on screen and of the end of the computation (spinner gone).
WATCH_JS = """() => { const t0 = performance.now(); window.__review = {first: null, done: null};
    new MutationObserver(() => { const r = window.__review, now = performance.now() - t0;
        if (r.first === null && document.querySelector('#review-table tr.review-row')) r.first = now;
        if (r.first !== null && r.done === null && !window.trame.state.get('review_busy')) r.done = now;
    }).observe(document.body, {childList: true, subtree: true, attributes: true}); }"""


def studio_first_table(repeats: int) -> None:
    """The review's first table in a fresh tab of `imm explore` (a new tab per repeat: its studio process has loaded
    nothing of the review yet)."""
    import tempfile
    from pathlib import Path

    from playwright.sync_api import sync_playwright

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the studio driver lives beside the tests
    from tests import studio_probe as probe

    firsts, dones, rows = [], [], 0
    with tempfile.TemporaryDirectory() as cache, probe.StudioProcess(cache_dir=Path(cache)) as studio, sync_playwright() as p:
        browser = probe.launch_chromium(p)
        for _ in range(repeats):
            page = probe.open_studio(browser, studio.url, 1366, 768)
            page.wait_for_selector(probe.LATENT_POINTS, timeout=120000)  # the page settled, as a user would find it
            page.evaluate(WATCH_JS)
            page.click("#review-open")
            page.wait_for_function("() => window.__review.done !== null", timeout=600000)
            timing = page.evaluate("() => window.__review")
            rows = probe.state(page, "review_rows")
            firsts.append(timing["first"] / 1000)
            dones.append(timing["done"] / 1000)
            page.close()
        browser.close()
    models = sum(1 for key in rows[0] if key.startswith("m") and key[1:].isdigit()) if rows else 0
    print(f"studio, first table: first rows on screen {min(firsts):.2f} s best, {statistics.median(firsts):.2f} s median; "
          f"whole table ({len(rows)} rows x {models} models, feature distances included) {statistics.median(dones):.2f} s median "
          f"of {repeats} fresh tabs", flush=True)


def library_tables(args) -> None:
    import torch

    torch.set_num_threads(1)
    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation import review
    from imm_model.evaluation.review import ReviewThresholds, fold_interaction_features, real_foot_threshold, review_table
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA, SAMPLE_DIFFUSION, SAMPLE_GAN, SAMPLE_JUDGE
    from imm_model.reads_as import ReadsAs

    DEFAULT_CHUNK = review.CPU_SAMPLER_CHUNK
    data = InteractionDataset.load(SAMPLE_DATA)
    t0 = time.perf_counter()
    judge = ReadsAs.load(SAMPLE_JUDGE)
    features = fold_interaction_features(data, "s04", progress=True)
    t1 = time.perf_counter()
    thresholds = ReviewThresholds(real_foot_threshold(data))
    t2 = time.perf_counter()
    print(f"judge + interaction classifier loaded in {t1 - t0:.2f} s; foot threshold "
          f"{thresholds.foot_skate_mps:.3f} m/s from the real followers in {t2 - t1:.2f} s")
    runs = [("gan", SAMPLE_GAN, None), ("diffusion", SAMPLE_DIFFUSION, None)]
    runs += [(f"diffusion, {c} rows per call", SAMPLE_DIFFUSION, c) for c in args.chunk]
    for name, path, chunk in runs:
        model = ReactionModel.load(path)
        review.CPU_SAMPLER_CHUNK = chunk or DEFAULT_CHUNK
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            rows = review_table(model, data, judge=judge, features=features, thresholds=thresholds)
            times.append(time.perf_counter() - start)
        flagged = sum(r.contact_flag or r.foot_flag for r in rows)
        print(f"{name}: {len(rows)} rows in {min(times):.2f} s best, {statistics.median(times):.2f} s median of "
              f"{args.repeats} (mean AFD {sum(r.afd for r in rows) / len(rows):.3f}, {flagged} rows flagged)")


if __name__ == "__main__":
    main()
