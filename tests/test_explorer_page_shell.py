"""The page's shell (explorer/serving/page_shell.py): trame's index.html plus the websocket and latent map scripts."""

from __future__ import annotations

from explorer.serving import page_shell


def test_the_shell_runs_the_websocket_script_before_trames_scripts():
    trame_index = f"<head><title>t</title>{page_shell.ANCHOR}<script src='x.js'></script></head>"
    index = page_shell.shell_index(trame_index)
    assert index.index("BytesWebSocket") < index.index(page_shell.ANCHOR)
    assert index.index("window.immLatent") < index.index(page_shell.ANCHOR)  # the latent map's figure code
    assert page_shell.shell_index("<head>another client</head>") == "<head>another client</head>"


def test_the_shell_is_built_once_and_keeps_trames_files(tmp_path):
    first = page_shell.page_shell(tmp_path)
    assert (first / "vue.global.js").is_file() and "BytesWebSocket" in (first / "index.html").read_text()
    stamp = (first / "index.html").stat().st_mtime_ns
    assert page_shell.page_shell(tmp_path) == first and (first / "index.html").stat().st_mtime_ns == stamp
    assert [p.name for p in tmp_path.iterdir()] == [first.name]  # no half-built copy left behind


def test_the_shells_index_names_trames_files_under_the_launchers_static_key(tmp_path):
    """Each file of trame's client that index.html loads comes from ../../static/<the shell's key>/ (one URL for every
    tab); the module folders the page loads from are linked in the shell, and another set of them is another key."""
    module = tmp_path / "module"  # a stand-in for a trame module's served folder (synthetic)
    module.mkdir()
    (module / "lib.js").write_text("// a module's script")
    shell = page_shell.page_shell(tmp_path / "cache", {"__trame_lib_1.0": str(module)})
    key = page_shell.shell_key(shell)
    index = (shell / "index.html").read_text()
    assert f'src="../../static/{key}/vue.global.js"' in index and index.index("BytesWebSocket") < index.index("vue.global.js")
    named = [m[2] for m in page_shell.FILE_URL.finditer(index) if m[2] != "."]  # not <base href=".">
    assert named and all(n.startswith(f"../../static/{key}/") and (shell / n.split("/", 4)[4]).is_file() for n in named), named
    assert (shell / "__trame_lib_1.0" / "lib.js").read_text() == "// a module's script"
    assert page_shell.page_shell(tmp_path / "cache", {"__trame_lib_1.1": str(module)}) != shell


def test_the_page_loads_plotly_js_by_its_version_from_the_launchers_static_path():
    """static/latent_map.js names plotly.min.js above the tab's /s/<id>/ (one URL for every tab, so the browser's
    cache serves the next one); the page names the vendored bundle, whose name carries the version its first lines
    state (the browser keeps it a year under that name)."""
    import re

    head = page_shell.PLOTLY_JS.read_bytes()[:200]
    version = re.search(rb"plotly\.js \(basic - minified\) v(\S+)", head).group(1).decode()
    assert page_shell.PLOTLY_JS.name == f"plotly-basic-{version}.min.js"
    assert f"'../../{page_shell.PLOTLY_SRC}'" in page_shell.LATENT_SCRIPT.read_text()
    index = page_shell.shell_index(f"<head>{page_shell.ANCHOR}</head>")
    assert f"'../../static/plotly-basic-{version}.min.js'" in index and page_shell.PLOTLY_SRC not in index


def test_the_latent_map_draws_only_traces_plotlys_basic_bundle_has():
    """The vendored bundle registers scatter, bar and pie only: a trace of another type (scattergl, say) would draw
    nothing and log an error in the page."""
    import re

    registered = set(re.findall(r'moduleType:"trace",name:"(\w+)"', page_shell.PLOTLY_JS.read_text()))
    used = set(re.findall(r"\btype: '(\w+)'", page_shell.LATENT_SCRIPT.read_text()))
    assert registered == {"scatter", "bar", "pie"} and used and used <= registered, (registered, used)
