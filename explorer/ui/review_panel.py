"""The review across sequences: ground truth against every model the session holds, one row per sequence
(imm_model/evaluation/review.py: AFD, feature distance, what the reaction reads as, contact and foot flags), each
model's numbers in columns of their own, side by side.

- Labels: each row under its own class ("match", the default: what a ground-truth review means), or every row under
  the current mix (the sliders and the scale).
- Rows: the held-out sequences of the studio's first model's fold, or all sequences; per sequence, or one summary row
  per class (means, and how many rows are flagged).
- The table fills in as it is computed: rows come a few at a time, model by model (a progress line says how far), and
  the feature distances, which need the fold's feature classifier (torch; trained once on a fresh clone), come last.
- "Next worst" steps down the sorted column; a click on a row opens that sequence and plays it, as a click on the
  latent map does (under its own class, or under the mix when the table is of the mix).
- Columns: as many models' column groups as fit the pane (the page measures it), chosen with chips; a model picked
  beyond that replaces the longest-shown one, so the table never scrolls sideways unseen. Per class, the "all classes"
  row stays first whatever the sort.

The table is computed off the event loop (one worker thread, made on the first open) and only once the user opens the
review. While it is open, a change of what it is computed from (models, labels, rows, seed, clean-up; the mix in
"mix" mode) recomputes it, debounced; while it is closed the table is only marked stale, and recomputed when it opens.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from trame.app import asynchronous
from trame.widgets import client, html
from trame.widgets import vuetify3 as v3

from explorer.rendering.palette import display_name
from explorer.session.words import no_parts, one_line
from imm_model.data.labels import Label
from imm_model.evaluation.review import LOWER_IS_WORSE, SORT_KEYS, ReviewRow, next_worst, sort_rows

if TYPE_CHECKING:
    from explorer.ui.panel_api import Page

DEBOUNCE_S = 0.6  # a change recomputes an open table once the sliders have been still this long
CHUNK_ROWS = 8  # followers per synthesis call: the table fills in this many rows at a time
SPLITS = {"held": "held out", "all": "all"}
# Each column's width in px (a cell's text is cut to it, whole on hover): the page fits as many model groups as these
# widths allow (page_aids.js immWatchFit), so they must hold the headers ("reads as" and its sort arrow) too.
CELL_PAD = 8  # a cell's padding, both sides
FIXED_WIDTHS = {"sequence": 90, "class": 92}
METRIC_WIDTHS = {"afd": 44, "feature_distance": 44, "asked_p": 84, "flags": 60}
FIXED_PX = sum(FIXED_WIDTHS.values()) + CELL_PAD * len(FIXED_WIDTHS)
MODEL_PX = sum(METRIC_WIDTHS.values()) + CELL_PAD * len(METRIC_WIDTHS)
TABLE_CSS = """
#review-table { --v-table-header-height: 24px; }
#review-table th, #review-table td { padding: 0 4px !important; white-space: nowrap; font-size: 11.5px; height: 24px !important; }
#review-table th { line-height: 1.1; }
#review-table td > span { display: inline-block; overflow: hidden; text-overflow: ellipsis; vertical-align: bottom; }
#review-table tr.review-summary td { font-weight: 600; }
""" + "".join(f"#review-table .review-{key} > span {{ width: {px}px; }}\n" for key, px in {**FIXED_WIDTHS, **METRIC_WIDTHS}.items())

# One model's columns: (metric, header, what the cell shows; None: the number with 3 decimals). Sorting is by the
# metric (review.SORT_KEYS): for "reads as" the probability of the asked classes (lowest worst), for flags their count.
MODEL_COLUMNS: tuple[tuple[str, str], ...] = (
    ("afd", "AFD"),
    ("feature_distance", "feat."),
    ("asked_p", "reads as"),
    ("flags", "flags"),
)


def column_key(k: int, metric: str) -> str:
    """The table's key of model `k`'s metric: a path into the row's per-model numbers (models are named by position:
    a model's name may hold any character)."""
    return f"m{k}.{metric}"


def parse_sort_key(key: str | None, n_models: int) -> tuple[int, str]:
    """"m1.asked_p" -> (1, "asked_p"); a key that is not a model's review metric -> the first model's AFD."""
    head, _, metric = (key or "").partition(".")
    if head[:1] == "m" and head[1:].isdigit() and int(head[1:]) < n_models and metric in SORT_KEYS:
        return int(head[1:]), metric
    return 0, "afd"


@dataclass(frozen=True)
class ReviewInputs:
    """What one table is computed from, read on the event loop when it starts (the worker thread never reads the page)."""

    models: tuple[tuple[str, Any], ...]  # the session's models, (name, model), in its order
    data: Any
    judge: Any
    labels: str  # "match" or "mix"
    label: Label  # the mix ("mix" only), as the session holds it
    indices: tuple[int, ...]  # the rows' dataset indices
    split: str  # "held" or "all"
    subject: str | None  # the held-out subject of the rows' fold (the feature space's fold)
    seed: int
    raw: bool  # the clean-up off

    @property
    def key(self) -> tuple:
        mix = (self.label.text(), self.label.scale) if self.labels == "mix" else None
        return (tuple(name for name, _ in self.models), self.labels, mix, self.split, self.seed, self.raw)

    def label_vectors(self, model, indices: Sequence[int]) -> np.ndarray:
        """(N, C): each row's label as `model` takes it (its own class at +1, or the mix)."""
        n = len(self.data.class_names)
        if self.labels == "mix":
            if self.label.parts_differ and not model.part_labels:  # a part mix is never approximated (Session.set_model)
                raise no_parts(model.title)
            vec = np.asarray(model.label_vector(self.label), np.float32)
            return np.repeat(vec[None], len(indices), 0)
        own = {c: np.asarray(model.label_vector(list(np.eye(n)[c]), scale=1.0), np.float32) for c in range(n)}
        return np.stack([own[int(self.data.actions[i])] for i in indices])


def session_inputs(session, labels: str, split: str) -> ReviewInputs:
    """The page's session as a table's inputs. Every model reviews with the clean-up the studio shows."""
    from imm_model.evaluation.review import default_split

    models = tuple(session.models.items())
    raw = bool(getattr(session.model, "raw", False))
    for _, model in models:
        model.raw = raw  # what switching to it would set (explorer/session/session.py set_model)
    data, first = session.data, models[0][1]
    subject = getattr(first, "held_out_subject", None) or data.info.get("held_out_subject") or None
    indices = default_split(first, data) if split == "held" else np.arange(len(data))
    return ReviewInputs(models=models, data=data, judge=session.readings.reader, labels=labels,
                        label=session.label,
                        indices=tuple(int(i) for i in indices), split=split, subject=subject, seed=int(session.seed), raw=raw)


class ReviewCompute(Protocol):
    """What the panel runs in its worker thread (StudioCompute; tests give a stand-in)."""

    def rows(self, inputs: ReviewInputs, model, indices: Sequence[int]) -> tuple[list[ReviewRow], list[np.ndarray]]: ...

    def feature_distances(self, inputs: ReviewInputs, indices: Sequence[int], followers: list[np.ndarray]) -> np.ndarray: ...


class StudioCompute:
    """The rows of one model (review.py's synthesis and scores) and, last, their distances in FID's feature space of
    the rows' fold; the real followers' foot threshold and each fold's feature space are loaded once."""

    def __init__(self):
        self._features: dict[str | None, Any] = {}
        self._thresholds = None

    def rows(self, inputs: ReviewInputs, model, indices: Sequence[int]) -> tuple[list[ReviewRow], list[np.ndarray]]:
        from imm_model.evaluation.review import ReviewThresholds, pairs_of, real_foot_threshold, score_rows, synthesize_followers

        if self._thresholds is None:
            self._thresholds = ReviewThresholds(real_foot_threshold(inputs.data))
        labels = inputs.label_vectors(model, indices)
        leaders, _ = pairs_of(inputs.data, indices)
        followers = synthesize_followers(model, leaders, labels, inputs.seed)
        rows = score_rows(inputs.data, indices, labels, followers, judge=inputs.judge, thresholds=self._thresholds)
        return rows, followers

    def feature_distances(self, inputs: ReviewInputs, indices: Sequence[int], followers: list[np.ndarray]) -> np.ndarray:
        from imm_model.evaluation.review import feature_distances, fold_interaction_features, pairs_of

        if inputs.subject not in self._features:
            self._features[inputs.subject] = fold_interaction_features(inputs.data, inputs.subject)
        leaders, reals = pairs_of(inputs.data, indices)
        actions = np.asarray(inputs.data.actions)[np.asarray(indices, int)]
        return feature_distances(self._features[inputs.subject], leaders, reals, followers, actions)


def _number(value: float) -> float | None:
    return None if value is None or math.isnan(value) else round(float(value), 4)


def model_cells(row: ReviewRow) -> dict[str, Any]:
    """One model's numbers of a row as the page's table reads them: JSON numbers (nan -> None), the flags in words."""
    marks = [row.contact_reason] if row.contact_flag else []
    if row.foot_flag:
        marks.append("foot skate")
    return {"afd": _number(row.afd), "feature_distance": _number(row.feature_distance), "asked_p": _number(row.asked_p),
            "reads_as": display_name(row.reads_as) if row.reads_as else "", "reads_as_p": _number(row.reads_as_p),
            "flags": row.flags, "flag_text": ", ".join(marks), "foot_skate_mps": _number(row.foot_skate_mps)}


def summary_cells(rows: Sequence[ReviewRow]) -> dict[str, Any]:
    """One model's numbers over several rows: means, and the flagged rows counted."""
    def mean(values):
        values = [v for v in values if not math.isnan(v)]
        return _number(float(np.mean(values))) if values else None

    flagged = sum(1 for r in rows if r.flags)
    return {"afd": mean([r.afd for r in rows]), "feature_distance": mean([r.feature_distance for r in rows]),
            "asked_p": mean([r.asked_p for r in rows]), "reads_as": "", "reads_as_p": None, "flags": flagged,
            "flag_text": f"{flagged} of {len(rows)} flagged" if flagged else "", "foot_skate_mps": mean([r.foot_skate_mps for r in rows])}


class ReviewPanel:
    def __init__(self, page: Page, *, open_sequence: Callable[[int, bool], None], compute: ReviewCompute | None = None,
                 inputs: Callable[[str, str], ReviewInputs] | None = None, prefix: str = "review"):
        """`open_sequence(index, keep_mix)` shows dataset sequence `index` in the studio, under its own class or with the
        mix kept; `compute` makes the rows in a worker thread (default StudioCompute); `inputs(labels, split)` reads
        what a table is computed from (default: the page's session)."""
        self.page = page
        self.open_sequence = open_sequence
        self.compute = compute or StudioCompute()
        self.inputs = inputs or (lambda labels, split: session_inputs(page.session, labels, split))
        self.names_of_models: list[str] = list(getattr(page.session, "models", {}) or [])
        self.rows: dict[int, dict[int, ReviewRow]] = {}  # model position -> dataset index -> row
        self.prefix = p = prefix
        self.names = {k: f"{p}_{k}" for k in ("rows", "sort_by", "current", "busy", "note", "error", "headers", "open",
                                               "stale", "under", "progress", "labels", "split", "per", "models", "shown", "fit")}
        self._picks: list[int] = []  # the models whose columns the user picked, oldest pick first (none: as many as fit)
        self._shown: tuple | None = None  # the inputs' key of the table on the page (None: never computed)
        self._order: list[int] = []  # the rows' dataset indices, in the table's order of computation
        self._task = None
        self._due_at: float | None = None  # when a computation is asked for (monotonic), None: none asked
        self._executor: ThreadPoolExecutor | None = None  # made on the first computation
        state, n = page.state, self.names
        state.update({
            n["rows"]: [],
            n["sort_by"]: [{"key": column_key(0, "afd"), "order": "desc"}],
            n["current"]: None,
            n["busy"]: False,
            n["progress"]: "",  # how far the computation is, in words
            n["note"]: "",  # what the table is short of ("the last row ...")
            n["error"]: "",  # why the last computation failed, one line
            n["headers"]: self.headers(),
            n["open"]: False,
            n["stale"]: False,  # what the table is computed from changed since
            n["under"]: "",  # what the table is of, in words
            n["labels"]: "match",
            n["split"]: "held",
            n["per"]: "sequence",  # or "class": one summary row per class
            n["models"]: self.model_chips(),
            n["shown"]: list(range(len(self.names_of_models))),  # the models whose columns the table shows
            n["fit"]: None,  # how many model column groups the pane fits (the page measures it; None: not yet)
        })  # fmt: skip
        state.change(n["open"], n["labels"], n["split"])(self.on_choice_change)
        state.change(n["per"])(lambda **_: self.publish())
        state.change(n["fit"])(lambda **_: self.show_columns())
        page.trigger(f"{p}_columns_picked")(self.pick_columns)
        page.trigger(f"{p}_refresh_pressed")(lambda: self.schedule(0.0))
        page.trigger(f"{p}_next_worst_pressed")(page.guarded(self.next_worst))
        page.trigger(f"{p}_open_row")(page.guarded(self.open))

    @property
    def state(self):
        return self.page.state

    def headers(self) -> list[dict]:
        models = [{"title": self.page.session.model_title(name), "align": "center", "model": k,
                   "children": [{"title": title, "key": column_key(k, metric), "sortable": True} for metric, title in MODEL_COLUMNS]}
                  for k, name in enumerate(self.names_of_models)]
        return [{"title": "sequence", "key": "sequence_id", "sortable": True},
                {"title": "class", "key": "class_name", "sortable": True}, *models]

    def model_chips(self) -> list[dict]:
        """The column chips: each model by the name `imm explore --model` gave it (short), its title on hover."""
        return [{"value": k, "name": name, "title": self.page.session.model_title(name)} for k, name in enumerate(self.names_of_models)]

    def current_inputs(self) -> ReviewInputs:
        return self.inputs(self.state[self.names["labels"]] or "match", self.state[self.names["split"]] or "held")

    # ---- when to compute ------------------------------------------------------------------------------------------------
    def on_choice_change(self, **_):
        """The review opened, or its labels or rows changed: compute when what is shown is not of the inputs."""
        if self.state[self.names["open"]] and self._shown != self.current_inputs().key:
            self.schedule(0.0)
        elif self._shown is not None:
            self.state[self.names["stale"]] = self._shown != self.current_inputs().key

    def follow(self) -> None:
        """The studio shows another sequence, mix or model (called after each): the current row follows the studio's
        sequence; a table of other inputs is recomputed when the review is open (debounced), else marked stale."""
        ses = self.page.session
        self.state[self.names["current"]] = None if ses.upload else int(ses.index)
        if self._shown is None:
            return
        changed = self._shown != self.current_inputs().key
        self.state[self.names["stale"]] = changed
        if changed and self.state[self.names["open"]]:
            self.schedule(DEBOUNCE_S)

    def schedule(self, delay: float) -> None:
        """Compute the table `delay` s from now (a later call moves the time; one computation at a time: one under way
        stops at its next step)."""
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

    async def _in_worker(self, fn, *args):
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imm-review")
        return await asyncio.get_running_loop().run_in_executor(self._executor, fn, *args)

    async def recompute(self) -> None:
        """One table, published as it fills in: each model's rows a chunk at a time, then the feature distances. A newer
        request stops it at its next step (the rows so far stay, marked stale); a failure is one line over the table."""
        state, n = self.state, self.names
        inputs = self.current_inputs()
        self.names_of_models = [name for name, _ in inputs.models]
        self.rows, self._order = {k: {} for k in range(len(inputs.models))}, list(inputs.indices)
        with state:
            state[n["busy"]] = True
            state[n["error"]] = ""
            state[n["headers"]] = self.headers()
            state[n["models"]] = self.model_chips()
            self.show_columns()
            state[n["under"]] = self.under_text(inputs)
        followers: dict[int, dict[int, np.ndarray]] = {k: {} for k in self.rows}
        total, done, error = len(inputs.indices) * len(inputs.models), 0, ""
        try:
            for start in range(0, len(inputs.indices), CHUNK_ROWS):  # a few rows, every model, then the next few
                if self._due_at is not None:
                    break
                chunk = inputs.indices[start:start + CHUNK_ROWS]
                for k, (_, model) in enumerate(inputs.models):
                    rows, drawn = await self._in_worker(self.compute.rows, inputs, model, chunk)
                    self.rows[k].update({r.index: r for r in rows})
                    followers[k].update(zip(chunk, drawn, strict=True))
                    done += len(chunk)
                self.publish(f"{done // len(inputs.models)} of {len(inputs.indices)} rows ({done} of {total} followers)")
            for k, (name, _) in enumerate(inputs.models):
                if self._due_at is not None or len(followers[k]) < len(inputs.indices):
                    break
                title = self.page.session.model_title(name)
                self.publish(f"feature distances of {title} (the first time loads the fold's feature classifier)")
                distances = await self._in_worker(self.compute.feature_distances, inputs, list(inputs.indices),
                                                  [followers[k][i] for i in inputs.indices])
                self.rows[k] = {i: replace(self.rows[k][i], feature_distance=float(d))
                                for i, d in zip(inputs.indices, distances, strict=True)}
        except Exception as err:  # noqa: BLE001 - the page shows it on one line
            error = f"the review failed: {one_line(err)}"
        complete = not error and all(len(r) == len(inputs.indices) for r in self.rows.values())
        with state:
            self._shown = inputs.key if complete or self._due_at is not None else None
            self.publish("")
            state[n["error"]] = error
            state[n["note"]] = "" if inputs.indices or error else "no held-out sequences for this model"
            state[n["stale"]] = self._shown is not None and (not complete or self._shown != self.current_inputs().key)
            state[n["busy"]] = False
            if state[n["stale"]] and state[n["open"]] and self._due_at is None:  # what it is of moved while it computed
                self.schedule(DEBOUNCE_S)

    def publish(self, progress: str | None = None) -> None:
        """The rows so far on the page: one per sequence (each model's numbers under m0, m1, ...), or one per class."""
        state, n = self.state, self.names
        done = [i for i in self._order if all(i in rows for rows in self.rows.values())] if self.rows else []
        data = self.page.session.data
        if state[n["per"]] == "class" and done:
            classes = sorted({int(data.actions[i]) for i in done})
            groups = [(-1 - c, f"{display_name(data.class_names[c])}", [i for i in done if int(data.actions[i]) == c]) for c in classes]
            groups.append((-1 - len(data.class_names), "all classes", done))
            table = [{"index": key, "sequence_id": f"{len(members)} rows", "class_name": title, "summary": True,
                      "pinned": title == "all classes",  # first in the table, whatever the sort
                      **{f"m{k}": summary_cells([rows[i] for i in members]) for k, rows in self.rows.items()}}
                     for key, title, members in groups]
        else:
            table = []
            for i in done:
                first = self.rows[0][i]
                table.append({"index": i, "sequence_id": first.sequence_id, "class_name": display_name(first.class_name),
                              "subject_pair": first.subject_pair, **{f"m{k}": model_cells(rows[i]) for k, rows in self.rows.items()}})
        with state:
            state[n["rows"]] = table
            if progress is not None:
                state[n["progress"]] = progress

    def under_text(self, inputs: ReviewInputs) -> str:
        rows = f"{len(inputs.indices)} held-out sequences (subject {inputs.subject})" if inputs.split == "held" and inputs.subject \
            else f"{len(inputs.indices)} {'held-out ' if inputs.split == 'held' else ''}sequences"
        label = "each under its own class" if inputs.labels == "match" else f"all under {self.page.session.label_text()}"
        seeded = any(m.settings.seed for _, m in inputs.models)
        return f"{rows}, {label}{f' · seed {inputs.seed}' if seeded else ''}"

    # ---- which models' columns show ---------------------------------------------------------------------------------------
    def pick_columns(self, picked) -> None:
        """The user picked models' column chips: the newest picks that fit the pane show."""
        picked = [int(k) for k in picked or []]
        self._picks = [k for k in self._picks if k in picked] + [k for k in picked if k not in self._picks]
        self.show_columns()

    def show_columns(self) -> None:
        """The models whose columns show: the user's newest picks, or the first models, as many as fit the pane (all
        while it is not measured); the sort moves to a shown model when its own is hidden."""
        state, n = self.state, self.names
        count = len(self.names_of_models)
        fit = max(1, min(count, state[n["fit"]] or count))
        picks = [k for k in self._picks if k < count]
        shown = sorted(picks[-fit:]) if picks else list(range(fit))
        if shown != state[n["shown"]]:
            state[n["shown"]] = shown
        model, metric = parse_sort_key((state[n["sort_by"]] or [{}])[0].get("key"), max(1, count))
        if shown and model not in shown:
            order = (state[n["sort_by"]] or [{}])[0].get("order", "desc")
            state[n["sort_by"]] = [{"key": column_key(shown[0], metric), "order": order}]

    # ---- what the controls do -------------------------------------------------------------------------------------------
    def sort_key(self) -> tuple[int, str]:
        """The table's sort column as (model position, review.SORT_KEYS metric); the first model's AFD for another."""
        sort_by = self.state[self.names["sort_by"]] or []
        key = sort_by[0].get("key") if sort_by and isinstance(sort_by[0], dict) else None
        return parse_sort_key(key, max(1, len(self.rows)))

    def open(self, index) -> None:
        """A row clicked: the studio opens dataset sequence `index` and plays it (a class's summary row: that class's
        worst sequence in the sorted column)."""
        index = int(index[0] if isinstance(index, list | tuple) else index)
        if index < 0:
            model, metric = self.sort_key()
            rows = list(self.rows.get(model, {}).values())
            n = len(self.page.session.data.class_names)
            members = [r for r in rows if -1 - index >= n or int(self.page.session.data.actions[r.index]) == -1 - index]
            if not members:
                return
            index = sort_rows(members, metric)[0].index
        self.state[self.names["current"]] = index
        self.open_sequence(index, self.state[self.names["labels"]] == "mix")
        self.state.playing = True

    def next_worst(self) -> int | None:
        """Open the row after the current one in the sort column's worst-first order (the worst when none is current);
        None, with a note, after the last."""
        state = self.state
        model, metric = self.sort_key()
        rows = list(self.rows.get(model, {}).values())
        row = next_worst(rows, state[self.names["current"]], metric)
        state[self.names["sort_by"]] = [{"key": column_key(model, metric), "order": "asc" if metric in LOWER_IS_WORSE else "desc"}]
        if row is None:
            state[self.names["note"]] = "the last row: nothing worse is left" if rows else "no table yet"
            return None
        state[self.names["note"]] = ""
        self.open(row.index)
        return row.index


def review_button() -> None:
    """The side panel's button that opens and closes the review; it stays at the top of the panel when that scrolls."""
    with html.Div(style="position: sticky; top: 0; z-index: 3; background: rgb(var(--v-theme-surface))", classes="pt-3 pb-1"):
        v3.VBtn("Review across sequences", id="review-open", size="small", variant="tonal", block=True,
                prepend_icon="mdi-table-search", color=("review_open ? 'primary' : undefined",),
                click="review_open = !review_open", title="every sequence against every model: ground truth vs synthesized")


def review_overlay(n_models: int, panel_prefix: str = "review") -> None:
    """The review, under the 3D view (the layout's fold gives the view 400 px and the review the rest of the window; the
    chart and the latent map follow below it)."""
    n = {k: f"{panel_prefix}_{k}" for k in ("rows", "sort_by", "current", "busy", "note", "error", "headers", "open",
                                             "stale", "under", "progress", "labels", "split", "per", "models", "shown", "fit")}
    p = panel_prefix
    with v3.VCard(v_if=n["open"], id=f"{p}-panel", variant="outlined", classes="pa-1 imm-review-panel"):
        review_controls(n, p)
        with html.Div(classes="text-caption d-flex align-center", style="gap: 8px; white-space: nowrap; overflow: hidden"):
            html.Span(f"{{{{ {n['under']} }}}}", classes="text-medium-emphasis", id=f"{p}-under",
                      style="overflow: hidden; text-overflow: ellipsis; flex: 0 1 auto; min-width: 40px")
            html.Span(f"{{{{ {n['progress']} }}}}", v_if=f"{n['busy']} && {n['progress']}", id=f"{p}-progress")
            html.Span("computing...", v_if=f"{n['busy']} && !{n['progress']}")
            html.Span("what it is of changed: this table is of the previous choice", v_if=f"{n['stale']} && !{n['busy']}",
                      classes="text-warning", id=f"{p}-stale")
            html.Span(f"{{{{ {n['error']} }}}}", v_if=n["error"], id=f"{p}-error", classes="text-error",
                      style="overflow: hidden; text-overflow: ellipsis")
            html.Span(f"{{{{ {n['note']} }}}}", v_if=n["note"], id=f"{p}-note", classes="text-warning")
            v3.VSpacer()
            column_chips(n, p)
        with html.Div(style="flex: 1 1 auto; min-height: 0; position: relative"):
            review_table(n, p, n_models)
        client.Style(TABLE_CSS)
        # the current row in sight (static/page_aids.js), whichever way it became current
        client.ClientStateChange(value=n["current"], change=f"utils.get('immScrollIntoView')('#{p}-table tr.review-current')")
        # how many model column groups the table's pane fits, measured again as it is resized (static/page_aids.js)
        client.ClientTriggers(mounted=f"utils.get('immWatchFit')('#{p}-table .v-table__wrapper', {FIXED_PX}, {MODEL_PX}, '{n['fit']}')")


def review_controls(n: dict[str, str], p: str) -> None:
    """The review's first line: its title, what the rows are of, and its buttons."""
    with html.Div(classes="d-flex align-center flex-wrap", style="gap: 6px; row-gap: 2px"):
        html.Div("Review: ground truth vs synthesized", classes="text-caption font-weight-bold", style="white-space: nowrap")
        v3.VProgressCircular(v_if=n["busy"], indeterminate=True, size=14, width=2, id=f"{p}-busy")
        for key, items, ident in (("labels", (("own class", "match"), ("current mix", "mix")), "labels"),
                                  ("split", (("held out", "held"), ("all", "all")), "split"),
                                  ("per", (("per sequence", "sequence"), ("per class", "class")), "per")):
            with v3.VBtnToggle(v_model=(n[key],), density="compact", mandatory=True, variant="outlined", divided=True,
                               id=f"{p}-{ident}"):
                for title, value in items:
                    v3.VBtn(title, value=value, size="x-small")
        v3.VSpacer()
        # the chart and the map are below the review while it is open: one click brings them in
        v3.VBtn("chart & map", id=f"{p}-to-cards", size="x-small", variant="text", prepend_icon="mdi-arrow-down",
                click="utils.get('immScrollIntoView')('#chart-card')", title="the error chart and the latent map, below the review")
        v3.VBtn("Next worst", id=f"{p}-next-worst", size="x-small", variant="tonal", prepend_icon="mdi-arrow-down",
                disabled=(f"!{n['rows']}.length",), click=f"trigger('{p}_next_worst_pressed')")
        v3.VBtn(icon="mdi-refresh", id=f"{p}-refresh", size="x-small", variant="text", title="compute again",
                disabled=(n["busy"],), click=f"trigger('{p}_refresh_pressed')")
        v3.VBtn(icon="mdi-close", size="x-small", variant="text", title="close the review", click=f"{n['open']} = false",
                id=f"{p}-close")


def column_chips(n: dict[str, str], p: str) -> None:
    """Which models' columns the table shows, one chip a model (the server keeps as many as fit: pick_columns)."""
    with html.Div(classes="d-flex align-center", style="gap: 4px; flex: 0 0 auto", id=f"{p}-columns"):
        html.Span("columns:", classes="text-medium-emphasis")
        with v3.VChipGroup(model_value=(n["shown"],), multiple=True, mandatory=True, color="primary",
                           update_modelValue=f"trigger('{p}_columns_picked', [$event])", classes="py-0"):
            v3.VChip("{{ m.name }}", v_for=f"m in {n['models']}", key=("m.value",), value=("m.value",), size="x-small",
                     filter=True, variant="outlined", title=("m.title + ' · as many as fit show; a new pick replaces the oldest'",),
                     classes="ma-0 mr-1 review-column-chip")


def review_table(n: dict[str, str], p: str, n_models: int) -> None:
    """The rows, in the shown models' columns; per class the "all classes" row is pinned first (body.prepend), out of
    the sort."""
    headers = f"{n['headers']}.filter((h) => h.model == null || {n['shown']}.includes(h.model))"
    with v3.VDataTable(id=f"{p}-table", headers=(headers,), items=(f"{n['rows']}.filter((r) => !r.pinned)",), item_value="index",
                       sort_by=(n["sort_by"],), update_sortBy=f"{n['sort_by']} = $event", multi_sort=False,
                       must_sort=True, density="compact", items_per_page=("-1",), hover=True, fixed_header=True,
                       height="100%", hide_default_footer=True, style="position: absolute; inset: 0",
                       no_data_text=(f"{n['busy']} ? 'the first rows are on their way...' : 'no rows'",)):
        with v3.Template(raw_attrs=['v-slot:item="{ item }"']):
            review_row(n, p, n_models)
        with v3.Template(raw_attrs=["v-slot:body.prepend"]):
            review_row(n, p, n_models, v_for=f"item in {n['rows']}.filter((r) => r.pinned)")


def review_row(n: dict[str, str], p: str, n_models: int, v_for: str | None = None) -> None:
    """One row of `item`: its sequence and class, then each shown model's numbers (cut to their column, whole on hover)."""
    with html.Tr(v_for=v_for, key=("item.index",) if v_for else None, click=f"trigger('{p}_open_row', [item.index])",
                 raw_attrs=[':data-index="item.index"'],
                 classes=(f"(item.summary ? 'review-summary' : 'review-row') + (item.pinned ? ' review-pinned' : '') + "
                          f"(item.index === {n['current']} ? ' bg-blue-lighten-4 review-current' : '')",),
                 style="cursor: pointer", title=("item.summary ? 'open its worst sequence' : 'open and play'",)):
        cell("{{ item.sequence_id }}", "review-sequence", title=("item.sequence_id",))
        cell("{{ item.class_name }}", "review-class", title=("item.class_name",))
        for k in range(n_models):
            m, shown = f"item.m{k}", f"{n['shown']}.includes({k})"
            cell(f"{{{{ {m}.afd == null ? '–' : {m}.afd.toFixed(3) }}}}", f"text-right review-afd review-m{k}-afd", v_if=shown)
            cell(f"{{{{ {m}.feature_distance == null ? '–' : {m}.feature_distance.toFixed(2) }}}}",
                 "text-right review-feature_distance", v_if=shown,
                 title="distance to the real reaction in FID's feature space (1.0: as far as another real interaction of the class)")
            reads = (f"{m}.reads_as ? {m}.reads_as + ' ' + ({m}.reads_as_p * 100).toFixed(0) + '%' : "
                     f"({m}.asked_p == null ? '' : 'asked ' + ({m}.asked_p * 100).toFixed(0) + '%')")
            cell(f"{{{{ {reads} }}}}", "review-asked_p", v_if=shown,
                 title=(f"({reads}) + ({m}.asked_p == null ? '' : ' · P(asked) ' + ({m}.asked_p * 100).toFixed(0) + '%')",))
            cell(f"{{{{ {m}.flag_text }}}}", "text-error review-flags", v_if=shown,
                 title=(f"{m}.flag_text + ({m}.foot_skate_mps == null ? '' : (({m}.flag_text ? ' · ' : '') + "
                        f"'foot skate ' + {m}.foot_skate_mps.toFixed(2) + ' m/s'))",))


def cell(text: str, classes: str, **attrs) -> None:
    """A table cell whose text is cut to its column's width (TABLE_CSS), the whole of it in the cell's title."""
    with html.Td(classes=f"text-caption {classes}", **attrs):
        html.Span(text)
