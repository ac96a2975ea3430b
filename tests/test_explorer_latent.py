"""Latent map: cache key, on-disk cache, kNN placement of the current mix."""

from __future__ import annotations

import contextlib
import os

import numpy as np
import pytest

pytest.importorskip("sklearn")


class TinyModel:
    """Stands in for ReactionModel's embedding call: deterministic features of leader + label."""

    def __init__(self, data):
        self.class_names = data.class_names
        self.calls = 0

    def label_vector(self, label, scale=1.0):
        return np.asarray(label, np.float32) * scale

    def latent_canonical_batch(self, leaders, label_vectors):
        self.calls += 1
        feats = np.stack([np.concatenate([a.mean(0).ravel(), a.std(0).ravel()]) for a in leaders])
        return np.concatenate([feats, 3 * np.asarray(label_vectors)], 1).astype(np.float32)


def test_cache_key_follows_file_contents(tmp_path):
    from explorer.session.latent import cache_key

    a, b = tmp_path / "a.safetensors", tmp_path / "d.npz"
    a.write_bytes(b"weights-1")
    b.write_bytes(b"data")
    k1 = cache_key(a, b)
    assert k1 == cache_key(a, b)
    a.write_bytes(b"weights-2")
    assert cache_key(a, b) != k1
    a.write_bytes(b"weights-1")
    a.with_suffix(".json").write_text("{}")  # the checkpoint's sidecar is part of the model
    assert cache_key(a, b) != k1


def test_build_caches_and_places(tmp_path, sample_data, monkeypatch):
    from explorer.session import latent
    model = TinyModel(sample_data)
    lm = latent.LatentMap.build(model, sample_data, tmp_path, "k1")
    xy = lm.coords["tsne"]
    assert xy.shape == (len(sample_data), 2) and np.isfinite(xy).all()
    assert (tmp_path / "latent-k1.npz").exists()

    # Second build: read from disk, no embedding and no projection recomputed.
    monkeypatch.setattr(latent, "project", lambda *a, **k: pytest.fail("projection recomputed despite the cache"))
    again = latent.LatentMap.build(model, sample_data, tmp_path, "k1")
    assert model.calls == 1
    np.testing.assert_array_equal(again.coords["tsne"], xy)

    # A point equal to an existing embedding lands on that point; any point lands inside the map.
    np.testing.assert_allclose(again.place(again.latents[7], "tsne"), xy[7], atol=1e-2)
    p = again.place(again.latents[7] + 0.5, "tsne")
    assert (xy.min(0) <= p).all() and (p <= xy.max(0)).all()


def test_corrupt_cache_is_recomputed(tmp_path, sample_data):
    from explorer.session import latent
    (tmp_path / "latent-bad.npz").write_bytes(b"not a zip")
    lm = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "bad")
    assert lm.coords["tsne"].shape == (len(sample_data), 2)


def test_unknown_projection(sample_data):
    from explorer.session.latent import project

    with pytest.raises(ValueError, match="projection must be one of"):
        project(np.zeros((5, 3)), "pca")


def test_concurrent_requests_share_one_fit_per_method(tmp_path, monkeypatch):
    """Ten UMAP requests while the first fit runs (as from ten toggles in the page): one fit, one cache file,
    no temporary file left behind, no error."""
    import threading
    import time

    from explorer.session import latent as latent_module
    calls, waiting = [], []

    class CountingLock:
        """The map's lock for one method, counting the requests that reached it."""

        def __init__(self):
            self.lock, self.arrived, self.count_lock = threading.Lock(), 0, threading.Lock()

        def __enter__(self):
            with self.count_lock:
                self.arrived += 1
            self.lock.acquire()

        def __exit__(self, *exc):
            self.lock.release()

    def slow_project(latents, method, seed=0):
        calls.append(method)
        deadline = time.monotonic() + 60
        while lock.arrived < len(threads) and time.monotonic() < deadline:  # the fit runs until all ten are waiting
            time.sleep(0.01)
        waiting.append(lock.arrived)
        return np.zeros((len(latents), 2), np.float32) + len(calls)

    monkeypatch.setattr(latent_module, "project", slow_project)
    lm = latent_module.LatentMap(np.random.default_rng(0).normal(size=(20, 8)).astype(np.float32), {}, tmp_path / "latent-x.npz")
    lm._locks["umap"] = lock = CountingLock()
    errors = []

    def request():
        try:
            lm.ensure("umap")
        except Exception as err:  # noqa: BLE001 - any error fails the test below
            errors.append(err)

    threads = [threading.Thread(target=request) for _ in range(10)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == [] and calls == ["umap"] and waiting == [len(threads)]  # all ten came while it ran
    assert sorted(p.name for p in tmp_path.iterdir()) == ["latent-x.lock", "latent-x.npz"]  # no temporary file left


def test_a_fit_in_another_process_is_taken_not_repeated(tmp_path, sample_data):
    """What the studio does on a cold cache: the loader saves the embeddings only; a separate process
    (`python -m explorer.session.latent`, as LatentMap.fit_elsewhere runs it) fits t-SNE; the studio takes that result, and so
    does a later ensure() in any process, without fitting again."""
    import asyncio

    from explorer.session import latent
    lm = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "k2", methods=())
    assert not lm.has("tsne") and (tmp_path / "latent-k2.npz").exists()
    asyncio.run(lm.fit_elsewhere("tsne"))
    assert lm.coords["tsne"].shape == (len(sample_data), 2)
    other = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "k2", methods=())
    np.testing.assert_array_equal(other.coords["tsne"], lm.coords["tsne"])
    with pytest.raises(RuntimeError, match="usage: python -m explorer.session.latent"):
        asyncio.run(lm.fit_elsewhere("pca"))


def test_the_fit_runs_at_the_studios_priority(tmp_path, sample_data):
    """The page waits for its map: the fitting process keeps the studio's priority (the AFD scorer, background work,
    runs below it). Seen once it has opened the cache file's lock (which this test holds), past where it would lower
    its priority."""
    import fcntl
    import subprocess
    import sys
    import time

    from explorer.session import latent

    lm = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "k4", methods=())
    ours = os.getpriority(os.PRIO_PROCESS, 0)
    with open(lm.path.with_suffix(".lock"), "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        fitter = subprocess.Popen([sys.executable, "-m", "explorer.session.latent", str(lm.path), "tsne"], stderr=subprocess.PIPE)
        lock, deadline = str(lm.path.with_suffix(".lock")), time.monotonic() + 60

        def has_the_lock_open() -> bool:
            with contextlib.suppress(OSError):
                return any(os.readlink(f"/proc/{fitter.pid}/fd/{fd}") == lock for fd in os.listdir(f"/proc/{fitter.pid}/fd"))
            return False

        while not has_the_lock_open():
            assert fitter.poll() is None and time.monotonic() < deadline, "the fitter ended or never opened the lock"
            time.sleep(0.01)
        assert os.getpriority(os.PRIO_PROCESS, fitter.pid) == ours
    assert fitter.wait(60) == 0, fitter.stderr.read()
    assert latent.LatentMap.load(lm.path).has("tsne")


def test_a_save_keeps_a_map_fitted_while_it_was_being_written(tmp_path, sample_data, monkeypatch):
    """Two processes on one cache file: the AFD scorer saves its scores just as a fit saves its map. The scorer's save
    holds the file's lock from its read of the file to its write, so the fit's map, saved after, is kept beside the
    scores (without the lock the scorer's write, from a read before the fit's, dropped the map)."""
    import threading

    from explorer.session import latent

    scorer = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "k5", methods=())
    fitter = latent.LatentMap(scorer.latents.copy(), path=scorer.path)  # the other process's map, read at its start
    fit = threading.Thread(target=fitter.ensure, args=("tsne",))
    read = latent.LatentMap.reload

    def reload_then_let_the_fit_run(self):
        read(self)
        if self is scorer and not fit.is_alive():
            fit.start()
            fit.join(timeout=5)  # the fit's save waits for this save: it cannot end meanwhile

    monkeypatch.setattr(latent.LatentMap, "reload", reload_then_let_the_fit_run)
    scorer.afd = np.ones(len(sample_data), np.float32)
    scorer.save()
    fit.join(60)
    saved = latent.LatentMap.load(scorer.path)
    assert saved.has("tsne") and saved.afd is not None
    np.testing.assert_array_equal(saved.coords["tsne"], fitter.coords["tsne"])


def test_the_fit_command_answers_bad_arguments_in_one_line(tmp_path):
    import subprocess
    import sys

    from explorer.session.latent import LatentMap

    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    cache = tmp_path / "good.npz"
    LatentMap(np.zeros((3, 2), np.float32), path=cache).save()
    for args, needle in (([], "usage"), ([str(tmp_path / "x.npz"), "pca"], "usage"),
                         ([str(tmp_path / "bad.npz"), "tsne"], "cannot be read"),
                         ([str(tmp_path / "missing.npz"), "umap"], "cannot be read"),
                         ([str(tmp_path / "x.npz"), "afd", "model.safetensors"], "usage"),
                         ([str(cache), "afd", str(tmp_path / "none.safetensors"), str(tmp_path / "x.npz")], "cannot score")):  # fmt: skip
        proc = subprocess.run([sys.executable, "-m", "explorer.session.latent", *args], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2 and needle in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_per_sequence_afd_is_scored_once_and_cached(tmp_path, sample_data):
    """Each sequence's AFD under its own label (the map's hover and AFD colouring), saved beside the projections: a
    second map on the same cache reads it back instead of re-synthesizing; a follower equal to the real one scores 0."""
    from explorer.session import latent
    class Copier(TinyModel):
        """Synthesizes the real follower exactly for odd sequences and a shifted one for even ones."""

        def __init__(self, data):
            super().__init__(data)
            self.data, self.synths = data, 0

        def synthesize_canonical(self, leader, label_vector):
            self.synths += 1
            i = next(j for j in range(len(self.data)) if self.data.canonical(j)[0] is leader or
                     np.array_equal(self.data.canonical(j)[0], leader))
            real = self.data.canonical(i)[1]
            return real if i % 2 else real + np.float32(0.1)

    subset = sample_data.subset(list(range(6)))
    model = Copier(subset)
    lm = latent.LatentMap.build(model, subset, tmp_path, "afd", methods=())
    assert lm.afd is None
    steps = lm.afd_scores(model, subset)
    next(steps)
    assert model.synths == 1 and lm.afd is None  # one sequence per step
    assert len(list(steps)) == 5 and model.synths == 6
    scores = lm.afd
    assert scores.shape == (6,) and np.all(scores[1::2] == 0) and np.all(scores[0::2] > 0)
    again = latent.LatentMap.build(model, subset, tmp_path, "afd", methods=())
    assert list(again.afd_scores(model, subset)) == [] and model.synths == 6  # read from the cache file
    np.testing.assert_array_equal(again.afd, scores)


def test_the_afds_are_scored_in_a_process_of_its_own_below_the_studios_priority(tmp_path, sample_data, monkeypatch):
    """The studio's map scores its AFDs in `python -m explorer.session.latent <cache> afd <checkpoint> <data>` at
    BACKGROUND_NICE, not between the page's slider moves: the scores equal those made in the studio's own process (as
    a map without a cache file still makes them), and a second map on the cache reads them back."""
    import asyncio
    import subprocess
    import sys
    import time

    from explorer.session import latent
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_GAN

    gan = ReactionModel.load(SAMPLE_GAN)
    lm = latent.LatentMap.build(gan, sample_data, tmp_path, "gan", methods=())
    scorer = subprocess.Popen([sys.executable, "-m", "explorer.session.latent", str(lm.path), "afd", str(SAMPLE_GAN),
                               str(sample_data.path), latent.WHILE_STDIN_OPEN], stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    niceness = os.getpriority(os.PRIO_PROCESS, 0)
    seen = niceness
    while scorer.poll() is None and seen == niceness:
        with contextlib.suppress(ProcessLookupError):
            seen = os.getpriority(os.PRIO_PROCESS, scorer.pid)
        time.sleep(0.005)
    assert seen == min(niceness + latent.BACKGROUND_NICE, 19)
    scorer.stdin.close()  # the studio's process ended: the scorer ends too, its scores unsaved
    assert scorer.wait(60) == 1 and latent.LatentMap.load(lm.path).afd is None
    asyncio.run(lm.score_elsewhere(gan, sample_data))
    here = latent.LatentMap(lm.latents)  # no cache file: scored in this process
    asyncio.run(here.score_elsewhere(gan, sample_data, 0))
    assert lm.afd.shape == (len(sample_data),) and np.isfinite(lm.afd).all()
    np.testing.assert_allclose(lm.afd, here.afd, rtol=1e-5)
    np.testing.assert_array_equal(latent.LatentMap.build(gan, sample_data, tmp_path, "gan", methods=()).afd, lm.afd)
    stale = latent.LatentMap(lm.latents, path=lm.path)  # a tab's map, read before the scores were saved: no scorer
    monkeypatch.setattr(latent.asyncio, "create_subprocess_exec", lambda *a, **k: pytest.fail("scored again"))
    asyncio.run(stale.score_elsewhere(gan, sample_data))
    np.testing.assert_array_equal(stale.afd, lm.afd)


def test_the_selection_list_sorts_worst_first_by_id_or_class(sample_data):
    from types import SimpleNamespace

    from explorer.session.latent import LatentMap
    from explorer.ui.latent_panel import LatentPanel

    panel = LatentPanel.__new__(LatentPanel)  # rows() needs only the session's data and the map's AFDs
    panel.page = SimpleNamespace(session=SimpleNamespace(data=sample_data, class_names=sample_data.class_names))
    panel.latent = LatentMap(np.zeros((len(sample_data), 2), np.float32))
    picked = [40, 3, 120, 3, 9999, -1]  # a repeat and indices off the map are dropped
    assert [r["i"] for r in panel.rows(picked, "afd")] == [3, 40, 120] and panel.rows(picked, "afd")[0]["afd"] is None
    panel.latent.afd = np.arange(len(sample_data), dtype=np.float32) % 50
    assert [r["afd"] for r in panel.rows(picked, "afd")] == [40.0, 20.0, 3.0]
    by_id = [r["id"] for r in panel.rows(picked, "id")]
    assert by_id == sorted(by_id)
    by_class = [r["cls"] for r in panel.rows(picked, "class")]
    assert by_class == sorted(by_class) and {r["held"] for r in panel.rows(range(len(sample_data)), "id")} == {True, False}


def test_the_fit_at_a_pages_start_waits_for_its_slider_moves_to_rest(monkeypatch):
    """A cold cache's fit starts FIT_DELAY_S after the page opens, once no follower has been drawn for FIT_QUIET_S: a
    series of slider moves goes first. A page that never rests gets its fit FIT_LATEST_S after it opened."""
    import asyncio
    import time

    from explorer.ui import latent_panel

    monkeypatch.setattr(latent_panel, "FIT_DELAY_S", 0.1)
    monkeypatch.setattr(latent_panel, "FIT_QUIET_S", 0.3)
    monkeypatch.setattr(latent_panel, "FIT_LATEST_S", 1.5)
    panel = latent_panel.LatentPanel.__new__(latent_panel.LatentPanel)  # _rest needs only the time of the last draw
    panel._last_redraw = 0.0

    async def started_after(moves_for: float) -> tuple[float, float]:
        """-> (seconds until the fit may start, seconds until the last follower drawn), followers drawn every 50 ms."""
        start = time.monotonic()
        rest = asyncio.ensure_future(panel._rest())
        while time.monotonic() - start < moves_for and not rest.done():
            panel._last_redraw = time.monotonic()
            await asyncio.sleep(0.05)
        last = panel._last_redraw - start
        await rest
        return time.monotonic() - start, last

    waited, _ = asyncio.run(started_after(0))
    assert 0.1 <= waited < 1.0  # nothing drawn: the delay only
    waited, last = asyncio.run(started_after(0.6))
    assert waited >= last + 0.3 and waited >= 0.6  # after the moves, and a rest of FIT_QUIET_S
    waited, last = asyncio.run(started_after(10))
    assert 1.5 <= waited < 5 and last >= 1.4  # moves that go on: at FIT_LATEST_S, while they still came


def test_a_fit_ends_when_the_studio_process_that_started_it_does(tmp_path, sample_data):
    """The studio holds the fit's stdin open: once it closes (the tab's process ended, the studio stopped) the fit
    stops instead of running on with no one to take its result."""
    import subprocess
    import sys

    from explorer.session import latent

    lm = latent.LatentMap.build(TinyModel(sample_data), sample_data, tmp_path, "k3", methods=())
    fitter = subprocess.Popen([sys.executable, "-m", "explorer.session.latent", str(lm.path), "tsne", latent.WHILE_STDIN_OPEN],
                              stdin=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    fitter.stdin.close()
    assert fitter.wait(60) == 1, fitter.stderr.read()
    assert not latent.LatentMap.load(lm.path).has("tsne")
