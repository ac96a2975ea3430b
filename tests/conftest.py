"""Shared fixtures. Tests that need ../shared/datasets are marked `shared` and skip without it; the studio's browser
tests (`browser` marker) skip without /usr/bin/chromium or the bundled checkpoint."""

from __future__ import annotations

import os

# One math thread per test process (and the processes it starts): the suite's torch and numpy work is small, and beside
# another busy process two threads on two cores spin against each other (a tiny training test took minutes, not 7 s).
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import pytest  # noqa: E402

from imm_model.paths import SAMPLE_DATA, SAMPLE_GAN, k3hi_raw_root, sbu_raw_root


@pytest.fixture(scope="session")
def sample_data():
    from imm_model.data.dataset import InteractionDataset

    return InteractionDataset.load(SAMPLE_DATA)


@pytest.fixture(scope="session")
def sbu_root():
    root = sbu_raw_root()
    if not root.is_dir():
        pytest.skip(f"raw SBU data not found at {root}")
    return root


@pytest.fixture(scope="session")
def k3hi_root():
    root = k3hi_raw_root()
    if not root.is_dir():
        pytest.skip(f"raw K3HI data not found at {root}")
    return root


# ---- the studio in a browser (test_explorer_browser.py, test_explorer_serving.py): one studio and one page per module


@pytest.fixture(scope="module")
def browser():
    if not os.path.exists("/usr/bin/chromium"):
        pytest.skip("needs /usr/bin/chromium (apt-get install -y chromium)")
    if not SAMPLE_GAN.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_GAN}")
    sync_api = pytest.importorskip("playwright.sync_api")
    from tests import studio_probe as probe

    with sync_api.sync_playwright() as p:
        b = probe.launch_chromium(p)
        yield b
        b.close()


@pytest.fixture(scope="module")
def studio(browser, tmp_path_factory):
    from tests import studio_probe as probe

    # room for the tabs a module opens at once (five) and those still closing (a closed tab's process ends ~2 s later)
    with probe.StudioProcess("--max-clients", "12", cache_dir=tmp_path_factory.mktemp("studio-cache")) as s:
        yield s


@pytest.fixture(scope="module")
def page(studio, browser):
    from tests import studio_probe as probe

    # a module's first page meets its fresh studio's start-up work (the latent map's fit in the background): on a busy
    # two-core machine its first picture has come after more than a minute
    pg = probe.open_studio(browser, studio.url, timeout_ms=180000)
    probe.watch_view_images(pg)
    yield pg
    pg.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failed browser test's report ends with what its studio wrote last (start-up, its processes' errors)."""
    outcome = yield
    report = outcome.get_result()
    studio = item.funcargs.get("studio") if hasattr(item, "funcargs") else None
    if report.failed and studio is not None:
        report.sections.append(("studio log (last 40 lines)", "\n".join(studio.lines[-40:])))


def pytest_terminal_summary(terminalreporter):
    """Each studio process a launcher found stuck and replaced (with its threads' stacks), and each page that loaded
    itself again, whether or not a test failed: a tab that recovered still names a fault worth knowing."""
    from tests.studio_probe import NOTICE, StudioProcess

    for studio in StudioProcess.noticed:
        first = next(i for i, line in enumerate(studio.lines) if line.startswith(NOTICE))
        terminalreporter.write_sep("-", f"studio notices ({studio.url})")
        terminalreporter.write_line("\n".join(studio.lines[first:first + 80]))
