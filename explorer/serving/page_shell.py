"""The page's shell: trame's index.html with static/websocket_bytes.js run before trame's client, served by every
studio process as its main web content. Binary websocket messages then reach wslink as bytes instead of Blobs that
it reads back asynchronously (~20 ms between a picture's arrival and its display, measured in docs/experiments/studio-performance.md).
The shell also carries static/latent_map.js, the latent map's Plotly figure. That script loads plotly.js (from the
plotly package, 4.8 MB) after the page's first picture from the launcher's /static/, at one path for every tab with
the plotly.js version in its name (plotly_name), so a second tab and a reload take it from the browser's cache; under
each tab's own /s/<id>/ every tab downloaded it again.

The shell is written once per content into the studio's cache folder (a copy of trame's 0.3 MB client folder with
the new index.html) and found there by every later studio process.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import re
import shutil
import tempfile
from pathlib import Path

from explorer.trame_adapter import CLIENT_FIRST_SCRIPT, client_www, serve_page

STATIC = Path(__file__).resolve().parents[1] / "static"  # explorer/static
BYTES_SCRIPT = STATIC / "websocket_bytes.js"
LATENT_SCRIPT = STATIC / "latent_map.js"
PLOTLY_SRC = "static/plotly.min.js"  # in static/latent_map.js: named with its version in the page
PLOTLY_VERSION = re.compile(rb"plotly\.js v([0-9][0-9A-Za-z.+-]*)")  # the file's first line: "* plotly.js v4.1.1"
ANCHOR = CLIENT_FIRST_SCRIPT  # trame's first script: ours go before it


def use_page_shell(server, cache_dir: Path) -> None:
    """Serve the shell as `server`'s page: call once the studio's modules are enabled, before the server starts."""
    serve_page(server, page_shell(cache_dir), {})


def plotly_js() -> Path:
    """The plotly package's plotly.min.js (found without importing plotly)."""
    spec = importlib.util.find_spec("plotly")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("the studio's latent map needs plotly (pip install 'imm-studio[studio]')")
    return Path(spec.submodule_search_locations[0]) / "package_data" / "plotly.min.js"


@functools.cache
def plotly_name() -> str:
    """plotly.min.js's name under the launcher's /static/: plotly-<plotly.js version>.min.js, read from the file's
    first line (the browser keeps the file for a year: a new version must have a new name); a content hash for a
    file that names no version."""
    path = plotly_js()
    with path.open("rb") as f:
        found = PLOTLY_VERSION.search(f.read(200))
    tag = found.group(1).decode() if found else hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    return f"plotly-{tag}.min.js"


def shell_index(trame_index: str) -> str:
    """trame's index.html -> the studio's: the websocket and latent map scripts inline, before trame's scripts."""
    if ANCHOR not in trame_index:
        return trame_index  # another trame client layout: serve it unchanged rather than guess
    latent = LATENT_SCRIPT.read_text().replace(PLOTLY_SRC, f"static/{plotly_name()}")
    scripts = "".join(f"<script>{text}</script>" for text in (BYTES_SCRIPT.read_text(), latent))
    return trame_index.replace(ANCHOR, scripts + ANCHOR, 1)


def page_shell(cache_dir: Path) -> Path:
    """The folder to serve as the page (built on first use; concurrent studio processes build it once)."""
    source = client_www()
    index = shell_index((source / "index.html").read_text())
    key = hashlib.sha256(index.encode() + str(source).encode()).hexdigest()[:16]
    shell = cache_dir / f"page-{key}"
    if (shell / "index.html").is_file():
        return shell
    cache_dir.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(prefix="page-", dir=cache_dir))
    shutil.copytree(source, building, dirs_exist_ok=True, ignore=shutil.ignore_patterns("index.html"))
    (building / "index.html").write_text(index)
    try:
        os.rename(building, shell)  # atomic: a page is never served half-written
    except OSError:  # another studio process built it first
        shutil.rmtree(building, ignore_errors=True)
    return shell
