"""The review across sequences: every held-out sequence of the model's fold in one sortable table
(imm_model/evaluation/review.py: AFD, feature distance, what the reaction reads as, contact and foot flags), each
follower synthesized under the current mix (the sliders, the scale, the model, its seed and the clean-up), a
"next worst" step down the sorted column, and a click on a row that opens that sequence with the mix kept (the view
then shows the follower the row scored).

The table is computed off the event loop (one worker thread, made on the first open) and only once the user opens the
review: its first computation imports torch and loads the fold's feature classifier, which a studio process otherwise
never does. While the review is open, a new mix or model recomputes it (debounced); while it is closed the table is
only marked stale, and recomputed when it opens again.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from trame.app import asynchronous
from trame.widgets import client, html
from trame.widgets import vuetify3 as v3

from explorer.rendering.palette import display_name
from explorer.session.session import one_line
from imm_model.evaluation.review import LOWER_IS_WORSE, SORT_KEYS, ReviewRow, next_worst, sort_rows

if TYPE_CHECKING:
    from explorer.ui.panel_api import Page

DEBOUNCE_S = 0.6  # a new mix recomputes an open table once the sliders have been still this long
WIDTH = 600  # the review's side panel, pixels (its seven columns without a horizontal scroll)
TABLE_CSS = """
#review-table th, #review-table td { padding: 0 5px !important; white-space: nowrap; font-size: 11.5px; height: 26px !important; }
#review-table th { line-height: 1.1; }
"""

# (row key, header, decimals, sortable); the numeric sort keys are review.SORT_KEYS
COLUMNS: tuple[tuple[str, str, int | None, bool], ...] = (
    ("sequence_id", "sequence", None, True),
    ("class_name", "class", None, True),
    ("afd", "AFD", 3, True),
    ("feature_distance", "feat. dist.", 2, True),
    ("asked_p", "reads as", None, True),  # sorted by the probability of the asked classes (lowest worst)
    ("interpenetration", "contact", None, True),
    ("foot_skate_mps", "foot", None, True),
)


@dataclass(frozen=True)
class ReviewInputs:
    """What one table is computed from, read on the event loop when it starts (the worker thread never reads the page)."""

    model: Any
    model_name: str
    data: Any
    judge: Any
    label: tuple[float, ...]  # the model's label vector for the mix (the scale in it)
    seed: int
    raw: bool  # the clean-up off

    @property
    def key(self) -> tuple:
        return (self.model_name, self.label, self.seed, self.raw)


def session_inputs(session) -> ReviewInputs:
    return ReviewInputs(model=session.model, model_name=session.model_name, data=session.data, judge=session.reader,
                        label=tuple(round(float(x), 6) for x in session.label_vector()), seed=int(session.seed),
                        raw=bool(getattr(session.model, "raw", False)))


class StudioRows:
    """The studio's table: the model's held-out fold (review.default_split) under the inputs' mix, with FID's feature
    space of that fold and the real followers' foot threshold, both loaded once (in the worker thread)."""

    def __init__(self):
        self._features: dict[str | None, Any] = {}
        self._thresholds = None

    def __call__(self, inputs: ReviewInputs) -> list[ReviewRow]:
        from imm_model.evaluation.review import ReviewThresholds, fold_interaction_features, real_foot_threshold, review_table

        data = inputs.data
        subject = getattr(inputs.model, "held_out_subject", None) or data.info.get("held_out_subject") or None
        if subject not in self._features:
            self._features[subject] = fold_interaction_features(data, subject)
        if self._thresholds is None:
            self._thresholds = ReviewThresholds(real_foot_threshold(data))
        return review_table(inputs.model, data, judge=inputs.judge, label=list(inputs.label), features=self._features[subject],
                            seed=inputs.seed, thresholds=self._thresholds)


def row_state(row: ReviewRow) -> dict[str, Any]:
    """A row as the page's table reads it: JSON numbers (nan -> None), rounded, display names and the flags in words."""
    out: dict[str, Any] = {}
    for key, value in row.to_dict().items():
        if isinstance(value, float):
            value = None if math.isnan(value) else round(value, 4)
        out[key] = value
    out["class_name"] = display_name(row.class_name)
    out["reads_as"] = display_name(row.reads_as) if row.reads_as else ""
    marks = [row.contact_reason] if row.contact_flag else []
    if row.foot_flag:
        marks.append("foot skate")
    out["flag_text"] = ", ".join(marks)
    return out


class ReviewPanel:
    def __init__(self, page: Page, *, open_sequence: Callable[[int], None],
                 compute_rows: Callable[[ReviewInputs], Sequence[ReviewRow]] | None = None,
                 inputs: Callable[[], ReviewInputs] | None = None, prefix: str = "review"):
        """`open_sequence(index)` shows dataset sequence `index` in the studio (the mix kept); `compute_rows(inputs)` makes
        the table (default StudioRows: the model's fold under the mix), in a worker thread; `inputs()` reads what it is
        computed from (default: the page's session)."""
        self.page = page
        self.open_sequence = open_sequence
        self.compute_rows = compute_rows or StudioRows()
        self.inputs = inputs or (lambda: session_inputs(page.session))
        self.rows: list[ReviewRow] = []
        self.prefix = p = prefix
        self.names = {k: f"{p}_{k}" for k in ("rows", "sort_by", "current", "busy", "note", "error", "headers", "open",
                                               "stale", "under")}
        self._shown: tuple | None = None  # the inputs' key of the table on the page (None: never computed)
        self._task = None
        self._due_at: float | None = None  # when a computation is asked for (monotonic), None: none asked
        self._executor: ThreadPoolExecutor | None = None  # made on the first computation
        state, n = page.state, self.names
        state.update({
            n["rows"]: [],
            n["sort_by"]: [{"key": "afd", "order": "desc"}],
            n["current"]: None,
            n["busy"]: False,
            n["note"]: "",  # what the table is short of ("the last row ...")
            n["error"]: "",  # why the last computation failed, one line
            n["headers"]: [{"title": title, "key": key, "sortable": sortable} for key, title, _, sortable in COLUMNS],
            n["open"]: False,
            n["stale"]: False,  # the mix or model changed since the table was computed
            n["under"]: "",  # the mix and model the table is for, in words
        })  # fmt: skip
        state.change(n["open"])(self.on_open_change)
        page.trigger(f"{p}_refresh_pressed")(lambda: self.schedule(0.0))
        page.trigger(f"{p}_next_worst_pressed")(page.guarded(self.next_worst))
        page.trigger(f"{p}_open_row")(page.guarded(self.open))

    @property
    def state(self):
        return self.page.state

    # ---- when to compute ------------------------------------------------------------------------------------------------
    def on_open_change(self, **kwargs):
        if kwargs.get(self.names["open"]) and self._shown != self.inputs().key:
            self.schedule(0.0)

    def follow(self) -> None:
        """The studio shows another sequence, mix or model (called after each): the current row follows the studio's
        sequence; a table of another mix is recomputed when the review is open (debounced), else marked stale."""
        ses = self.page.session
        self.state[self.names["current"]] = None if ses.upload else int(ses.index)
        if self._shown is None:
            return
        changed = self._shown != self.inputs().key
        self.state[self.names["stale"]] = changed
        if changed and self.state[self.names["open"]]:
            self.schedule(DEBOUNCE_S)

    def schedule(self, delay: float) -> None:
        """Compute the table `delay` s from now (a later call moves the time; one computation at a time)."""
        self._due_at = time.monotonic() + delay
        if self._task is None or self._task.done():
            self._task = asynchronous.create_task(self._run())

    async def _run(self) -> None:
        while self._due_at is not None:
            wait = self._due_at - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
                continue
            self._due_at = None
            await self.recompute()

    async def recompute(self) -> None:
        """One table, computed in the worker thread; a failure is one line over the table, never a traceback."""
        state, n = self.state, self.names
        inputs = self.inputs()
        with state:
            state[n["busy"]] = True
            state[n["error"]] = ""
        try:
            if self._executor is None:
                self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imm-review")
            rows = await asyncio.get_running_loop().run_in_executor(self._executor, self.compute_rows, inputs)
            self.rows, error = list(rows), ""
        except Exception as err:  # noqa: BLE001 - the page shows it on one line
            self.rows, error = [], f"the review failed: {one_line(err)}"
        with state:
            self._shown = inputs.key if not error else None
            state[n["rows"]] = [row_state(r) for r in sort_rows(self.rows, self.sort_key())]
            state[n["error"]] = error
            state[n["note"]] = "" if self.rows or error else "no held-out sequences for this model"
            state[n["under"]] = self.under_text(inputs)
            state[n["stale"]] = self._shown is not None and self._shown != self.inputs().key
            state[n["busy"]] = False
            if state[n["stale"]] and state[n["open"]]:  # the mix moved while it computed
                self.schedule(DEBOUNCE_S)

    def under_text(self, inputs: ReviewInputs) -> str:
        ses = self.page.session
        seed = f" · seed {inputs.seed}" if "seed" in inputs.model.settings else ""
        return f"{ses.model_title(inputs.model_name)}{seed} · {ses.label_text()}"

    # ---- what the controls do -------------------------------------------------------------------------------------------
    def sort_key(self) -> str:
        """The table's sort column when it is a review.SORT_KEYS one, else AFD."""
        sort_by = self.state[self.names["sort_by"]] or []
        key = sort_by[0].get("key") if sort_by and isinstance(sort_by[0], dict) else None
        return key if key in SORT_KEYS else "afd"

    def open(self, index) -> None:
        """A row clicked: the studio opens dataset sequence `index` (and the row is the current one)."""
        index = int(index[0] if isinstance(index, list | tuple) else index)
        self.state[self.names["current"]] = index
        self.open_sequence(index)

    def next_worst(self) -> int | None:
        """Open the row after the current one in the sort column's worst-first order (the worst when none is current);
        None, with a note, after the last."""
        state, key = self.state, self.sort_key()
        row = next_worst(self.rows, state[self.names["current"]], key)
        state[self.names["sort_by"]] = [{"key": key, "order": "asc" if key in LOWER_IS_WORSE else "desc"}]
        if row is None:
            state[self.names["note"]] = "the last row: nothing worse is left" if self.rows else "no table yet"
            return None
        state[self.names["note"]] = ""
        self.open(row.index)
        return row.index


def review_button() -> None:
    """The side panel's button that opens and closes the review; it stays at the top of the panel when that scrolls."""
    with html.Div(style="position: sticky; top: 0; z-index: 3; background: rgb(var(--v-theme-surface))", classes="pt-3 pb-1"):
        v3.VBtn("Review across sequences", id="review-open", size="small", variant="tonal", block=True,
                prepend_icon="mdi-table-search", color=("review_open ? 'primary' : undefined",),
                click="review_open = !review_open", title="every held-out sequence under this mix, worst first")


def review_drawer(panel_prefix: str = "review") -> None:
    """The review's side panel (right of the main column; it narrows the main column while open)."""
    n = {k: f"{panel_prefix}_{k}" for k in ("rows", "sort_by", "current", "busy", "note", "error", "headers", "open",
                                             "stale", "under")}
    p = panel_prefix
    with v3.VNavigationDrawer(v_model=(n["open"],), location="right", permanent=True, width=WIDTH, id=f"{p}-drawer"):
        with html.Div(classes="pa-2 d-flex flex-column", style="height: 100%; min-height: 0"):
            with html.Div(classes="d-flex align-center", style="gap: 6px"):
                html.Div("Review across sequences", classes="text-overline", style="white-space: nowrap")
                v3.VProgressCircular(v_if=n["busy"], indeterminate=True, size=14, width=2, id=f"{p}-busy")
                v3.VSpacer()
                v3.VBtn("Next worst", id=f"{p}-next-worst", size="x-small", variant="tonal", prepend_icon="mdi-arrow-down",
                        disabled=(f"!{n['rows']}.length",), click=f"trigger('{p}_next_worst_pressed')")
                v3.VBtn(icon="mdi-refresh", id=f"{p}-refresh", size="x-small", variant="text", title="compute again",
                        disabled=(n["busy"],), click=f"trigger('{p}_refresh_pressed')")
                v3.VBtn(icon="mdi-close", size="x-small", variant="text", title="close the review", click=f"{n['open']} = false")
            html.Div(f"held-out sequences of the model's fold under {{{{ {n['under']} || 'the current mix' }}}}",
                     classes="text-caption text-medium-emphasis", id=f"{p}-under")
            html.Div(f"computing the table{{{{ {n['rows']}.length ? '' : ' (the first time loads the feature classifier)' }}}}...",
                     v_if=n["busy"], classes="text-caption", id=f"{p}-busy-text")
            html.Div("the mix or model changed: the table is of the previous one", v_if=f"{n['stale']} && !{n['busy']}",
                     classes="text-caption text-warning", id=f"{p}-stale")
            html.Div(f"{{{{ {n['error']} }}}}", v_if=n["error"], id=f"{p}-error", classes="text-caption text-error",
                     style="white-space: nowrap; overflow: hidden; text-overflow: ellipsis")
            html.Div(f"{{{{ {n['note']} }}}}", v_if=n["note"], id=f"{p}-note", classes="text-caption text-warning")
            with html.Div(style="flex: 1 1 auto; min-height: 0; position: relative"):
                review_table(n, p)
            client.Style(TABLE_CSS)


def review_table(n: dict[str, str], p: str) -> None:
    with v3.VDataTable(id=f"{p}-table", headers=(n["headers"],), items=(n["rows"],), item_value="index",
                       sort_by=(n["sort_by"],), update_sortBy=f"{n['sort_by']} = $event", multi_sort=False,
                       must_sort=True, density="compact", items_per_page=("-1",), hover=True, fixed_header=True,
                       height="100%", hide_default_footer=True, style="position: absolute; inset: 0"):
        with v3.Template(raw_attrs=['v-slot:item="{ item }"']):
            with html.Tr(click=f"trigger('{p}_open_row', [item.index])", raw_attrs=[':data-index="item.index"'],
                         classes=(f"'review-row' + (item.index === {n['current']} ? ' bg-blue-lighten-4 review-current' : '')",),
                         style="cursor: pointer"):
                for key, _, decimals, _ in COLUMNS:
                    if key == "asked_p":
                        share = "item.reads_as_p == null ? '' : ' ' + (item.reads_as_p * 100).toFixed(0) + '%'"
                        html.Td(f"{{{{ item.reads_as }}}}{{{{ {share} }}}}", classes="text-caption",
                                title=("item.asked_p == null ? '' : 'P(asked) ' + (item.asked_p * 100).toFixed(0) + '%'",))
                    elif key == "interpenetration":
                        html.Td("{{ item.contact_flag ? item.contact_reason : '' }}", classes="text-caption text-error",
                                title=("'bones within 5 cm on ' + (item.interpenetration * 100).toFixed(0) + '% of frames'",))
                    elif key == "foot_skate_mps":
                        html.Td("{{ item.foot_skate_mps == null ? '–' : item.foot_skate_mps.toFixed(2) }}",
                                classes=("'text-caption text-right' + (item.foot_flag ? ' text-error font-weight-bold' : '')",),
                                title="foot skate, m/s (red: over the real followers' 95th percentile)")
                    elif decimals is None:
                        html.Td(f"{{{{ item.{key} }}}}", classes="text-caption", style="white-space: nowrap")
                    else:
                        html.Td(f"{{{{ item.{key} == null ? '–' : item.{key}.toFixed({decimals}) }}}}",
                                classes=f"text-caption text-right review-{key}")
