"""The review panel (explorer/ui/review_panel.py) on a bare trame server with a stand-in Page: its widgets build, its
computation runs off the event loop, only when asked, and fills the table in as it goes, every model in columns of its
own; it sorts, steps, opens and plays rows, sums up each class, and follows what it is computed from. No browser
(tests/test_studio_review.py drives it in the studio)."""

from __future__ import annotations

import asyncio
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from imm_model.evaluation.review import ReviewRow
from imm_model.families.base import SamplerSettings

ACTIONS = {3: 0, 7: 1, 9: 1}  # dataset index -> class


def row(index: int, afd: float, asked_p: float = 0.5, contact: str = "", foot: bool = False) -> ReviewRow:
    return ReviewRow(index=index, sequence_id=f"s/{index}", class_name="hugging", subject_pair="s01s04", frames=20,
                     afd=afd, feature_distance=float("nan"), reads_as="shaking_hands", reads_as_p=0.9, asked_p=asked_p,
                     interpenetration=0.0, real_interpenetration=0.0, closest_m=0.1, real_closest_m=0.1,
                     contact_flag=bool(contact), contact_reason=contact, foot_skate_mps=0.3, foot_flag=foot)


ROWS = {"gan": [row(3, 0.5, 0.9), row(7, 1.5, 0.2, contact="interpenetrates"), row(9, 1.0, 0.6, foot=True)],
        "diffusion": [row(3, 2.0, 0.1), row(7, 0.4, 0.8), row(9, 0.7, 0.5)]}


class Compute:
    """A stand-in for StudioCompute: the rows above, noting each call and its thread."""

    def __init__(self):
        self.calls: list[tuple] = []
        self.fail: Exception | None = None

    def rows(self, inputs, model, indices):
        self.calls.append(("rows", model, tuple(indices), inputs.key, threading.current_thread().name))
        if self.fail:
            raise self.fail
        by_index = {r.index: r for r in ROWS[model]}
        return [by_index[i] for i in indices], [np.zeros((2, 15, 3)) for _ in indices]

    def feature_distances(self, inputs, indices, followers):
        self.calls.append(("features", tuple(indices)))
        return np.arange(len(indices), dtype=float) + 0.5


class StandIn(str):
    """A model as the panel sees it: a name the stand-in computation knows, and the sampler settings it takes."""

    settings: SamplerSettings = SamplerSettings()


class SeededStandIn(StandIn):
    settings = SamplerSettings(seed=True)


class Inputs(SimpleNamespace):
    @property
    def key(self):
        return (self.labels, self.mix if self.labels == "mix" else None, self.split)


@pytest.fixture
def panel():
    from trame.app import get_server

    from explorer.ui.panel_api import Page
    from explorer.ui.review_panel import ReviewPanel

    server = get_server("review-panel-test", client_type="vue3")
    data = SimpleNamespace(actions=np.array([0, 0, 0, 0, 0, 0, 0, 1, 0, 1]), class_names=("hugging", "kicking"))
    models = {"gan": StandIn("gan"), "diffusion": SeededStandIn("diffusion")}
    titles = {"gan": "the paper's GAN", "diffusion": "the diffusion model"}
    session = SimpleNamespace(upload=None, index=3, label_text=lambda: "+1 hugging", data=data, models=models,
                              model_title=lambda name=None: titles[name])
    page = Page(session, server.state, server.controller, server.trigger, lambda fn: fn)
    opened: list[tuple[int, bool]] = []
    compute = Compute()
    choice = {"mix": (1.0,)}

    def inputs(labels, split):
        return Inputs(models=tuple(models.items()), labels=labels, split=split, mix=choice["mix"],
                      indices=(3, 7, 9), subject="s04", seed=0)

    p = ReviewPanel(page, open_sequence=lambda i, keep: opened.append((i, keep)), compute=compute, inputs=inputs)
    p.opened, p.server, p.compute_stub, p.choice = opened, server, compute, choice
    return p


def run(coro):
    return asyncio.run(coro)


def test_the_panel_builds_a_table_with_a_column_group_per_model_and_clickable_rows(panel):
    from trame.ui.vuetify3 import VAppLayout

    from explorer.ui.review_panel import review_button, review_overlay

    with VAppLayout(panel.server) as layout:
        review_button()
        review_overlay(2)
    markup = layout.html
    assert "<VDataTable" in markup and ':itemsPerPage="-1"' in markup and "review_rows" in markup and "review_sort_by" in markup
    assert "trigger('review_open_row', [item.index])" in markup and "review-next-worst" in markup and "item.m1.afd" in markup
    headers = panel.server.state.review_headers
    assert [h["title"] for h in headers[2:]] == ["the paper's GAN", "the diffusion model"]
    assert [c["key"] for c in headers[3]["children"]] == ["m1.afd", "m1.feature_distance", "m1.asked_p", "m1.flags"]


def test_nothing_is_computed_until_the_review_opens(panel):
    assert panel.compute_stub.calls == [] and panel.server.state.review_rows == []
    panel.follow()  # a new mix with the review closed and never computed: still nothing
    assert panel.compute_stub.calls == [] and panel.server.state.review_stale is False


def test_every_model_fills_its_columns_off_the_event_loop_then_the_feature_distances(panel):
    state = panel.server.state
    run(panel.recompute())
    rows_calls = [c for c in panel.compute_stub.calls if c[0] == "rows"]
    assert [c[1] for c in rows_calls] == ["gan", "diffusion"] and all(c[4].startswith("imm-review") for c in rows_calls)
    assert rows_calls[0][3][0] == "match"  # each row under its own class by default
    assert [c for c in panel.compute_stub.calls if c[0] == "features"] == [("features", (3, 7, 9))] * 2
    by_index = {r["index"]: r for r in state.review_rows}
    assert by_index[7]["m0"]["afd"] == 1.5 and by_index[7]["m1"]["afd"] == 0.4
    assert by_index[7]["m0"]["flag_text"] == "interpenetrates" and by_index[9]["m0"]["flag_text"] == "foot skate"
    assert by_index[3]["m0"]["reads_as"] == "shaking hands" and by_index[7]["m1"]["feature_distance"] == 1.5
    assert state.review_busy is False and state.review_stale is False and "held-out" in state.review_under


def test_next_worst_walks_the_sorted_models_column_and_a_row_plays(panel):
    state = panel.server.state
    run(panel.recompute())
    state.review_current = None
    assert [panel.next_worst() for _ in range(3)] == [7, 9, 3]  # the GAN's AFD, worst first
    assert panel.opened == [(7, False), (9, False), (3, False)] and state.playing is True
    assert panel.next_worst() is None and "last row" in state.review_note
    state.review_current = None
    state.review_sort_by = [{"key": "m1.afd", "order": "asc"}]  # the diffusion model's column
    assert panel.next_worst() == 3 and state.review_sort_by == [{"key": "m1.afd", "order": "desc"}]
    state.review_sort_by = [{"key": "m1.asked_p", "order": "desc"}]
    state.review_current = None
    assert panel.next_worst() == 3  # the lowest probability of the asked class is the worst
    assert state.review_sort_by == [{"key": "m1.asked_p", "order": "asc"}]


def test_per_class_rows_sum_up_each_class_and_open_its_worst_sequence(panel):
    state = panel.server.state
    run(panel.recompute())
    state.review_per = "class"
    panel.publish()
    summary = {r["class_name"]: r for r in state.review_rows}
    assert set(summary) == {"hugging", "kicking", "all classes"}
    assert summary["kicking"]["m0"]["afd"] == pytest.approx(1.25) and summary["kicking"]["m0"]["flags"] == 2
    assert summary["all classes"]["m1"]["afd"] == pytest.approx((2.0 + 0.4 + 0.7) / 3, abs=1e-4)
    panel.open(summary["kicking"]["index"])
    assert panel.opened[-1] == (7, False)  # kicking's worst by the GAN's AFD


def test_the_mix_choice_recomputes_and_a_row_keeps_the_mix(panel):
    state = panel.server.state
    run(panel.recompute())
    panel.follow()
    panel.choice["mix"] = (0.5,)
    panel.follow()  # "match": the mix does not matter
    assert state.review_stale is False
    state.review_labels = "mix"
    panel.on_choice_change()  # closed: marked, not computed
    assert state.review_stale is True
    run(panel.recompute())
    assert [c for c in panel.compute_stub.calls if c[0] == "rows"][-1][3][:2] == ("mix", (0.5,))
    panel.open(9)
    assert panel.opened[-1] == (9, True)


def test_an_open_review_recomputes_a_new_mix_once_debounced(panel):
    from explorer.ui import review_panel

    state = panel.server.state
    state.review_labels = "mix"

    async def scenario():
        await panel.recompute()
        state.review_open = True
        for mix in ((0.2,), (0.3,), (0.4,)):  # a slider dragged: three mixes in a row
            panel.choice["mix"] = mix
            panel.follow()
            await asyncio.sleep(0.01)
        assert len([c for c in panel.compute_stub.calls if c[0] == "rows"]) == 2  # still within the debounce
        await asyncio.wait_for(panel._task, review_panel.DEBOUNCE_S + 60)  # the debounced computation, once

    run(scenario())
    mixes = [c[3][1] for c in panel.compute_stub.calls if c[0] == "rows"]
    assert mixes == [(1.0,), (1.0,), (0.4,), (0.4,)] and state.review_stale is False


def test_a_failing_computation_is_one_line(panel):
    from imm_model.errors import LabelError

    panel.compute_stub.fail = LabelError("the review's label has shape (2,); expected 6 values")
    run(panel.recompute())
    state = panel.server.state
    assert state.review_rows == [] and state.review_error.startswith("the review failed: the review's label")
    assert "\n" not in state.review_error and state.review_busy is False
    assert panel.next_worst() is None and state.review_note == "no table yet"
