"""The strip drawn on exported pictures and video frames: which colour is which figure, what was asked for (the mix,
the model, the sequence) and the frame number. The page shows these in HTML around the view; a picture pasted into a
paper or a slide would lose them, so exports carry them on the image. The on-screen view stays plain.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

STRIP_ALPHA = 0.82  # the figures stay faintly visible under the strip
STRIP_RGB = (255, 255, 255)
TEXT_RGB = (34, 34, 34)
ELLIPSIS = "…"
SEPARATOR = " · "


def font_size(height: int, width: int) -> int:
    """Pixels of text for an image: a thirtieth of its height (17 px at the view's usual 500), narrower images a
    little smaller so the lines still hold their text; never below 11 px, the smallest that stays legible."""
    return max(11, round(min(height / 30, width / 50)))


def annotate(image: np.ndarray, legend: Sequence[tuple[str, str]], mix: str, about: str, frame: str) -> np.ndarray:
    """(H, W, 3) uint8 -> a copy with a translucent strip along the top: `legend` ((title, "#rrggbb") per figure shown,
    each a dot and its title in its colour) on the first line with `frame` ("frame 12 / 46") at its right; `mix` and
    `about` (the model and the sequence) on the second, joined by " · ". Text too long for the width is cut with "…":
    the mix first, so the model and the sequence stay whole. An empty legend puts everything on one line."""
    h, w = image.shape[:2]
    size = font_size(h, w)
    font = _font(size)
    pad, line_h = round(size * 0.45), round(size * 1.3)
    lines = 2 if legend else 1
    strip_h = min(h, 2 * pad + lines * line_h)

    out = np.array(image[..., :3], dtype=np.uint8, copy=True)
    band = out[:strip_h].astype(np.float32)
    out[:strip_h] = np.round(band * (1 - STRIP_ALPHA) + np.float32(STRIP_RGB) * STRIP_ALPHA).astype(np.uint8)
    strip = Image.fromarray(out[:strip_h])
    draw = ImageDraw.Draw(strip)

    frame = _drawable(frame, font)
    frame_w = draw.textlength(frame, font=font)
    gap = size  # between the line's left part and the frame number
    cy = pad + line_h / 2  # the first line's middle
    draw.text((w - pad - frame_w, cy), frame, fill=TEXT_RGB, font=font, anchor="lm")
    if legend:
        _draw_legend(draw, font, size, legend, pad, cy, w - pad - frame_w - gap)
        cy, right = cy + line_h, w - pad
    else:
        right = w - pad - frame_w - gap
    text = _label_line(draw, font, _drawable(mix, font), _drawable(about, font), right - pad)
    draw.text((pad, cy), text, fill=TEXT_RGB, font=font, anchor="lm")
    out[:strip_h] = np.asarray(strip)
    return out


def _draw_legend(draw: ImageDraw.ImageDraw, font, size: int, legend, x: float, cy: float, right: float) -> None:
    """Dot and title per entry, left to right, centred on the height `cy`; an entry that does not fit is cut, and the
    ones after it left out."""
    dot = round(size * 0.62)
    for title, color in legend:
        title = _drawable(title, font)
        room = right - x - dot - size * 0.35
        if room < draw.textlength("M" + ELLIPSIS, font=font):
            return
        draw.ellipse((x, cy - dot / 2, x + dot, cy + dot / 2), fill=color)
        x += dot + size * 0.35
        shown = _fit(draw, font, title, room)
        draw.text((x, cy), shown, fill=color, font=font, anchor="lm")
        x += draw.textlength(shown, font=font) + size * 0.9
        if shown != title:
            return


def _label_line(draw: ImageDraw.ImageDraw, font, mix: str, about: str, width: float) -> str:
    """mix · about in `width` pixels: the mix cut first; only when `about` alone is too wide is it cut too."""
    if not about:
        return _fit(draw, font, mix, width)
    if not mix:
        return _fit(draw, font, about, width)
    tail = SEPARATOR + about
    room = width - draw.textlength(tail, font=font)
    if room >= draw.textlength(mix[:4] + ELLIPSIS, font=font) or draw.textlength(mix + tail, font=font) <= width:
        return _fit(draw, font, mix, room) + tail
    return _fit(draw, font, about, width)


def _fit(draw: ImageDraw.ImageDraw, font, text: str, width: float) -> str:
    """`text`, or its longest start that fits in `width` pixels with "…" after it ("" when not even that fits)."""
    if draw.textlength(text, font=font) <= width:
        return text
    lo, hi = 0, len(text)  # the longest start that fits, with the ellipsis: binary search on its length
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if draw.textlength(text[:mid].rstrip() + ELLIPSIS, font=font) <= width:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo].rstrip() + ELLIPSIS if lo or draw.textlength(ELLIPSIS, font=font) <= width else ""


@functools.lru_cache(maxsize=8)
def _font(size: int):
    return ImageFont.load_default(size=size)


def _drawable(text: str, font) -> str:
    """`text` with the characters the font has no glyph for (Pillow's default font covers ASCII and a few more) as
    "?", rather than as boxes; "×" becomes "x"."""
    text = text.replace("×", "x")
    return "".join(ch if ch.isspace() or _has_glyph(font, ch) else "?" for ch in text)


@functools.lru_cache(maxsize=4096)
def _has_glyph(font, ch: str) -> bool:
    return _mask_bytes(font, ch) != _mask_bytes(font, "\ue000")  # a private-use code point: the missing-glyph box


@functools.lru_cache(maxsize=64)
def _mask_bytes(font, ch: str) -> tuple[tuple[int, int], bytes]:
    mask = font.getmask(ch)
    return mask.size, bytes(mask)
