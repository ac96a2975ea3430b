"""The per-frame distance chart, drawn as HTML + SVG markup that the page shows with `v-html`.

Written by hand rather than with Plotly: it needs lines, shaded bands and a click that seeks, which a few lines of
markup do, and it is on screen from the page's first picture, before plotly.js has loaded (the latent map,
which needs zoom, pan and selection, is a Plotly figure loaded after that picture: explorer/ui/latent_panel.py). The frame
cursor is not in the markup: the layout binds it to `frame`, so playback does not resend the chart.

Coordinates inside the plot box (DISTANCE_BOX, CSS insets) are percentages (HTML) or a 0-1000 SVG viewBox stretched
to the box, with strokes that do not scale.
"""

from __future__ import annotations

import math
from html import escape

import numpy as np

from explorer.rendering.palette import GROUND_TRUTH, LEADER, PINNED, SYNTHESIZED, WARNING
from imm_model.evaluation.plausibility import PENETRATION_M

DISTANCE_BOX = "left: 52px; right: 12px; top: 24px; bottom: 34px"  # plot area of the distance chart

CHART_CSS = """
.imm-chart { position: absolute; inset: 0; font: 11px Roboto, sans-serif; color: #444; }
.imm-plot { position: absolute; }
.imm-plot > svg { position: absolute; inset: 0; width: 100%; height: 100%; overflow: visible; }
.imm-tick-y { position: absolute; right: calc(100% + 5px); transform: translateY(-50%); white-space: nowrap; }
.imm-tick-x { position: absolute; top: calc(100% + 3px); transform: translateX(-50%); }
.imm-axis-x { position: absolute; bottom: 0; left: 52px; right: 12px; text-align: center; }
.imm-axis-y { position: absolute; left: 6px; top: 6px; font-size: 10px; }
.imm-legend { position: absolute; display: flex; gap: 10px; font-size: 10px; }
.imm-swatch { display: inline-block; width: 14px; height: 0; border-top: 2px solid; vertical-align: middle; margin-right: 4px; }
.imm-cursor { position: absolute; top: 0; bottom: 0; border-left: 1.5px dotted #333; pointer-events: none; }
"""


def penetration_ranges(closest: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive frames whose closest limbs are within the interpenetration threshold: [(first, last)]."""
    bad = np.flatnonzero(np.asarray(closest) < PENETRATION_M)
    if not len(bad):
        return []
    breaks = np.flatnonzero(np.diff(bad) > 1)
    return [(int(bad[a]), int(bad[b])) for a, b in zip(np.r_[0, breaks + 1], np.r_[breaks, len(bad) - 1], strict=True)]


def contact_text(closest: np.ndarray) -> str:
    n = sum(b - a + 1 for a, b in penetration_ranges(closest))
    if n == 0:
        return f"no interpenetration (closest limbs {np.min(closest):.2f} m apart)" if len(closest) else ""
    return f"bodies interpenetrate in {n} of {len(closest)} frames (limbs < {PENETRATION_M * 100:.0f} cm apart: orange)"


def nice_ticks(top: float, count: int = 4) -> list[float]:
    """0 and multiples of a 1/2/2.5/5 x 10^k step up to `top`, about `count` of them."""
    if top <= 0:
        return [0.0]
    raw = top / count
    magnitude = 10 ** math.floor(math.log10(raw))
    step = next(m * magnitude for m in (1, 2, 2.5, 5, 10) if m * magnitude >= raw * 0.999)
    return [round(i * step, 10) for i in range(int(top / step + 1e-9) + 1)]


def _polyline(values: np.ndarray, x_of, top: float, color: str, series: str, dash: str = "") -> str:
    points = " ".join(f"{x_of(i):.1f},{1000 - 1000 * v / top:.1f}" for i, v in enumerate(values))
    dashes = f' stroke-dasharray="{dash}"' if dash else ""
    return (f'<polyline data-series="{series}" points="{points}" fill="none" stroke="{color}" stroke-width="2"'
            f' vector-effect="non-scaling-stroke"{dashes}/>')


def distance_chart(distances: np.ndarray, fps: float, ab: np.ndarray | None = None,
                   closest: np.ndarray | None = None) -> str:
    """Ground truth vs synthesized per frame; with `ab` (a pinned mix), pinned vs current; with `closest`, the
    closest limb distance between leader and follower, and the interpenetrating frames shaded."""
    series = [(v, color, key, name, dash) for v, color, key, name, dash in (
        (distances, SYNTHESIZED, "truth", "ground truth ↔ current", ""),
        (ab, PINNED, "pinned", "pinned ↔ current", "6 4"),
        (closest, WARNING, "closest", "closest limbs, leader ↔ follower", "2 3"),
    ) if v is not None and len(v)]  # fmt: skip
    return line_chart(series, fps, "metres", penetration_ranges(closest if closest is not None else []))


# a picked joint quantity's lines (explorer/session/joint_plot.py series): colour, name and dash by whose it is
JOINT_LINES = {
    "follower": (SYNTHESIZED, "synthesized follower", ""),
    "truth": (GROUND_TRUTH, "ground truth", "6 4"),
    "leader": (LEADER, "leader", ""),
}


def joint_chart(series: dict[str, np.ndarray], fps: float, unit: str) -> str:
    """A picked quantity of joints per frame: the synthesized follower's line, and the ground truth's dashed."""
    return line_chart([(v, JOINT_LINES[k][0], k, *JOINT_LINES[k][1:]) for k, v in series.items()], fps, unit)


def line_chart(series: list, fps: float, unit: str, shaded: list[tuple[int, int]] = ()) -> str:
    """Lines per frame, each (values, color, key, name, dash), on one y axis in `unit` from 0, and the `shaded`
    runs of frames [(first, last)]; a legend when there is more than one line."""
    series = [(np.asarray(v), *rest) for v, *rest in series]
    n = max([len(v) for v, *_ in series], default=1)
    top = max([float(np.max(v)) for v, *_ in series] + [1e-3]) * 1.05
    y_ticks = nice_ticks(top)
    x_ticks = [t for t in nice_ticks(n - 1, 6) if float(t).is_integer()]  # frames: whole numbers only
    width = 1000 / max(1, n - 1)  # one frame in viewBox units

    svg = [f'<rect class="penetration" x="{(a - 0.5) * width:.1f}" width="{(b - a + 1) * width:.1f}" y="0" height="1000"'
           f' fill="{WARNING}" opacity="0.18"/>' for a, b in shaded]
    svg += [f'<line x1="0" x2="1000" y1="{1000 - 1000 * t / top:.1f}" y2="{1000 - 1000 * t / top:.1f}" stroke="#e6e6e6"'
            ' vector-effect="non-scaling-stroke"/>' for t in y_ticks]
    svg += [_polyline(v, lambda i: i * width, top, color, key, dash) for v, color, key, _, dash in series]
    labels = [f'<span class="imm-tick-y" style="top: {100 - 100 * t / top:.2f}%">{t:g}</span>' for t in y_ticks]
    labels += [f'<span class="imm-tick-x" style="left: {100 * t / max(1, n - 1):.2f}%">{t:g}</span>' for t in x_ticks]
    legend = "".join(f'<span><i class="imm-swatch" style="border-color: {color}; border-top-style: {"dashed" if dash else "solid"}">'
                     f'</i>{escape(name)}</span>' for _, color, _, name, dash in series) if len(series) > 1 else ""
    return (f'<div class="imm-chart"><div class="imm-legend" style="left: 52px; top: 2px">{legend}</div>'
            f'<div class="imm-plot" style="{DISTANCE_BOX}">'
            f'<svg viewBox="0 0 1000 1000" preserveAspectRatio="none">{"".join(svg)}</svg>{"".join(labels)}</div>'
            f'<div class="imm-axis-x">frame ({fps:g} fps)</div><div class="imm-axis-y">{escape(unit)}</div></div>')


def contact_frames(closest: np.ndarray) -> list[int]:
    """The frames where the bodies come closest, marked on the timeline: in each run of interpenetrating frames the
    closest one, or the one closest frame of a take where they never interpenetrate."""
    closest = np.asarray(closest)
    if not len(closest):
        return []
    runs = penetration_ranges(closest) or [(0, len(closest) - 1)]
    return [a + int(np.argmin(closest[a : b + 1])) for a, b in runs]
