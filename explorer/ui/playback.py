"""Real-time playback of the studio's three figures."""

from __future__ import annotations

import asyncio
import math
import os
from typing import TYPE_CHECKING, Any, Protocol

from explorer.session.session import FPS
from explorer.ui.layout import SPEEDS

if TYPE_CHECKING:
    from explorer.session.session import Session

MIN_YIELD_S = 0.005  # even when late, give the image delivery and incoming messages a turn
# Pictures per second at most. On a 2-core machine the browser and the server share the cores: asked for 30/s (2x),
# the page showed 6-8 of them a second, asked for 15/s it showed 12-13 (docs/experiments/studio-performance.md).
MAX_PICTURES_PER_S = 30 if (os.cpu_count() or 1) >= 4 else 15


def playback_speed(value) -> float:
    """The page's speed value, clamped to the offered range (a crafted 1e-300 or -2 must not freeze or reverse playback)."""
    try:
        speed = float(value)
    except (TypeError, ValueError):
        return 1.0
    return min(max(speed, SPEEDS[0]), SPEEDS[-1]) if math.isfinite(speed) else 1.0


class Player(Protocol):
    """What playback reads and moves: the page's frame, playing, speed and loop, and the session's frame count."""

    state: Any
    session: Session


async def play(studio: Player) -> None:
    """Play in real time: the position advances with the wall clock (frames are skipped, not
    slowed down, when a picture takes longer than a frame), and the loop sleeps until the next
    frame is due (a loop that never yields starves the image delivery)."""
    loop = asyncio.get_running_loop()
    pos, last = float(studio.state.frame or 0), loop.time()
    shown = int(pos)
    while studio.state.playing:
        rate = FPS * playback_speed(studio.state.speed)
        if int(studio.state.frame or 0) != shown:  # the user scrubbed while playing
            pos = shown = int(studio.state.frame or 0)
        now = loop.time()
        pos, last = pos + (now - last) * rate, now
        await asyncio.sleep(max(MIN_YIELD_S, (math.floor(pos) + 1 - pos) / rate, 1 / MAX_PICTURES_PER_S))
        now = loop.time()
        pos, last = pos + (now - last) * rate, now
        if not studio.state.playing:
            break
        n = studio.session.num_frames
        with studio.state:
            if pos >= n:
                if studio.state.loop:
                    pos %= n
                else:
                    pos = n - 1
                    studio.state.playing = False
            shown = int(pos)
            studio.state.frame = shown
