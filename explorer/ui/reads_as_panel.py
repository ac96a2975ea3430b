"""The "reads as" panel: which interaction the synthesized reaction on screen reads as, per the follower-only
classifier (imm_model/reads_as.py), one bar per class, the asked-for classes marked. Updated with every slider
move, so a user sees whether a mix reads as intended; an asked-for class the classifier barely sees is named under
the bars (the mixes that fail the mix target show this way, docs/user-guide.md "Mixes that do not read").

The bundled classifier reads the whole follower: for a mix per body part the panel shows that reading with a caption
(a reading per part needs the evaluation's body-part judges, imm_model/evaluation/loso.py, which are not bundled)."""

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


PART_NOTE = "the whole body's reading: a reading per body part needs part judges, which the studio does not have"


def unread_note(rows: Sequence[dict], parts_differ: bool = False) -> str:
    """'' when every class asked for with at least ASKED_WEIGHT reads; else which ones get under MIX_SHARE of the
    probability, in one line. A mix per body part gets PART_NOTE instead (the whole-body classifier cannot tell whether
    a part reads as asked)."""
    if parts_differ and rows:
        return PART_NOTE
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
            html.Div("{{ row.name }}", classes="text-caption",
                     style=("'width: 118px; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; flex: 0 0 118px;'"
                            " + (row.asked ? 'font-weight: 700' : '')",))
            v3.VProgressLinear(model_value=("row.p * 100",), color=("row.color",), height=8, rounded=True,
                               bg_color="grey-lighten-2", classes="reads-as-bar", style="flex: 1 1 auto")
            html.Div("{{ (row.asked ? row.asked + ' ' : '') + (row.p * 100).toFixed(0) + '%' }}", classes="text-caption ml-1",
                     style="flex: 0 0 48px; text-align: right; white-space: nowrap")
        html.Div("{{ reads_as_note }}", v_if="reads_as_note", id="reads-as-note",
                 classes=("'text-caption mt-1 ' + (reads_as_note.startsWith('Does not') ? 'text-warning' : 'text-medium-emphasis')",))
