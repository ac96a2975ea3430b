"""The review panel (explorer/ui/review_panel.py) on a bare trame server with a stand-in Page: its widgets build, its
computation runs off the event loop and only when asked, it sorts, steps and opens rows, and follows the mix. No
browser (tests/test_explorer_browser.py drives it in the studio)."""

from __future__ import annotations

import asyncio
import threading
from types import SimpleNamespace

import pytest

from imm_model.evaluation.review import ReviewRow


def row(index: int, afd: float, asked_p: float = 0.5, contact: str = "", foot: bool = False) -> ReviewRow:
    return ReviewRow(index=index, sequence_id=f"s/{index}", class_name="hugging", subject_pair="s01s04", frames=20,
                     afd=afd, feature_distance=float("nan"), reads_as="shaking_hands", reads_as_p=0.9, asked_p=asked_p,
                     interpenetration=0.0, real_interpenetration=0.0, closest_m=0.1, real_closest_m=0.1,
                     contact_flag=bool(contact), contact_reason=contact, foot_skate_mps=0.3, foot_flag=foot)


ROWS = [row(3, 0.5, 0.9), row(7, 1.5, 0.2, contact="interpenetrates"), row(9, 1.0, 0.6, foot=True)]


class Inputs(SimpleNamespace):
    @property
    def key(self):
        return (self.model_name, self.label)


@pytest.fixture
def panel():
    from trame.app import get_server

    from explorer.ui.panel_api import Page
    from explorer.ui.review_panel import ReviewPanel

    server = get_server("review-panel-test", client_type="vue3")
    session = SimpleNamespace(upload=None, index=3, label_text=lambda: "+1 hugging", model_title=lambda name: name)
    page = Page(session, server.state, server.controller, server.trigger, lambda fn: fn)
    opened: list[int] = []
    calls: list[tuple] = []
    mix = {"label": (1.0,)}

    def compute(inputs):
        calls.append((inputs.key, threading.current_thread().name))
        if isinstance(p.rows_out, Exception):
            raise p.rows_out
        return p.rows_out

    p = ReviewPanel(page, open_sequence=opened.append, compute_rows=compute,
                    inputs=lambda: Inputs(model=SimpleNamespace(settings={}), model_name="gan", label=mix["label"], seed=0))
    p.opened, p.server, p.rows_out, p.calls, p.mix = opened, server, list(ROWS), calls, mix
    return p


def run(coro):
    return asyncio.run(coro)


def test_the_panel_builds_a_drawer_with_a_sortable_table_and_clickable_rows(panel):
    from trame.ui.vuetify3 import VAppLayout

    from explorer.ui.review_panel import review_button, review_drawer

    with VAppLayout(panel.server) as layout:
        review_button()
        review_drawer()
    markup = layout.html
    assert "<VDataTable" in markup and ':itemsPerPage="-1"' in markup and "review_rows" in markup and "review_sort_by" in markup
    assert "trigger('review_open_row', [item.index])" in markup and "review-next-worst" in markup and "review_open" in markup


def test_nothing_is_computed_until_the_review_opens(panel):
    assert panel.calls == [] and panel.server.state.review_rows == []
    panel.follow()  # a new mix with the review closed and never computed: still nothing
    assert panel.calls == [] and panel.server.state.review_stale is False


def test_recompute_sorts_worst_first_off_the_event_loop_and_next_worst_walks_to_the_end(panel):
    state = panel.server.state
    run(panel.recompute())
    assert len(panel.calls) == 1 and panel.calls[0][1].startswith("imm-review")  # the worker thread, not the loop's
    assert [r["index"] for r in state.review_rows] == [7, 9, 3]
    assert state.review_rows[0]["feature_distance"] is None and state.review_rows[0]["flag_text"] == "interpenetrates"
    assert state.review_rows[0]["reads_as"] == "shaking hands" and state.review_busy is False
    state.review_current = None
    assert [panel.next_worst() for _ in range(3)] == [7, 9, 3]
    assert panel.opened == [7, 9, 3] and state.review_current == 3
    assert panel.next_worst() is None and "last row" in state.review_note and panel.opened == [7, 9, 3]
    panel.open(9)  # a clicked row, then the next one down
    assert panel.next_worst() == 3


def test_next_worst_follows_the_sort_column(panel):
    state = panel.server.state
    run(panel.recompute())
    state.review_current = None
    state.review_sort_by = [{"key": "asked_p", "order": "desc"}]
    assert panel.next_worst() == 7  # the lowest probability of the asked class is the worst
    assert state.review_sort_by == [{"key": "asked_p", "order": "asc"}]
    state.review_sort_by = [{"key": "sequence_id", "order": "asc"}]  # not a review column: AFD
    panel.server.state.review_current = None
    assert panel.next_worst() == 7


def test_a_new_mix_marks_a_closed_table_stale_and_the_current_row_follows_the_studio(panel):
    state = panel.server.state
    run(panel.recompute())
    panel.follow()
    assert state.review_stale is False and state.review_current == 3
    panel.mix["label"] = (0.5,)
    panel.page.session.index = 9
    panel.follow()  # closed: marked, not computed
    assert state.review_stale is True and state.review_current == 9 and len(panel.calls) == 1
    run(panel.recompute())
    assert state.review_stale is False and panel.calls[-1][0] == ("gan", (0.5,))


def test_an_open_review_recomputes_a_new_mix_once_debounced(panel):
    from explorer.ui import review_panel

    state = panel.server.state

    async def scenario():
        await panel.recompute()
        state.review_open = True
        for label in ((0.2,), (0.3,), (0.4,)):  # a slider dragged: three mixes in a row
            panel.mix["label"] = label
            panel.follow()
            await asyncio.sleep(0)  # the debounce task runs between the moves
        assert len(panel.calls) == 1  # still within the debounce
        await asyncio.wait_for(panel._task, review_panel.DEBOUNCE_S + 60)  # the debounced computation, once

    run(scenario())
    assert [c[0][1] for c in panel.calls] == [(1.0,), (0.4,)] and state.review_stale is False


def test_a_failing_computation_is_one_line(panel):
    from imm_model.errors import LabelError

    panel.rows_out = LabelError("the review's label has shape (2,); expected 6 values")
    run(panel.recompute())
    state = panel.server.state
    assert state.review_rows == [] and state.review_error.startswith("the review failed: the review's label")
    assert "\n" not in state.review_error and state.review_busy is False
    assert panel.next_worst() is None and state.review_note == "no table yet"
