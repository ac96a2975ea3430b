"""The latent map: every sequence's embedding projected to 2D (t-SNE or UMAP), cached on disk, with each
sequence's AFD under its own label (what the map's hover and its AFD colouring show).

Points are the model's per-sequence embeddings of each leader with the sequence's own one-hot label
("real / match"). The current mix (leader + mixed label) is placed on the existing map by
inverse-distance-weighted k-nearest neighbours in latent space: t-SNE cannot embed new points, UMAP's
`transform` costs tens of ms and a numba warm-up, while the kNN placement costs well under 1 ms, is
the same for both methods and never moves the map under the user (docs/architecture.md).
"""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import hashlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imm_model.checkpoint import sidecar_path
from imm_model.data.dataset import InteractionDataset
from imm_model.evaluation.metrics import afd

METHODS = ("tsne", "umap")
# the AFD scorer (`main`) runs below the studio's priority: on a small machine it shares the cores with the page's
# first slider moves, which go first (in the studio's own process the scoring added up to one synthesis, 20-30 ms, to
# a move). The projection fitter does not: the page waits for its map, and at nice 10 beside two busy processes a
# 2.5 s t-SNE fit took 90 s (benchmarks/latent_map_fit.py; docs/experiments/studio-performance.md)
BACKGROUND_NICE = 10
CACHE_VERSION = "1"  # bump when embeddings or projections are computed differently
KNN = 8


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "imm-studio"


def file_digest(path: Path | str, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def cache_key(checkpoint: Path | str, data: Path | str) -> str:
    """Hash of the checkpoint's and the data's bytes: a retrained model or rebuilt bundle misses."""
    h = hashlib.sha256(f"v{CACHE_VERSION}".encode())
    for p in (checkpoint, data):
        h.update(file_digest(p).encode())
        # A sidecar (e.g. the checkpoint's .json config) changes the model too.
        side = sidecar_path(p)
        if side.exists():
            h.update(file_digest(side).encode())
    return h.hexdigest()[:24]


def one_hot_labels(model, data: InteractionDataset) -> np.ndarray:
    c = len(data.class_names)
    eye = np.eye(c, dtype=np.float32)
    return np.stack([np.asarray(model.label_vector(list(eye[a])), np.float32) for a in data.actions])


def embed_all(model, data: InteractionDataset) -> np.ndarray:
    leaders = [data.canonical(i)[0] for i in range(len(data))]
    return np.asarray(model.latent_canonical_batch(leaders, one_hot_labels(model, data)), np.float32)


def project(latents: np.ndarray, method: str, seed: int = 0) -> np.ndarray:
    """(N, D) -> (N, 2), standardized features, deterministic for a seed."""
    from threadpoolctl import threadpool_limits

    x = _standardize(latents, latents)
    # One OpenMP thread: on a busy 2-core machine threaded t-SNE took 4-18 s for 197 points, 0.6 s on one.
    with threadpool_limits(1):
        return _project(x, method, seed)


def _project(x: np.ndarray, method: str, seed: int) -> np.ndarray:
    if method == "tsne":
        from sklearn.manifold import TSNE

        perplexity = float(min(30.0, max(2.0, (len(x) - 1) / 3)))
        y = TSNE(n_components=2, perplexity=perplexity, init="pca", random_state=seed, max_iter=1000).fit_transform(x)
    elif method == "umap":
        import umap  # slow import (numba); only when asked for

        y = umap.UMAP(n_components=2, n_neighbors=min(15, len(x) - 1), min_dist=0.15, random_state=seed).fit_transform(x)
    else:
        raise ValueError(f"projection must be one of {METHODS}, not {method!r}")
    return np.asarray(y, np.float32)


def _standardize(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    mu, sd = ref.mean(0), ref.std(0) + 1e-6
    return (np.asarray(x, np.float64) - mu) / sd


@dataclass
class LatentMap:
    latents: np.ndarray  # (N, D) embeddings with each sequence's own one-hot label
    coords: dict[str, np.ndarray] = field(default_factory=dict)  # method -> (N, 2)
    path: Path | None = None  # cache file, when cached
    afd: np.ndarray | None = None  # (N,) per-sequence AFD under its own label; None until scored (afd_scores)
    # one fit per method at a time: a second request for a method being fitted waits for that fit
    _locks: dict[str, threading.Lock] = field(default_factory=lambda: {m: threading.Lock() for m in METHODS}, repr=False)

    @classmethod
    def build(cls, model, data: InteractionDataset, cache_dir: Path | None, key: str | None, methods=("tsne",)) -> LatentMap:
        """Load from `cache_dir/<key>.npz` or compute the embeddings and save them; then fit the requested
        projections that the cache lacks (none: the studio fits them after it opens, see `fit_elsewhere`)."""
        path = Path(cache_dir) / f"latent-{key}.npz" if (cache_dir and key) else None
        lm = cls.load(path) if path else None
        if lm is None or len(lm.latents) != len(data):
            lm = cls(embed_all(model, data), {}, path)
            lm.save()
        for m in methods:
            lm.ensure(m)
        return lm

    @classmethod
    def load(cls, path: Path) -> LatentMap | None:
        """The cached map, or None when there is none or it cannot be read (a corrupt cache is recomputed)."""
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls(z["latents"], {m: z[m] for m in METHODS if m in z.files}, path, z["afd"] if "afd" in z.files else None)
        except Exception:
            return None

    def has(self, method: str) -> bool:
        return method in self.coords

    def reload(self) -> None:
        """Take the projections another process saved for these latents."""
        other = LatentMap.load(self.path) if self.path else None
        if other is not None and np.array_equal(other.latents, self.latents):
            for m, xy in other.coords.items():
                self.coords.setdefault(m, xy)
            if self.afd is None:
                self.afd = other.afd

    def ensure(self, method: str) -> np.ndarray:
        """The method's map: from memory, from the cache file, or fitted here (once across threads and, through a
        lock on the cache file, across the studio's processes)."""
        if method not in METHODS:
            raise ValueError(f"projection must be one of {METHODS}, not {method!r}")
        with self._locks[method], self._file_lock():
            if method not in self.coords:
                self.reload()
            if method not in self.coords:
                self.coords[method] = project(self.latents, method)
                self._write()
        return self.coords[method]

    @contextlib.contextmanager
    def _file_lock(self, suffix: str = ".lock"):
        if not self.path:
            yield
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path.with_suffix(suffix), "a") as f:  # flock: released even when a fitter is killed
            fcntl.flock(f, fcntl.LOCK_EX)
            yield

    def save(self) -> None:
        """Write the cache file under the file lock a fit holds: a save read between another process's read and write
        of the file would drop what that process saved (an AFD scorer finishing as a fit did lost the fitted map)."""
        with self._file_lock():
            self._write()

    def _write(self) -> None:
        """Write the cache file, keeping what other processes saved; the caller holds the file lock."""
        if not self.path:
            return
        self.reload()
        with tempfile.NamedTemporaryFile(dir=self.path.parent, prefix=self.path.name, suffix=".tmp", delete=False) as f:
            extra = {} if self.afd is None else {"afd": self.afd}
            np.savez(f, latents=self.latents, **dict(self.coords), **extra)
        Path(f.name).replace(self.path)  # atomic: a reader never sees half a file

    def afd_scores(self, model, data: InteractionDataset) -> Iterator[None]:
        """Score every sequence's AFD under its own one-hot label, one sequence per step (a generator: the studio runs
        a step between its other work, so a slider move waits for one synthesis at most, not for all 197: ~2 s on a
        busy core), then save them for every later process. No steps when the cache file has them already."""
        self.reload()
        if self.afd is not None and len(self.afd) == len(data):
            return
        labels = one_hot_labels(model, data)
        scores = []
        for i in range(len(data)):
            leader, real = data.canonical(i)
            scores.append(afd(model.synthesize_canonical(leader, labels[i]), real, data.frame_of(i), data.skeleton, units="normalized"))
            yield
        self.afd = np.asarray(scores, np.float32)
        self.save()

    async def fit_elsewhere(self, method: str) -> None:
        """Fit in a separate process (`python -m explorer.session.latent`), then take its result: a fit holds the GIL for
        seconds (sklearn's import alone is ~1.9 s here, UMAP's numba compilation 10-50 s), and in the studio's
        own process that would stall the page it serves. Without a cache file, in a thread."""
        if not self.path:
            await asyncio.to_thread(self.ensure, method)
            return
        error = await self._elsewhere(method)
        if method not in self.coords:
            raise RuntimeError(error)

    async def score_elsewhere(self, model, data: InteractionDataset, pause_s: float = 0.01) -> None:
        """`afd_scores` in a separate process below the studio's priority (`main`), then take its result: in the
        studio's own process each sequence's synthesis held up a slider move that came meanwhile. Without a cache file,
        or for a model or data not read from files, here, a sequence at a time with `pause_s` between."""
        self.reload()  # another process may have saved them since this map was read (each tab's process asks)
        if self.afd is not None and len(self.afd) == len(data):
            return
        if not (self.path and getattr(model, "path", None) and data.path):
            for _ in self.afd_scores(model, data):
                await asyncio.sleep(pause_s)
            return
        error = await self._elsewhere("afd", str(model.path), str(data.path))
        if self.afd is None:
            raise RuntimeError(error)

    async def _elsewhere(self, *words: str) -> str:
        """Run `python -m explorer.session.latent <cache file> <words>` to its end and take what it saved; -> the last
        line it wrote to stderr (its error, if it saved nothing)."""
        worker = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "explorer.session.latent", str(self.path), *words, WHILE_STDIN_OPEN,
            stdin=asyncio.subprocess.PIPE, stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE,
        )  # fmt: skip
        _, err = await worker.communicate()  # stdin stays open: the work ends with this process, not before
        self.reload()
        lines = err.decode(errors="replace").strip().splitlines() or [f"exit code {worker.returncode}"]
        return lines[-1]

    def place(self, latent: np.ndarray, method: str, k: int = KNN) -> np.ndarray:
        """A new embedding -> 2D, as the inverse-distance-weighted mean of its k nearest neighbours'
        positions on the map (standardized latent space)."""
        coords = self.coords[method]
        x = _standardize(self.latents, self.latents)
        q = _standardize(np.asarray(latent).reshape(1, -1), self.latents)[0]
        d = np.linalg.norm(x - q, axis=1)
        k = min(k, len(d))
        nn = np.argpartition(d, k - 1)[:k]
        w = 1.0 / (d[nn] + 1e-6)
        return (coords[nn] * w[:, None]).sum(0) / w.sum()


WHILE_STDIN_OPEN = "--while-stdin-open"


def _exit_when_stdin_closes() -> None:
    """The studio process that started this fit holds our stdin open: when it ends (its tab closed, the studio
    stopped), the fit ends too instead of running on for seconds (minutes for UMAP) with no one to take it."""

    def watch():
        while os.read(0, 4096):  # the raw descriptor: sys.stdin's lock would stall this process's own exit
            pass
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    """`python -m explorer.session.latent <cache file> <method> [--while-stdin-open]`: fit one projection of a cached map
    and save it; `... <cache file> afd <checkpoint> <data> [--while-stdin-open]`: score every sequence's AFD with that
    model (`LatentMap.afd_scores`) and save them, once across processes (a second scorer waits for the first and reads
    its scores) at BACKGROUND_NICE. Either stops if stdin closes first. Bad arguments get one line on stderr and exit
    code 2 (the studio shows that line)."""
    args = sys.argv[1:] if argv is None else argv
    if args[-1:] == [WHILE_STDIN_OPEN]:
        args = args[:-1]
        _exit_when_stdin_closes()
    task = args[1] if len(args) > 1 else ""
    if not ((len(args) == 2 and task in METHODS) or (len(args) == 4 and task == "afd")):
        print(f"usage: python -m explorer.session.latent <cache file> <{'|'.join(METHODS)}> [{WHILE_STDIN_OPEN}], or <cache file> "
              f"afd <checkpoint> <data> [{WHILE_STDIN_OPEN}], not {' '.join(args)!r}", file=sys.stderr)  # fmt: skip
        return 2
    if task == "afd":
        os.nice(BACKGROUND_NICE)
    latent_map = LatentMap.load(Path(args[0]))
    if latent_map is None:
        print(f"latent map cache {args[0]} cannot be read", file=sys.stderr)
        return 2
    if task in METHODS:
        latent_map.ensure(task)
        return 0
    from explorer.session.words import one_line
    from imm_model.errors import IMMError
    from imm_model.inference import ReactionModel

    try:
        model, data = ReactionModel.load(Path(args[2])), InteractionDataset.load(Path(args[3]))
    except (IMMError, OSError) as err:
        print(f"cannot score the AFDs: {one_line(err)}", file=sys.stderr)
        return 2
    with latent_map._file_lock(".afd-lock"):
        for _ in latent_map.afd_scores(model, data):
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
