"""Real-time playback of the studio's three figures."""

from __future__ import annotations

import asyncio
import contextlib
import math
import os
from typing import TYPE_CHECKING, Any, Protocol

from explorer.session.files import FPS
from explorer.session.loop_range import loop_bounds, with_end, wrap
from explorer.ui.layout import SPEEDS

if TYPE_CHECKING:
    from explorer.session.session import Session
    from explorer.ui.panel_api import Page

MIN_YIELD_S = 0.005  # even when late, give the image delivery and incoming messages a turn
# Each frame waits until its picture is encoded (explorer/rendering/view_stream.py: the view holds a picture back
# until the page has shown the one before), so the next frame renders while the page shows this one, and playback
# shows what the page can, skipping frames beyond that. A fixed rate ran ahead of a busy page, whose <img> then
# cancelled most pictures: asked for 30/s on 2 cores, it showed 6-8 (docs/experiments/studio-performance.md).
ENCODED_TIMEOUT_S = 0.5  # plays on at this pace at least if a picture never comes
# A view that cannot tell (vtk.js drawing in the page, --render local) keeps the earlier fixed cap: frames a second.
UNPACED_PER_S = 30 if (os.cpu_count() or 1) >= 4 else 15
# Playback's pictures at this fraction of the view's width and height, stretched by the page (the still picture
# when it stops is full size): the sharpest that kept ~30 pictures a second at 2x (benchmarks/explorer_latency.py
# --playback-only measures each size back to back).
PLAYBACK_SCALE = 0.6
MIN_PLAYBACK_SCALE = 0.25


def playback_speed(value) -> float:
    """The page's speed value, clamped to the offered range (a crafted 1e-300 or -2 must not freeze or reverse playback)."""
    try:
        speed = float(value)
    except (TypeError, ValueError):
        return 1.0
    return min(max(speed, SPEEDS[0]), SPEEDS[-1]) if math.isfinite(speed) else 1.0


def playback_scale(value) -> float:
    """The page's playback_scale, clamped to MIN_PLAYBACK_SCALE..1 (a crafted 0 or 1e9 must not break the picture)."""
    try:
        scale = float(value)
    except (TypeError, ValueError):
        return PLAYBACK_SCALE
    return min(max(scale, MIN_PLAYBACK_SCALE), 1.0) if math.isfinite(scale) else PLAYBACK_SCALE


class Player(Protocol):
    """What playback reads and moves: the page's frame, playing, speed, loop and loop range, and the session's frame
    count; and
    what it waits for: the picture of the frame it set, encoded."""

    state: Any
    session: Session

    async def picture_encoded(self) -> bool: ...  # False: the view cannot tell (no wait)


def loop_range_of(studio: Player) -> tuple[int, int]:
    """The first and last frame playback keeps to: the loop range's, or the whole take's (a player with none)."""
    return loop_bounds(getattr(studio.state, "loop_range", None), studio.session.num_frames)


async def play(studio: Player) -> None:
    """Play in real time: the position advances with the wall clock (frames are skipped, not
    slowed down, when a picture takes longer than a frame), and the loop sleeps until the next
    frame is due (a loop that never yields starves the image delivery)."""
    loop = asyncio.get_running_loop()
    first, end = loop_range_of(studio)
    if not first <= int(studio.state.frame or 0) < end:  # from outside the loop range, or at its end: from its start
        with studio.state:
            studio.state.frame = first
    pos, last = float(studio.state.frame or 0), loop.time()
    shown, earliest = int(pos), last
    while studio.state.playing:
        rate = FPS * playback_speed(studio.state.speed)
        if int(studio.state.frame or 0) != shown:  # the user scrubbed while playing
            pos = shown = int(studio.state.frame or 0)
        now = loop.time()
        pos, last = pos + (now - last) * rate, now
        due = 0.0 if int(pos) != shown else (math.floor(pos) + 1 - pos) / rate  # now, if the picture took over a frame
        await asyncio.sleep(max(MIN_YIELD_S, due, earliest - now))
        now = loop.time()
        pos, last = pos + (now - last) * rate, now
        if not studio.state.playing:
            break
        # the range read at every frame: set, moved or cleared while playing, it applies at once
        first, end = loop_range_of(studio)
        with studio.state:
            if pos >= end + 1:
                if studio.state.loop:
                    pos = wrap(pos, first, end)
                else:
                    pos = end
                    studio.state.playing = False
            shown = int(pos)
            studio.state.frame = shown
        earliest = loop.time()
        with contextlib.suppress(TimeoutError):
            if not await asyncio.wait_for(studio.picture_encoded(), ENCODED_TIMEOUT_S):
                earliest += 1 / UNPACED_PER_S


class LoopRange:
    """The timeline's loop range: its in and out set at the frame shown (buttons, or the keys [ and ]: keys.py), or
    cleared back to the whole take. One per take: it stays while the mix, model or clean-up change the follower, and
    a take opened (a sequence, an upload) starts with the whole take."""

    def __init__(self, page: Page):
        self.page = page
        self._take = page.session.current  # the leader the range is of
        page.state.loop_range = []
        page.ctrl.set_loop_in = lambda: self.on_loop_end_set("in")
        page.ctrl.set_loop_out = lambda: self.on_loop_end_set("out")
        page.ctrl.clear_loop = self.on_loop_cleared
        # every take opened is drawn, and mix_count counts each drawing (app.py): the first after a new take resets
        page.state.change("mix_count")(self.on_follower_drawn)

    def on_loop_end_set(self, end: str) -> None:
        s = self.page.state
        s.loop_range = with_end(s.loop_range, end, int(s.frame or 0), self.page.session.num_frames)

    def on_loop_cleared(self) -> None:
        self.page.state.loop_range = []

    def on_follower_drawn(self, **_) -> None:
        if self.page.session.current is not self._take:
            self._take = self.page.session.current
            self.page.state.loop_range = []
