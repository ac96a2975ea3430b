"""The page's shell (explorer/page_shell.py): trame's index.html plus the websocket script and preload links."""

from __future__ import annotations

from explorer import page_shell

SCRIPTS = ["__trame_vuetify/vue3/vuetify3.js", "__trame_rca/trame-rca.umd.js"]


def test_the_shell_adds_the_websocket_script_and_preloads_before_trames_scripts():
    trame_index = f"<head><title>t</title>{page_shell.ANCHOR}<script src='x.js'></script></head>"
    index = page_shell.shell_index(trame_index, SCRIPTS)
    ours = index.index("BytesWebSocket")
    assert ours < index.index(page_shell.ANCHOR)
    assert all(index.index(f'<link rel="preload" as="script" href="{s}">') < ours for s in SCRIPTS)
    assert page_shell.shell_index("<head>another client</head>", SCRIPTS) == "<head>another client</head>"


def test_the_shell_is_built_once_and_keeps_trames_files(tmp_path):
    first = page_shell.page_shell(tmp_path, SCRIPTS)
    assert (first / "vue.global.js").is_file() and "BytesWebSocket" in (first / "index.html").read_text()
    stamp = (first / "index.html").stat().st_mtime_ns
    assert page_shell.page_shell(tmp_path, SCRIPTS) == first and (first / "index.html").stat().st_mtime_ns == stamp
    other = page_shell.page_shell(tmp_path, SCRIPTS[:1])  # other modules: another shell beside it
    assert other != first and sorted(p.name for p in tmp_path.iterdir()) == sorted([first.name, other.name])
