"""What the studio's Export menu and screenshot button hand to the browser: the reaction as .npz or .bvh, the
animation as .gif or .mp4, the current 3D view as .png. Each is also saved into --export-dir. Pictures and videos
come at the view's size or at a size picked in the menu (EXPORT_SIZES), whatever the window: a slide wants 1920x1080
from a laptop's 1000 px wide view.

Pictures and video frames carry a strip naming the figures, the mix, the model, the sequence and the frame
(explorer/rendering/annotation.py), which the page shows around the view and a picture on its own would lose.

They are trame triggers, not controllers: the page awaits the returned bytes to download them. One tab may export
EXPORTS_PER_MINUTE a minute and save SAVED_BYTES into --export-dir (a script driving a tab could otherwise fill the
disk: the folder has no quota of its own).
"""

from __future__ import annotations

import re
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from trame.widgets import html
from trame.widgets import vuetify3 as v3

from explorer.rendering.palette import CHARACTER_TITLES, PINNED, WARNING, display_name
from explorer.rendering.palette import CHARACTERS as CHARACTER_COLORS
from explorer.rendering.pictures import frames, screenshot
from explorer.session.files import FPS
from explorer.session.words import one_line
from imm_model.data.labels import Label

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.panel_api import Page

CHARACTERS = ("follower", "leader")
VIDEO_FORMATS = ("gif", "mp4")
EXPORTS_PER_MINUTE = 20  # a user clicking Export is far below it
SAVED_BYTES = 500 * 1024 * 1024  # past it, a tab's exports are downloads only (a long sequence's video is ~30 MB)
EXPORT_SIZES = {"view size": None, "1280x720": (1280, 720), "1920x1080": (1920, 1080)}  # (width, height) of pictures


class Exports:
    def __init__(self, page: Page, scene: Scene, export_dir: Path, *, attach: Callable[[bytes], object]):
        """`attach(data)` makes `data` what a trigger returns for the page to download (explorer/trame_adapter.py)."""
        self.page, self.scene, self.export_dir, self.attach = page, scene, Path(export_dir), attach
        self.recent: deque[float] = deque()  # time.monotonic() of this tab's exports in the last minute
        self.saved = 0  # bytes this tab saved into export_dir
        page.state.export_size = next(iter(EXPORT_SIZES))  # the menu's choice; the page sends it with each export
        for name in ("export_npz", "export_bvh", "export_video", "export_png"):
            page.trigger(name)(page.guarded(self._rate_limited(getattr(self, name))))

    def _rate_limited(self, export: Callable) -> Callable:
        """`export`, refused in one line (before any work: a video takes seconds) past EXPORTS_PER_MINUTE."""

        def call(*args, **kwargs):
            now = time.monotonic()
            while self.recent and now - self.recent[0] >= 60:
                self.recent.popleft()
            if len(self.recent) >= EXPORTS_PER_MINUTE:
                wait = 60 - (now - self.recent[0])
                raise ValueError(f"export refused: at most {EXPORTS_PER_MINUTE} exports a minute from one tab (try again in {wait:.0f} s)")
            self.recent.append(now)
            return export(*args, **kwargs)

        call.__name__ = export.__name__
        return call

    @property
    def session(self):
        return self.page.session

    def file_stem(self) -> str:
        """What the browser names a download (and the server's copy), before its extension: the sequence and the mix."""
        return safe_file_name(self.session.files.name("x")).removesuffix(".x")

    def _send(self, name: str, data: bytes):
        self._save_copy(name, data)
        return self.attach(data)

    def export_npz(self):
        return self._send(self.session.files.name("npz"), self.session.files.npz())

    def export_bvh(self, character: str = "follower"):
        if character not in CHARACTERS:
            raise ValueError(f"unknown character {character!r}: {' or '.join(CHARACTERS)}")
        data = self.session.files.bvh(character)
        return self._send(self.session.files.name("bvh").replace(".bvh", f".{character}.bvh"), data)

    def export_png(self, size: str = "view size"):
        """The 3D view as the user sees it now, at `size` (an EXPORT_SIZES key; the server renders it, no browser canvas
        needed)."""
        import imageio.v3 as iio

        image = self._annotator(every_frame=False)(screenshot(self.scene, picture_size(size)), self.scene.frame)
        return self._send(self.session.files.name("png"), iio.imwrite("<bytes>", image, extension=".png"))

    def export_video(self, fmt: str = "gif", size: str = "view size"):
        import imageio.v3 as iio

        if fmt not in VIDEO_FORMATS:
            raise ValueError(f"unknown video format {fmt!r}: {' or '.join(VIDEO_FORMATS)}")

        annotate = self._annotator(every_frame=True)
        images = [annotate(im, f) for f, im in enumerate(frames(self.scene, size=picture_size(size)))]
        self.page.ctrl.view_update()
        if fmt == "mp4":
            images = [im[: im.shape[0] // 2 * 2, : im.shape[1] // 2 * 2] for im in images]  # even sizes for yuv420p
            # macro_block_size 1: the view's own size (imageio would otherwise stretch it to a multiple of 16)
            data = iio.imwrite("<bytes>", np.stack(images), extension=".mp4", fps=FPS, codec="libx264", macro_block_size=1)
        else:
            data = iio.imwrite("<bytes>", np.stack(images), extension=".gif", duration=gif_delays(len(images)), loop=0)
        return self._send(self.session.files.name(fmt), data)

    def _annotator(self, every_frame: bool) -> Callable[[np.ndarray, int], np.ndarray]:
        """The strip for this view's export: the legend of the figures shown (side by side their captions name them,
        so there only the pinned one's), the mix, the model and the sequence; -> draws it on the picture of frame f."""
        from explorer.rendering.annotation import annotate

        ses, scene = self.session, self.scene
        titles = {**CHARACTER_TITLES, "pinned": f"pinned: {ses.pinned.text()}", "contact": "limbs in contact"}
        colors = {**CHARACTER_COLORS, "pinned": PINNED, "contact": WARNING}
        shown = scene.shown(every_frame)
        if scene.layout == "side_by_side":
            shown = [k for k in shown if k == "pinned"]
        legend = [(titles[k], colors[k]) for k in shown]
        mix, about = mix_text(ses.label), about_text(ses)
        n = len(scene.sequences["leader"])
        return lambda image, f: annotate(image, legend, mix, about, f"frame {f + 1} / {n}")

    def _save_copy(self, name: str, data: bytes) -> None:
        """Saved under a name made of safe characters only (it comes partly from an upload's file name), beside
        and never over earlier exports (NAME-2.EXT, ...)."""
        from imm_model.errors import IMMError
        from imm_model.outputs import write_new

        state = self.page.state
        if self.saved + len(data) > SAVED_BYTES:
            state.notice = f"download only (this tab has saved {self.saved / 2**20:.0f} MB into the export folder, the most one tab may)"
            return
        try:
            path = write_new(self.export_dir / safe_file_name(name), data)
            self.saved += len(data)
            state.notice = f"saved {path}"
        except (OSError, IMMError) as err:
            state.notice = f"download only (could not save a copy: {one_line(err)})"


def picture_size(name: str) -> tuple[int, int] | None:
    """An EXPORT_SIZES key -> (width, height), None for the view's size; ValueError, one line, for another name."""
    if name not in EXPORT_SIZES:
        raise ValueError(f"unknown export size {str(name)[:20]!r}: {', '.join(EXPORT_SIZES)}")
    return EXPORT_SIZES[name]


def mix_text(label: Label) -> str:
    """The mix as the page's sliders write it: 'kicking +1.00, hugging +0.50 · scale 1.00'; a mix per body part by its
    part keys: 'upper:shaking_hands=1,lower:pushing=-1 · scale 1.00'."""
    if label.parts_differ:
        return f"{label.text()} · scale {label.scale:.2f}"
    parts = [f"{display_name(n)} {w:+.2f}" for n, w in zip(label.class_names, label.parts[0], strict=True) if abs(w) > 1e-6]
    return f"{', '.join(parts) or 'neutral (all classes 0)'} · scale {label.scale:.2f}"


def about_text(session) -> str:
    """Which model drew the follower (and its seed, for a seeded one), and of which leader: 'the diffusion model,
    seed 7 · s01s02/03/001' (an uploaded leader: its file's name)."""
    model = session.model_title()
    if session.seeded:
        model += f", seed {session.seed}"
    if not session.cleaned_up:
        model += ", no clean-up"
    leader = Path(session.upload.name).name if session.upload else session.data.sequence_ids[session.index]
    return f"{model} · {leader}"


def safe_file_name(name: str) -> str:
    """NAME.EXT with letters, digits and . _ + - only (anything else becomes _), no leading dot, bounded length."""
    stem, _, ext = name.rpartition(".")
    stem = re.sub(r"[^A-Za-z0-9._+-]", "_", stem).lstrip(".")[:100] or "export"
    return f"{stem}.{re.sub(r'[^A-Za-z0-9]', '', ext)[:5] or 'bin'}"


def gif_delays(frames: int) -> list[int]:
    """Per-frame delays (ms) that play a GIF at the data's rate: a GIF counts delays in hundredths of a second, so a
    constant 1000 / FPS (66.7 ms) was cut to 60 ms (16.7 frames a second for 15 fps data); 70, 70, 60 keeps 15 a second
    on average."""
    step = 1000.0 / FPS
    return [int(round(step * (k + 1), -1) - round(step * k, -1)) for k in range(frames)]


# ---- the page's controls ----------------------------------------------------------------------
def download(ext: str, trigger: str, mime: str) -> str:
    """A click that downloads what `trigger` (with its arguments, a JavaScript list) returns, named as the server's copy
    (the sequence and the mix: Exports.file_stem)."""
    return f"utils.download(export_stem + '{ext}', trigger({trigger}), '{mime}')"


def export_menu() -> None:
    """The Export menu: the pictures' size, then the files."""
    with v3.VMenu():
        with v3.Template(v_slot_activator="{ props }"):
            v3.VBtn("Export", v_bind="props", size="small", variant="tonal", prepend_icon="mdi-download", classes="ml-2",
                    id="export-menu")
        with v3.VList(density="compact"):
            # a click on a size keeps the menu open (the export to make follows); one on a file closes it
            with html.Div(classes="d-flex align-center px-4 pb-1", style="gap: 8px", raw_attrs=["@click.stop"],
                          title="pictures and animations at this size, whatever the window"):
                html.Div("size", classes="text-body-2")
                with v3.VBtnToggle(v_model=("export_size",), density="compact", mandatory=True, variant="outlined",
                                   divided=True, id="export-size"):
                    for name in EXPORT_SIZES:
                        v3.VBtn(name, value=name, size="x-small")
            v3.VListItem(title="Interaction: leader, follower, label (.npz)", id="export-npz",
                         click=download(".npz", "'export_npz'", "application/octet-stream"))
            for character in CHARACTERS:
                v3.VListItem(title=f"{'Synthesized follower' if character == 'follower' else 'Leader'} (.bvh)",
                             classes=f"export-bvh-{character}",
                             click=download(f".{character}.bvh", f"'export_bvh', ['{character}']", "text/plain"))
            v3.VListItem(title="Picture (.png)", id="export-png", click=download(".png", "'export_png', [export_size]", "image/png"))
            v3.VListItem(title="Animation (.gif)", id="export-gif",
                         click=download(".gif", "'export_video', ['gif', export_size]", "image/gif"))
            v3.VListItem(title="Animation (.mp4)", id="export-mp4",
                         click=download(".mp4", "'export_video', ['mp4', export_size]", "video/mp4"))


def screenshot_button() -> None:
    v3.VBtn(icon="mdi-camera", size="small", variant="text", title="Save the 3D view as a picture (.png), at the size the menu picks",
            id="screenshot", click=download(".png", "'export_png', [export_size]", "image/png"))
