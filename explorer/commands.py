"""`imm explore`: start the studio (registered through the `imm.commands` entry point).

trame and VTK are imported by the studio processes only, so `imm --help` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from explorer.serving.worker import model_argument


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "explore",
        help="open the studio: watch, mix and compare synthesized reactions in the browser",
        description="Start IMM Studio (a local web app). Each browser tab gets its own studio process.",
    )
    p.add_argument("--data", type=Path, default=None, help="interaction bundle .npz (default: the bundled SBU sample)")
    p.add_argument("--model", action="append", default=None, metavar="NAME=CHECKPOINT", type=model_argument,
                   help="a model the studio offers, by name (repeat it for several; the first opens the studio and its "
                        "latent map is the one shown). Default: the bundled ones, diffusion, gan and retrieval")
    p.add_argument("--port", type=int, default=None,
                   help="port to listen on; 0 picks a free one (printed). Default 8080 (with --desktop: a free one)")
    p.add_argument(
        "--host", default="127.0.0.1",
        help="address to bind (default 127.0.0.1: this machine only; 0.0.0.0 exposes the studio to your network)",
    )  # fmt: skip
    p.add_argument("--token", default=None,
                   help="access token required in the first URL (default: none on 127.0.0.1; a random one for any other --host)")
    p.add_argument("--no-auth", action="store_true", help="with a non-loopback --host: serve anyone who can reach the port")
    p.add_argument("--base-url", default=None,
                   help="the address users open when a reverse proxy serves the studio under a path, e.g. "
                        "https://lab.example.org/imm/ (printed instead of the local address; every page URL is relative)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser window")
    p.add_argument("--desktop", action="store_true",
                   help="open the studio in a window of its own instead of a browser (needs a display and the "
                        "'desktop' extra); closing the window stops the studio")
    p.add_argument("--cache-dir", type=Path, default=None, help="latent-map cache (default: ~/.cache/imm-studio)")
    p.add_argument("--export-dir", type=Path, default=Path("imm-exports"), help="where exports are also saved (default ./imm-exports)")
    p.add_argument("--max-clients", type=int, default=8, help="most browser tabs served at once (one process each). Default 8")
    p.add_argument(
        "--render", choices=("remote", "local"), default="remote",
        help="remote (default): the server renders pictures; local: the browser renders with vtk.js (needs WebGL)",
    )  # fmt: skip
    p.add_argument("--sequence", default=None, help="sequence id (e.g. s04s02/01/001) or index to open first")
    p.add_argument("--judge", default=None,
                   help="follower-only classifier for the 'reads as' panel (default: the bundled one, with the bundled body-part "
                        "judges for mixes by body part; a custom one reads the whole body only; 'none' hides the panel)")
    p.set_defaults(func=run_explore)


STUDIO_MODULES = ("trame", "trame_vuetify", "trame_vtk", "trame_rca", "vtk", "aiohttp", "umap", "imageio", "threadpoolctl")


def missing_studio_modules() -> list[str]:
    import importlib.util

    return [m for m in STUDIO_MODULES if importlib.util.find_spec(m) is None]


def access(args: argparse.Namespace) -> tuple[str | None, bool]:
    """-> (token, no_auth). On a non-loopback --host the studio is reachable from the network: it then needs a token
    (given or random, printed in its URL) unless --no-auth says otherwise; either way a warning is printed."""
    import secrets

    from explorer.serving.launcher import LOOPBACK

    if args.token is not None and (len(args.token) < 8 or not args.token.isascii() or not args.token.isprintable()):
        raise ValueError("--token must be at least 8 printable ASCII characters")
    if args.host in LOOPBACK:
        return args.token, False
    if args.no_auth:
        print(f"imm explore: warning: --host {args.host} --no-auth: anyone who can reach this port can use the studio",
              file=sys.stderr)
        return None, True
    print(f"imm explore: warning: --host {args.host} exposes the studio to the network; it answers only URLs with its "
          "token (printed below)", file=sys.stderr)
    return args.token or secrets.token_urlsafe(24), False


def run_explore(args: argparse.Namespace) -> int:
    missing = missing_studio_modules()
    if missing:
        _error(f"the studio needs its extra: pip install 'imm-studio[studio]' (missing: {', '.join(missing)})")
        return 2
    from explorer.serving.launcher import LaunchConfig, LaunchError, launch
    from imm_model.paths import SAMPLE_DATA, SAMPLE_MODELS

    data = args.data or SAMPLE_DATA
    models = args.model or [(name, path) for name, path in SAMPLE_MODELS.items() if path.is_file()]
    judge = None if args.judge in (None, "none") else Path(args.judge)
    names = [name for name, _ in models]
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        _error(f"--model {twice}: given twice; give each model a name of its own")
        return 2
    for what, path in ((("data file", data),) + tuple((f"--model {name}: checkpoint", path) for name, path in models)
                       + ((("judge", judge),) if judge else ())):
        if not Path(path).is_file():
            _error(f"{what} not found: {path}")
            return 2
    if args.max_clients < 1:
        _error(f"--max-clients must be at least 1 (one browser tab), not {args.max_clients}")
        return 2
    if args.port is None:
        args.port = 0 if args.desktop else 8080
    if not 0 <= args.port <= 65535:
        _error(f"--port must be 0..65535, not {args.port}")
        return 2
    base_url = args.base_url if args.base_url is None or args.base_url.endswith("/") else args.base_url + "/"
    if base_url is not None and not base_url.startswith(("http://", "https://")):
        _error(f"--base-url must start with http:// or https://, not {args.base_url!r}")
        return 2
    try:
        token, no_auth = access(args)
    except ValueError as err:
        _error(f"{err}")
        return 2
    config = LaunchConfig(
        token=token, no_auth=no_auth, base_url=base_url,
        data=Path(data).resolve(), models=tuple((name, Path(path).resolve()) for name, path in models),
        host=args.host, port=args.port,
        cache_dir=args.cache_dir.resolve() if args.cache_dir else None, export_dir=args.export_dir.resolve(),
        max_clients=args.max_clients, open_browser=not args.no_browser, sequence=args.sequence, render=args.render,
        judge=str(judge.resolve()) if judge else args.judge,
    )  # fmt: skip
    window = None
    if args.desktop:  # explorer/desktop.py: the launcher opens the studio window instead of a browser
        from explorer.desktop import CLOSED, DesktopError, Window, check

        try:
            check()
        except DesktopError as err:
            _error(f"{err}")
            return 2
        window = Window()
        config.open_browser, config.open_url = True, window.open
    try:
        rc = launch(config)
    except LaunchError as err:
        _error(f"{err}")
        return 2
    finally:
        closed = window.close() if window else None
    if window is not None and closed not in (None, *CLOSED):
        return 2  # the window failed to open, and said why
    return rc


def _error(message: str) -> None:
    """One line on stderr, control characters escaped (a path may hold a newline or an escape sequence)."""
    from imm_model.errors import printable

    print(f"imm explore: error: {printable(message)}", file=sys.stderr)
