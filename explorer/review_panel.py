"""The review across sequences: every sequence of a split in one sortable table (imm_model/evaluation/review.py: AFD,
feature distance, what the reaction reads as, contact and foot flags), a "next worst" step down the sorted column,
and a click on a row opens that sequence.

The panel needs only what `ReviewSource` names: the page's state and controller, a function computing the rows (the
current model, split and label are the caller's business) and one opening a sequence. Wiring it into a page:

    panel = ReviewPanel(ReviewSource(server.state, server.controller, compute_rows=lambda: review_table(...),
                                     open_sequence=select, trigger=server.trigger))
    panel.ui()            # inside the layout, where the table goes
    panel.set_current(i)  # when the page opens sequence i by other means (keeps "next worst" where the user is)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from trame.widgets import html
from trame.widgets import vuetify3 as v3

from imm_model.evaluation.review import LOWER_IS_WORSE, SORT_KEYS, ReviewRow, next_worst, sort_rows

# (state key, header, decimals); the sortable numeric columns are review.SORT_KEYS
COLUMNS: tuple[tuple[str, str, int | None], ...] = (
    ("sequence_id", "sequence", None),
    ("class_name", "class", None),
    ("afd", "AFD", 3),
    ("feature_distance", "feature dist.", 2),
    ("reads_as", "reads as", None),
    ("asked_p", "P(asked)", 2),
    ("interpenetration", "overlap", 2),
    ("foot_skate_mps", "foot skate", 2),
    ("flags", "flags", 0),
)


@dataclass
class ReviewSource:
    """What the review panel needs from its page."""

    state: Any  # the trame state
    ctrl: Any  # the trame controller
    compute_rows: Callable[[], Sequence[ReviewRow]]  # the table now (the page's model, split and label)
    open_sequence: Callable[[int], None]  # show dataset sequence `index` in the studio
    trigger: Callable[[str], Callable[[Callable], Callable]]  # server.trigger: names a function the page calls with arguments
    prefix: str = "review"  # state and controller names: {prefix}_rows, {prefix}_sort_by, {prefix}_current, ...


def row_state(row: ReviewRow) -> dict[str, Any]:
    """A row as the page's table reads it: JSON numbers (nan -> None), rounded, with a flag text."""
    out: dict[str, Any] = {}
    for key, value in row.to_dict().items():
        if isinstance(value, float):
            value = None if math.isnan(value) else round(value, 4)
        out[key] = value
    marks = [row.contact_reason] if row.contact_flag else []
    if row.foot_flag:
        marks.append("foot skate")
    out["flag_text"] = ", ".join(marks)
    return out


class ReviewPanel:
    def __init__(self, source: ReviewSource):
        self.source = source
        self.rows: list[ReviewRow] = []
        p = source.prefix
        self.names = {k: f"{p}_{k}" for k in ("rows", "sort_by", "current", "busy", "note", "headers")}
        state = source.state
        state[self.names["rows"]] = []
        state[self.names["sort_by"]] = [{"key": "afd", "order": "desc"}]
        state[self.names["current"]] = None
        state[self.names["busy"]] = False
        state[self.names["note"]] = ""
        state[self.names["headers"]] = [{"title": title, "key": key, "sortable": key in SORT_KEYS or key in ("sequence_id", "class_name")}
                                        for key, title, _ in COLUMNS]
        source.ctrl[f"{p}_refresh"] = self.refresh
        source.ctrl[f"{p}_next_worst"] = self.next_worst
        source.ctrl[f"{p}_open"] = self.open
        self.open_trigger = f"{p}_open_row"
        source.trigger(self.open_trigger)(self.open)

    # ---- what the controllers do (testable without a page) -------------------------------------------------------------
    def sort_key(self) -> str:
        """The table's sort column when it is a review.SORT_KEYS one, else AFD."""
        sort_by = self.source.state[self.names["sort_by"]] or []
        key = sort_by[0].get("key") if sort_by and isinstance(sort_by[0], dict) else None
        return key if key in SORT_KEYS else "afd"

    def refresh(self) -> None:
        """Recompute the table; a problem is one line under it, never a traceback."""
        state = self.source.state
        state[self.names["busy"]] = True
        state.flush()
        try:
            self.rows = list(self.source.compute_rows())
            state[self.names["note"]] = "" if self.rows else "no sequences in this split"
        except Exception as err:  # noqa: BLE001 - the page shows it on one line
            self.rows = []
            state[self.names["note"]] = (str(err).splitlines() or [type(err).__name__])[0][:300]
        finally:
            state[self.names["rows"]] = [row_state(r) for r in sort_rows(self.rows, self.sort_key())]
            state[self.names["busy"]] = False

    def open(self, index: int) -> None:
        """A row clicked: the studio opens dataset sequence `index`."""
        self.set_current(int(index))
        self.source.open_sequence(int(index))

    def set_current(self, index: int | None) -> None:
        self.source.state[self.names["current"]] = index

    def next_worst(self) -> int | None:
        """Open the row after the current one in the sort column's worst-first order (the worst when none is current);
        None, with a note, after the last."""
        state, key = self.source.state, self.sort_key()
        row = next_worst(self.rows, state[self.names["current"]], key)
        state[self.names["sort_by"]] = [{"key": key, "order": "asc" if key in LOWER_IS_WORSE else "desc"}]
        if row is None:
            state[self.names["note"]] = "the last row: nothing worse is left" if self.rows else "compute the table first"
            return None
        state[self.names["note"]] = ""
        self.open(row.index)
        return row.index

    # ---- the widgets ---------------------------------------------------------------------------------------------------
    def ui(self) -> None:
        """Place the panel in the layout's current container."""
        n, p = self.names, self.source.prefix
        with html.Div(id=f"{p}-panel"):
            with html.Div(classes="d-flex align-center ga-2 mt-2"):
                html.Div("Review across sequences", classes="text-overline")
                v3.VBtn("Compute", id=f"{p}-refresh", size="small", variant="tonal", loading=(n["busy"],),
                        click=self.source.ctrl[f"{p}_refresh"])
                v3.VBtn("Next worst", id=f"{p}-next-worst", size="small", variant="tonal",
                        disabled=(f"!{n['rows']}.length",), click=self.source.ctrl[f"{p}_next_worst"])
            html.Div(f"{{{{ {n['note']} }}}}", v_if=n["note"], id=f"{p}-note", classes="text-caption text-warning")
            with v3.VDataTable(id=f"{p}-table", headers=(n["headers"],), items=(n["rows"],), item_value="index",
                               sort_by=(n["sort_by"],), update_sortBy=f"{n['sort_by']} = $event", multi_sort=False,
                               must_sort=True, density="compact", items_per_page=("-1",), hover=True, fixed_header=True,
                               height=320):
                with v3.Template(raw_attrs=['v-slot:item="{ item }"']):
                    with html.Tr(click=f"trigger('{self.open_trigger}', [item.index])",
                                 classes=(f"item.index === {n['current']} ? 'bg-blue-lighten-4' : ''",),
                                 style="cursor: pointer"):
                        for key, _, decimals in COLUMNS:
                            if key == "reads_as":
                                share = "item.reads_as_p == null ? '' : ' ' + (item.reads_as_p * 100).toFixed(0) + '%'"
                                html.Td(f"{{{{ item.reads_as }}}}{{{{ {share} }}}}", classes="text-caption")
                            elif key == "flags":
                                html.Td("{{ item.flag_text }}", classes="text-caption text-error")
                            elif decimals is None:
                                html.Td(f"{{{{ item.{key} }}}}", classes="text-caption")
                            else:
                                html.Td(f"{{{{ item.{key} == null ? '–' : item.{key}.toFixed({decimals}) }}}}",
                                        classes="text-caption text-right")
