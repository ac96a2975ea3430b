"""Plotly figures as plain dicts (what trame-plotly puts in state): cheap to rebuild on every change."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from explorer.palette import PINNED, SYNTHESIZED, WARNING, class_color, display_name
from imm_model.evaluation.plausibility import PENETRATION_M

FONT = {"family": "Roboto, sans-serif", "size": 11}


def _trace(y: np.ndarray, color: str, name: str, dash: str = "solid") -> dict:
    return {"type": "scatter", "mode": "lines", "x": list(range(len(y))), "y": np.round(y, 4).tolist(),
            "line": {"color": color, "width": 2, "dash": dash}, "hovertemplate": "frame %{x}: %{y:.3f} m<extra></extra>",
            "name": name}


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


def distance_figure(distances: np.ndarray, frame: int, fps: float, ab: np.ndarray | None = None,
                    closest: np.ndarray | None = None) -> dict:
    """Ground truth vs synthesized per frame; with `ab` (a pinned mix), pinned vs current; with `closest`, the
    closest limb distance between leader and follower, and the interpenetrating frames shaded."""
    n = max(len(distances), 0 if ab is None else len(ab), 0 if closest is None else len(closest))
    data = [_trace(distances, SYNTHESIZED, "ground truth ↔ current")] if len(distances) else []
    if ab is not None and len(ab):
        data.append(_trace(ab, PINNED, "pinned ↔ current", "dash"))
    if closest is not None and len(closest):
        data.append(_trace(closest, WARNING, "closest limbs, leader ↔ follower", "dot"))
    ranges = penetration_ranges(closest) if closest is not None else []
    bands = [{"type": "rect", "x0": a - 0.5, "x1": b + 0.5, "yref": "paper", "y0": 0, "y1": 1, "fillcolor": WARNING,
              "opacity": 0.18, "line": {"width": 0}, "layer": "below"} for a, b in ranges]
    return {
        "data": data,
        "layout": {
            "margin": {"l": 48, "r": 10, "t": 8, "b": 34},
            "font": FONT,
            "xaxis": {"title": {"text": f"frame ({fps:g} fps)"}, "range": [0, max(1, n - 1)], "zeroline": False},
            "yaxis": {"title": {"text": "distance (m)"}, "rangemode": "tozero"},
            "shapes": bands + [
                {
                    "type": "line",
                    "x0": frame,
                    "x1": frame,
                    "yref": "paper",
                    "y0": 0,
                    "y1": 1,
                    "line": {"color": "#333", "width": 1.5, "dash": "dot"},
                }
            ],
            "showlegend": len(data) > 1,
            "legend": {"orientation": "h", "x": 0, "y": 1.12, "font": {"size": 10}},
            "plot_bgcolor": "#ffffff",
            "paper_bgcolor": "rgba(0,0,0,0)",
            "autosize": True,
        },
    }


def latent_figure(
    coords: np.ndarray,
    actions: np.ndarray,
    held_out: np.ndarray,
    sequence_ids: Sequence[str],
    class_names: Sequence[str],
    current_index: int | None,
    mix_xy: np.ndarray | None,
    mix_text: str,
    method: str,
) -> dict:
    """One trace per class (legend = class colors); held-out sequences as open circles; the current
    sequence ringed in black; the current mix as a green star (green = synthesized, as in 3D)."""
    data = _class_traces(coords, actions, held_out, sequence_ids, class_names)
    if current_index is not None:  # None: an uploaded leader, which has no point of its own on the map
        data.append(_point_trace("this sequence (match)", coords[current_index], int(current_index),
                                 f"{sequence_ids[current_index]} with its own label<extra></extra>",
                                 {"size": 15, "symbol": "circle-open", "color": "#111", "line": {"width": 2.5, "color": "#111"}}))
    if mix_xy is not None:
        data.append(_point_trace("current mix (synth)", mix_xy, -1 if current_index is None else int(current_index),
                                 mix_text.replace("%", "%%") + "<extra>current mix</extra>",
                                 {"size": 18, "symbol": "star", "color": SYNTHESIZED, "line": {"width": 1.5, "color": "#111"}}))
    title = {"text": method.upper() if method == "umap" else "t-SNE", "x": 0, "y": 1, "xref": "paper", "yref": "paper",
             "showarrow": False, "xanchor": "left", "font": {"size": 10, "color": "#777"}}
    layout = {"margin": {"l": 8, "r": 8, "t": 8, "b": 8}, "font": FONT, "xaxis": {"visible": False}, "yaxis": {"visible": False},
              "legend": {"orientation": "v", "x": 1.0, "xanchor": "left", "y": 1, "font": {"size": 10}},
              "hovermode": "closest", "plot_bgcolor": "#ffffff", "paper_bgcolor": "rgba(0,0,0,0)", "annotations": [title],
              "uirevision": method,  # keep the user's zoom while the star moves
              "autosize": True}
    return {"data": data, "layout": layout}


def _class_traces(coords, actions, held_out, sequence_ids, class_names) -> list[dict]:
    traces = []
    for c, name in enumerate(class_names):
        idx = np.flatnonzero(actions == c)
        if not len(idx):
            continue
        traces.append({
            "type": "scatter", "mode": "markers", "name": display_name(name),
            "x": np.round(coords[idx, 0], 3).tolist(), "y": np.round(coords[idx, 1], 3).tolist(),
            "customdata": idx.tolist(),
            "text": [sequence_ids[i] + (" (held out)" if held_out[i] else "") for i in idx],
            "hovertemplate": "%{text}<extra>" + display_name(name) + "</extra>",
            "marker": {"color": class_color(c), "size": 8, "symbol": ["circle-open" if held_out[i] else "circle" for i in idx],
                       "line": {"width": 1.5, "color": class_color(c)}},
        })  # fmt: skip
    return traces


def _point_trace(name: str, xy, customdata: int, hover: str, marker: dict) -> dict:
    return {"type": "scatter", "mode": "markers", "name": name, "x": [float(xy[0])], "y": [float(xy[1])],
            "customdata": [customdata], "hovertemplate": hover, "marker": marker}
