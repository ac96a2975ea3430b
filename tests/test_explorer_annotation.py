"""The strip on exported pictures (explorer/rendering/annotation.py), drawn on synthetic images: a plain background
and random noise, no scene."""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from explorer.rendering.annotation import _font, _label_line, annotate, font_size
from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED
from tests.studio_probe import color_mask

LEGEND = [("Leader (A)", LEADER), ("Ground truth (B)", GROUND_TRUTH), ("Synthesized (B)", SYNTHESIZED)]
MIX = "kicking +1.00, hugging +0.50 · scale 1.00"
ABOUT = "the diffusion model, seed 7 · s01s02/03/001"


def _plain(h=500, w=1050):
    return np.full((h, w, 3), (244, 245, 247), np.uint8)  # the scene's background colour


def _dark(img):
    return img.max(-1) < 120  # the label's text (the background and the strip are light)


def test_the_strip_holds_the_legend_label_and_frame_and_nothing_else_changes():
    plain = _plain()
    noise = np.random.default_rng(0).integers(0, 256, plain.shape, dtype=np.uint8)
    for image in (plain, noise):
        keep = image.copy()
        out = annotate(image, LEGEND, MIX, ABOUT, "frame 12 / 46")
        assert np.array_equal(image, keep)  # a copy: the on-screen picture is not drawn on
        rows = np.flatnonzero((out != image).any(axis=(1, 2)))
        assert rows[0] == 0 and len(rows) == rows[-1] + 1  # one band along the top
        assert 30 < len(rows) < 0.15 * image.shape[0]
        assert np.array_equal(out[len(rows):], image[len(rows):])
    strip = annotate(plain, LEGEND, MIX, ABOUT, "frame 12 / 46")[: len(rows)]
    empty = annotate(plain, [], "", "", "")[: len(rows) // 2]  # the translucent band alone
    assert len(np.unique(empty.reshape(-1, 3), axis=0)) == 1
    first, second = strip[: len(rows) // 2], strip[len(rows) // 2:]
    for color in (LEADER, GROUND_TRUTH, SYNTHESIZED):  # the legend's dots and titles in the figures' colours, in order
        assert color_mask(first, color).sum() > 40, color
    centres = [np.flatnonzero(color_mask(first, c).any(0)).mean() for c in (LEADER, GROUND_TRUTH, SYNTHESIZED)]
    assert np.all(np.diff(centres) > 0) and centres[-1] < plain.shape[1] / 2
    frame_cols = np.flatnonzero(_dark(first).any(0))
    assert frame_cols.min() > 0.8 * plain.shape[1]  # the frame number at the first line's right
    label_cols = np.flatnonzero(_dark(second).any(0))
    assert label_cols.min() < 20 and 0.5 * plain.shape[1] < label_cols.max() < plain.shape[1] - 5
    other = annotate(plain, LEGEND, MIX, ABOUT, "frame 13 / 46")[: len(rows)]
    differ = np.flatnonzero((other != strip).any(axis=(0, 2)))
    assert len(differ) and differ.min() > 0.8 * plain.shape[1]  # only the number changed


def test_without_a_legend_one_line_holds_the_label_and_the_frame():
    plain = _plain()
    two = annotate(plain, LEGEND, MIX, ABOUT, "frame 3 / 46")
    one = annotate(plain, [], MIX, ABOUT, "frame 3 / 46")  # side by side: the captions name the figures
    rows = [np.flatnonzero((out != plain).any(axis=(1, 2))) for out in (one, two)]
    assert len(rows[0]) < 0.7 * len(rows[1])
    text = np.flatnonzero(_dark(one).any(0))
    assert text.min() < 20 and text.max() > 0.9 * plain.shape[1]  # the label from the left, the frame at the right
    assert not any(color_mask(one, c).any() for c in (LEADER, GROUND_TRUTH, SYNTHESIZED))


def test_a_long_mix_is_cut_and_the_model_and_sequence_stay():
    h, w = 300, 600  # the smallest usual view
    mix = ", ".join(f"class {i} +0.{i}0" for i in range(1, 30)) + " · scale 1.00"
    font = _font(font_size(h, w))
    draw = ImageDraw.Draw(Image.new("RGB", (w, 40)))
    line = _label_line(draw, font, mix, ABOUT, w - 20)
    assert line.endswith(" · " + ABOUT) and "…" in line and draw.textlength(line, font=font) <= w - 20
    assert line.startswith("class 1 +0.10, class 2")
    out = annotate(_plain(h, w), LEGEND, mix, ABOUT, "frame 1 / 46")
    rows = np.flatnonzero((out != _plain(h, w)).any(axis=(1, 2)))
    cols = np.flatnonzero(_dark(out[rows[-1] // 2: rows[-1] + 1]).any(0))
    assert cols.min() > 0 and cols.max() < w - 4  # inside the picture, with a margin
    assert font_size(h, w) >= 11 and font_size(500, 1050) > font_size(h, w)
    long_about = "the diffusion model, seed 7 · " + "x" * 300  # an upload's long file name: cut too
    line = _label_line(draw, font, "kicking +1.00", long_about, w - 20)
    assert line.startswith("the diffusion model") and line.endswith("…") and draw.textlength(line, font=font) <= w - 20


def test_the_mix_reads_as_the_sliders_write_it():
    from explorer.ui.exports import mix_text
    from imm_model.data.labels import Label

    names = ("kicking", "pushing", "shaking_hands", "hugging")
    assert mix_text(Label.of([1, 0, 0, 0.5], names)) == "kicking +1.00, hugging +0.50 · scale 1.00"
    assert mix_text(Label.of([0, -0.25, 0, 0], names, 1.5)) == "pushing -0.25 · scale 1.50"
    assert mix_text(Label.of([0, 0, 0, 0], names)).startswith("neutral")
