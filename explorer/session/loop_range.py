"""The loop range of a take: the frames [in, out] that playback keeps to while it loops, as the page's state holds it
([] for the whole take, else [in, out], frame indices from 0)."""

from __future__ import annotations

import math


def loop_bounds(loop_range, n: int) -> tuple[int, int]:
    """The page's loop range -> (first, last) frame that playback keeps to, within 0..n-1; the whole take for [] or a
    value that is not two frames (the page is not trusted: a crafted range must not stall or break playback)."""
    try:
        first, last = (int(v) for v in loop_range)
    except (TypeError, ValueError, OverflowError):
        return 0, n - 1
    first, last = min(max(first, 0), n - 1), min(max(last, 0), n - 1)
    return (first, last) if first <= last else (0, n - 1)


def with_end(loop_range, end: str, frame: int, n: int) -> list[int]:
    """The range with its `end` ("in" or "out") at `frame`; the other end stays where it keeps the range in order,
    else goes to the take's first or last frame (an in set past the out runs to the end of the take)."""
    first, last = loop_bounds(loop_range, n)
    frame = min(max(int(frame), 0), n - 1)
    if end == "in":
        return [frame, last if last >= frame else n - 1]
    return [first if first <= frame else 0, frame]


def wrap(pos: float, first: int, last: int) -> float:
    """A playback position past `last` brought back into [first, last] as a loop plays on (the frames beyond the end
    continue from the start of the range, none skipped)."""
    return first + math.fmod(pos - first, last + 1 - first) if pos >= first else float(first)
