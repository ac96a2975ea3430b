"""The review panel (explorer/review_panel.py) on a bare trame server: its widgets build, its controllers compute,
sort, step and open rows. No browser."""

from __future__ import annotations

import pytest

from imm_model.evaluation.review import ReviewRow


def row(index: int, afd: float, asked_p: float = 0.5, contact: str = "", foot: bool = False) -> ReviewRow:
    return ReviewRow(index=index, sequence_id=f"s/{index}", class_name="hugging", subject_pair="s01s04", frames=20,
                     afd=afd, feature_distance=float("nan"), reads_as="hugging", reads_as_p=0.9, asked_p=asked_p,
                     interpenetration=0.0, real_interpenetration=0.0, closest_m=0.1, real_closest_m=0.1,
                     contact_flag=bool(contact), contact_reason=contact, foot_skate_mps=0.3, foot_flag=foot)


ROWS = [row(3, 0.5, 0.9), row(7, 1.5, 0.2, contact="interpenetrates"), row(9, 1.0, 0.6, foot=True)]


@pytest.fixture
def panel():
    from trame.app import get_server

    from explorer.review_panel import ReviewPanel, ReviewSource

    server = get_server("review-panel-test", client_type="vue3")
    opened: list[int] = []
    rows = list(ROWS)
    source = ReviewSource(server.state, server.controller, compute_rows=lambda: rows, open_sequence=opened.append,
                          trigger=server.trigger)
    p = ReviewPanel(source)
    p.opened, p.server, p.rows_out = opened, server, rows
    return p


def test_the_panel_builds_a_sortable_table_with_clickable_rows(panel):
    from trame.ui.vuetify3 import SinglePageLayout

    with SinglePageLayout(panel.server) as layout, layout.content:
        panel.ui()
    markup = layout.html
    assert "<VDataTable" in markup and ':itemsPerPage="-1"' in markup and "review_rows" in markup and "review_sort_by" in markup
    assert "trigger('review_open_row', [item.index])" in markup and "review-next-worst" in markup


def test_refresh_sorts_worst_first_and_next_worst_walks_to_the_end(panel):
    state = panel.server.state
    panel.refresh()
    assert [r["index"] for r in state.review_rows] == [7, 9, 3]
    assert state.review_rows[0]["feature_distance"] is None and state.review_rows[0]["flag_text"] == "interpenetrates"
    assert [panel.next_worst() for _ in range(3)] == [7, 9, 3]
    assert panel.opened == [7, 9, 3] and state.review_current == 3
    assert panel.next_worst() is None and "last row" in state.review_note and panel.opened == [7, 9, 3]
    panel.open(9)  # a clicked row, then the next one down
    assert panel.next_worst() == 3


def test_next_worst_follows_the_sort_column(panel):
    state = panel.server.state
    panel.refresh()
    state.review_sort_by = [{"key": "asked_p", "order": "desc"}]
    assert panel.next_worst() == 7  # the lowest probability of the asked class is the worst
    assert state.review_sort_by == [{"key": "asked_p", "order": "asc"}]
    state.review_sort_by = [{"key": "sequence_id", "order": "asc"}]  # not a review column: AFD
    panel.set_current(None)
    assert panel.next_worst() == 7


def test_a_failing_computation_is_one_line(panel):
    from imm_model.errors import LabelError

    def fail():
        raise LabelError("the review's label has shape (2,); expected 6 values")

    panel.source.compute_rows = fail
    panel.refresh()
    assert panel.server.state.review_rows == [] and panel.server.state.review_note.startswith("the review's label")
    assert panel.next_worst() is None and panel.server.state.review_note == "compute the table first"
