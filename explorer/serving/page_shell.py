"""The page's shell: trame's index.html with static/websocket_bytes.js run before trame's client, served by every
studio process as its main web content. Binary websocket messages then reach wslink as bytes instead of Blobs that
it reads back asynchronously (~20 ms between a picture's arrival and its display, measured in docs/experiments/studio-performance.md).
The shell also carries static/page_aids.js (the 3D view's joint readout, a row scrolled into sight) and
static/latent_map.js, the latent map's Plotly figure. That script loads plotly.js after the page's first picture from
the launcher's /static/, at one path for every tab with the plotly.js version in its name: plotly.js's basic bundle
(its scatter, bar and pie traces; 1.2 MB, evaluated in a fifth of the full bundle's time), vendored in static/vendor/
because no Python package carries it (static/vendor/README.md).

The rest of what the page loads (vue, vuetify and its fonts, trame's client: 2.3 MB) also comes from the launcher,
at /static/<the shell's key>/: trame's index.html names its files there, and the module scripts and styles trame's
client loads are named there too (explorer/trame_adapter.py, relocate_assets). One URL for every tab, so a second
tab and a reload take all of it from the browser's cache; under each tab's own /s/<id>/ every tab downloaded it again.

The shell is written once per content into the studio's cache folder, `page-<key>` (a copy of trame's 0.3 MB client
folder with the new index.html, and a link to each module folder the page loads from), and found there by every
later studio process; the launcher serves that folder's files (the studio process names it in its READY line).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

from explorer.trame_adapter import CLIENT_FIRST_SCRIPT, client_www, module_assets, relocate_assets, serve_page

STATIC = Path(__file__).resolve().parents[1] / "static"  # explorer/static
BYTES_SCRIPT = STATIC / "websocket_bytes.js"
LATENT_SCRIPT = STATIC / "latent_map.js"
AIDS_SCRIPT = STATIC / "page_aids.js"  # the 3D view's joint readout, a table row scrolled into sight
PLOTLY_SRC = "static/plotly.min.js"  # in static/latent_map.js: PLOTLY_JS's name in the page
PLOTLY_JS = STATIC / "vendor" / "plotly-basic-4.1.1.min.js"  # a new version must have a new name: browsers keep it a year
ANCHOR = CLIENT_FIRST_SCRIPT  # trame's first script: ours go before it
SHARED = "../../static/"  # from the tab's page (<prefix>/s/<id>/) to the launcher's /static/ (a proxy's prefix kept)
FILE_URL = re.compile(r'\b(src|href)="(?:\./)?([\w.-]+(?:/[\w.-]+)*)"')  # a file of trame's client, in its index


def use_page_shell(server, cache_dir: Path) -> Path:
    """Serve the shell as `server`'s page, its module scripts and styles named under the launcher's /static/<key>/;
    call once the studio's modules are enabled, before the server starts. -> the shell's folder."""
    folders = module_assets(server)
    shell = page_shell(cache_dir, folders)
    relocate_assets(server, folders, f"{SHARED}{shell_key(shell)}/")
    serve_page(server, shell, {})
    return shell


def shell_key(shell: Path) -> str:
    return shell.name.removeprefix("page-")


def shell_index(trame_index: str, shared: str = "", files: frozenset[str] = frozenset()) -> str:
    """trame's index.html -> the studio's: the websocket and latent map scripts inline, before trame's scripts; the
    `files` of trame's client that it names, from `shared` + their path."""
    if ANCHOR not in trame_index:
        return trame_index  # another trame client layout: serve it unchanged rather than guess
    latent = LATENT_SCRIPT.read_text().replace(PLOTLY_SRC, f"static/{PLOTLY_JS.name}")
    scripts = "".join(f"<script>{text}</script>" for text in (BYTES_SCRIPT.read_text(), latent, AIDS_SCRIPT.read_text()))
    head, rest = trame_index.split(ANCHOR, 1)

    def relocated(html: str) -> str:
        return FILE_URL.sub(lambda m: f'{m[1]}="{shared}{m[2]}"' if m[2] in files else m[0], html) if shared else html

    return relocated(head) + scripts + relocated(ANCHOR + rest)


def page_shell(cache_dir: Path, folders: dict[str, str] | None = None) -> Path:
    """The folder to serve as the page (built on first use; concurrent studio processes build it once), with a link
    to each of `folders` ({url: folder}, the module folders its scripts and styles come from)."""
    source = client_www()
    trame_index = (source / "index.html").read_text()
    folders = dict(sorted((folders or {}).items()))
    files = frozenset(p.relative_to(source).as_posix() for p in source.rglob("*") if p.is_file()) - {"index.html"}
    content = json.dumps([shell_index(trame_index), str(source), sorted(files), folders])
    key = hashlib.sha256(content.encode()).hexdigest()[:16]
    shell = cache_dir / f"page-{key}"
    if (shell / "index.html").is_file():
        return shell
    cache_dir.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(prefix="page-", dir=cache_dir))
    shutil.copytree(source, building, dirs_exist_ok=True, ignore=shutil.ignore_patterns("index.html"))
    for url, folder in folders.items():
        if not (building / url).exists():
            (building / url).symlink_to(folder, target_is_directory=True)
    (building / "index.html").write_text(shell_index(trame_index, f"{SHARED}{key}/", files))
    try:
        os.rename(building, shell)  # atomic: a page is never served half-written
    except OSError:  # another studio process built it first
        shutil.rmtree(building, ignore_errors=True)
    return shell
