"""The "reads as" panel: which interaction the synthesized reaction on screen reads as, per the follower-only
classifier (imm_model/reads_as.py), one bar per class, the asked-for classes marked. Updated with every slider
move, so a user sees whether a mix reads as intended; an asked-for class the classifier barely sees is named under
the bars (the mixes that fail the mix target show this way, docs/user-guide.md "Mixes that do not read").

The bundled classifier reads the whole follower. For a mix per body part the panel shows that reading and, under it, the
body-part judges' (sample_data/upper_judge and lower_judge.safetensors): each part's top classes, its asked class
marked, and a one-line note; without part judges (a custom --judge, or none) a caption says the reading is the whole
body's."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from trame.widgets import html
from trame.widgets import vuetify3 as v3

from explorer.rendering.palette import class_color, display_name
from imm_model.reads_as import MIX_SHARE

# A class asked for with less weight than this is a nudge, not an ask: its share is not judged against MIX_SHARE.
ASKED_WEIGHT = 0.5


def reads_as_rows(probabilities: np.ndarray | None, weights: Sequence[float], class_names: Sequence[str]) -> list[dict]:
    """The panel's state: one row per class with its probability and whether the label asks for (+) or avoids (-) it."""
    if probabilities is None:
        return []
    return [{"name": display_name(n), "p": round(float(p), 3), "color": class_color(i),
             "asked": "+" if w > 1e-6 else "-" if w < -1e-6 else "", "w": round(float(w), 3)}
            for i, (n, p, w) in enumerate(zip(class_names, probabilities, weights, strict=True))]


PART_NOTE = "the whole body's reading: a reading per body part needs part judges, which come only with the bundled judge"


PART_NAMES = {"upper": "upper body", "lower": "lower body"}


def part_rows(readings: dict[str, np.ndarray], part_weights: np.ndarray, class_names: Sequence[str]) -> list[dict]:
    """The parts' readings, compact: per part its top two classes and its asked class (the largest |weight| of the
    part; None when it asks nothing), each {"name", "p", "color", "asked"} as reads_as_rows gives them."""
    out = []
    for part, weights in zip(("upper", "lower"), part_weights, strict=True):
        if part not in readings:
            continue
        rows = reads_as_rows(readings[part], weights, class_names)
        top = [int(i) for i in np.argsort(-readings[part], kind="stable")[:2]]
        asked = int(np.argmax(np.abs(weights))) if np.abs(weights).max() > 1e-6 else None
        shown = top + ([asked] if asked is not None and asked not in top else [])
        out.append({"part": PART_NAMES[part], "classes": [rows[i] for i in shown],
                    "asked": None if asked is None else rows[asked]})
    return out


def part_note(parts: Sequence[dict]) -> str:
    """One line, each part in words with whether it does what was asked, by the mix bar's share (MIX_SHARE): 'upper
    body reads as shaking hands 61%, as asked · lower body avoids pushing (2%), as asked'; 'upper body reads as
    hugging 12%: not as asked (under 25%)'; 'lower body still reads as pushing 40%: asked to avoid it'. A part asked
    with less than ASKED_WEIGHT is a nudge (its reading, not judged); a part asking nothing gives its top class."""
    said = []
    for part in parts:
        row, name = part["asked"], part["part"]
        if row is None:
            top = part["classes"][0]
            said.append(f"{name} reads as {top['name']} {top['p'] * 100:.0f}%")
            continue
        share, w = f"{row['p'] * 100:.0f}%", row["w"]
        if abs(w) < ASKED_WEIGHT:
            said.append(f"{name} reads as {row['name']} {share} (a nudge of {w:+g}: not judged)")
        elif w > 0:
            said.append(f"{name} reads as {row['name']} {share}"
                        + (", as asked" if row["p"] >= MIX_SHARE else f": not as asked (under {MIX_SHARE * 100:.0f}%)"))
        else:
            said.append(f"{name} avoids {row['name']} ({share}), as asked" if row["p"] < MIX_SHARE
                        else f"{name} still reads as {row['name']} {share}: asked to avoid it")
    return " · ".join(said)


def unread_note(rows: Sequence[dict], parts_differ: bool = False, parts: Sequence[dict] = ()) -> str:
    """'' when every class asked for with at least ASKED_WEIGHT reads; else which ones get under MIX_SHARE of the
    probability, in one line. A mix per body part gets the parts' note (part_note) instead, or PART_NOTE without part
    judges (the whole-body classifier cannot tell whether a part reads as asked)."""
    if parts_differ and rows:
        return part_note(parts) if parts else PART_NOTE
    unread = [r for r in rows if r.get("w", 1.0) >= ASKED_WEIGHT and r["asked"] == "+" and r["p"] < MIX_SHARE]
    if not unread:
        return ""
    listed = ", ".join(f"{r['name']} {r['p'] * 100:.0f}%" for r in unread)
    return f"Does not read as asked: {listed} (under {MIX_SHARE * 100:.0f}%)"


def reads_as_panel() -> None:
    """Place the panel (inside the drawer's current container)."""
    with html.Div(v_if="reads_as.length", id="reads-as"):
        with html.Div(classes="d-flex align-center mt-2"):
            html.Div("Reads as", classes="text-overline", style="white-space: nowrap")
            html.Div("classifier of real reactions · + asked", classes="text-caption text-medium-emphasis ml-2",
                     style="white-space: nowrap")
        with html.Div(v_for="(row, i) in reads_as", key=("i",), classes="d-flex align-center reads-as-row", style="height: 20px"):
            # the ask marks the class's name (+ perform, − avoid), never the share: "− 1%" read as minus one percent
            html.Div("{{ (row.asked === '+' ? '+ ' : row.asked === '-' ? '− ' : '') + row.name }}", classes="text-caption",
                     style=("'width: 118px; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; flex: 0 0 118px;'"
                            " + (row.asked ? 'font-weight: 700' : '')",))
            v3.VProgressLinear(model_value=("row.p * 100",), color=("row.color",), height=8, rounded=True,
                               bg_color="grey-lighten-2", classes="reads-as-bar", style="flex: 1 1 auto")
            html.Div("{{ (row.p * 100).toFixed(0) + '%' }}", classes="text-caption ml-1",
                     style="flex: 0 0 48px; text-align: right; white-space: nowrap")
        with html.Div(v_if="reads_as_parts.length", id="reads-as-parts", classes="mt-1"):
            with html.Div(v_for="part in reads_as_parts", key=("part.part",), classes="text-caption reads-as-part"):
                html.Span("{{ part.part }}: ", classes="text-medium-emphasis")
                html.Span("{{ (j ? ' · ' : '') + (c.asked ? c.asked + ' ' : '') + c.name + ' ' + (c.p * 100).toFixed(0) + '%' }}",
                          v_for="(c, j) in part.classes", key=("j",), style=("{fontWeight: c.asked ? 700 : 400}",))
        html.Div("{{ reads_as_note }}", v_if="reads_as_note", id="reads-as-note",
                 classes=("'text-caption mt-1 ' + (reads_as_note.startsWith('Does not') ? 'text-warning' : 'text-medium-emphasis')",))
