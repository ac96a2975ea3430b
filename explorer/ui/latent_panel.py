"""The latent map beside the 3D view, as a Plotly figure (drawn in the page by static/latent_map.js): every
sequence's latent as a point (t-SNE or UMAP), the current sequence ringed, the current mix as a star that moves
with the sliders (placed on the fitted map, never refitted), hover for a sequence's id, class, subject pair, held
out and AFD, zoom, pan, box and lasso selection that lists the selected sequences, colour by class, AFD or held
out, and a click on a point that opens that sequence and plays it.

A method not fitted yet (UMAP until asked for; t-SNE too on a cold cache) is fitted in a separate process while
the page works, with a progress message (explorer/session/latent.py keeps one fit per method at a time, across the
studio's processes). The fit a page needs at its start waits for the page's first slider moves to rest, as the next
spare process does (explorer/serving/pool.py): it runs at the studio's priority and would share the cores with them.
The per-sequence AFDs are computed once, a sequence at a time between the page's own work once it is up, and cached.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from trame.app import asynchronous

from explorer.rendering.palette import SYNTHESIZED, class_color, display_name
from explorer.session.latent import METHODS, LatentMap
from explorer.session.words import one_line

if TYPE_CHECKING:
    from explorer.ui.panel_api import Page

SORT_KEYS = ("afd", "id", "class")
AFD_DELAY_S = 2.0  # the per-sequence AFDs wait this long after the page opens: its first picture goes first
AFD_STEP_S = 0.01  # ... and, scored in the studio process (no cache file), yield this long after each sequence
# The map's fit at a page's start (a cold cache) begins FIT_DELAY_S after the page opens, once no follower has been
# drawn for FIT_QUIET_S, and at the latest FIT_LATEST_S after it opens (a page that plays or steers on never rests)
FIT_DELAY_S = 2.0
FIT_QUIET_S = 1.0
FIT_LATEST_S = 20.0


class LatentPanel:
    def __init__(self, page: Page, latent: LatentMap, *, open_sequence: Callable[[int], None]):
        """`open_sequence(index)` opens a sequence as the picker does."""
        self.page = page
        self.latent = latent
        self.open_sequence = open_sequence
        self._drawn = ""  # the method whose points the page holds
        self._last_redraw = 0.0  # time.monotonic() of the last follower drawn (redraw is called after each)
        self._fitting: set[str] = set()  # methods being fitted (explorer/session/latent.py fit_elsewhere)
        page.state.update({
            "latent_points": None,  # the figure's points (static/latent_map.js draws them)
            "latent_marks": {"ring": None, "star": None},  # the current sequence and mix, map coordinates
            "latent_color": "class",
            "latent_colors": {"classes": [class_color(i) for i in range(len(page.session.class_names))],
                              "star": SYNTHESIZED},
            "latent_selection": [],  # indices the page's box or lasso selected
            "latent_rows": [],  # ... as rows of the list under the map
            "latent_sort": "afd",
        })  # fmt: skip
        page.state.change("projection")(self.on_projection_change)
        page.state.change("latent_selection", "latent_sort")(self.on_selection_change)
        page.ctrl.pick_latent_point = page.guarded(self.pick_point)
        page.ctrl.open_listed = page.guarded(self.open_listed)
        page.trigger("latent_pick")(page.guarded(self.pick_point))
        page.ctrl.on_server_ready.add(lambda **_: self.open_map(page.state.projection or "tsne"))
        page.ctrl.on_server_ready.add(lambda **_: asynchronous.create_task(self._score()))

    def points(self, method: str) -> dict:
        """What the figure plots for `method`: coordinates and each point's hover readout."""
        d, names = self.page.session.data, self.page.session.class_names
        xy = self.latent.coords[method]
        afd = self.latent.afd
        return {
            "method": method,
            "x": [round(float(v), 3) for v in xy[:, 0]],
            "y": [round(float(v), 3) for v in xy[:, 1]],
            "id": list(d.sequence_ids),
            "cls": [int(c) for c in d.actions],
            "class_names": [display_name(n) for n in names],
            "pair": list(d.subject_pairs),
            "held": [bool(h) for h in d.held_out],
            "afd": None if afd is None else [round(float(v), 3) for v in afd],
        }

    def redraw(self) -> None:
        """The map for the chosen method (nothing while that method is still being fitted). Its points are sent
        when the method changes; after that only the current sequence's ring and the mix's star move."""
        s, ses = self.page.state, self.page.session
        self._last_redraw = time.monotonic()
        method = s.projection or "tsne"
        if not self.latent.has(method):
            return
        coords = self.latent.coords[method]
        if self._drawn != method:
            s.latent_points = self.points(method)
            self._drawn = method
        star = self.latent.place(ses.mix_latent(), method)
        s.latent_marks = {
            "ring": None if ses.upload else [float(v) for v in coords[ses.index]],  # an upload has no point
            "star": None if star is None else [float(v) for v in star],
        }

    def open_map(self, projection: str) -> None:
        """The page has opened: its map, fitted once its first slider moves have rested when the cache lacks it."""
        self.on_projection_change(projection, after_rest=True)

    def on_projection_change(self, projection, after_rest: bool = False, **_):
        if projection not in METHODS:
            return
        if self.latent.has(projection):
            self.redraw()
            return
        self.page.state.projection_busy = True
        if projection not in self._fitting:
            self._fitting.add(projection)
            asynchronous.create_task(self._fit(projection, after_rest))

    async def _rest(self) -> None:
        """Returns FIT_DELAY_S from now once no follower has been drawn for FIT_QUIET_S, or FIT_LATEST_S from now."""
        start = time.monotonic()
        while (now := time.monotonic()) < start + FIT_LATEST_S:
            due = max(start + FIT_DELAY_S, self._last_redraw + FIT_QUIET_S)
            if now >= due:
                return
            await asyncio.sleep(min(due, start + FIT_LATEST_S) - now)

    async def _fit(self, method: str, after_rest: bool = False):
        state = self.page.state
        try:
            if after_rest:
                await self._rest()
            await self.latent.fit_elsewhere(method)
        except Exception as err:
            with state:
                state.error = f"{method} projection failed: {one_line(err)}"
                state.projection = "tsne"
        finally:
            self._fitting.discard(method)
        with state:
            state.projection_busy = bool(self._fitting)
            self.redraw()

    async def _score(self):
        """Every sequence's AFD for the hover and the AFD colouring (cached: later processes find it at once)."""
        if self.latent.afd is not None:
            return
        await asyncio.sleep(AFD_DELAY_S)
        ses = self.page.session
        try:  # the map is of this model, whichever is on; scored in a process of its own, below the page's priority
            await self.latent.score_elsewhere(ses.map_model, ses.data, AFD_STEP_S)
        except Exception as err:
            with self.page.state:
                self.page.state.error = f"AFD of the sequences failed: {one_line(err)}"
            return
        with self.page.state:
            self._drawn = ""  # resend the points, now with their AFDs
            self.redraw()
            self.on_selection_change()

    def rows(self, indices, sort: str) -> list[dict]:
        """The listed sequences: id, class, subject pair, held out, AFD; the worst AFD first, or by id or class."""
        d, names, afd = self.page.session.data, self.page.session.class_names, self.latent.afd
        rows = [{"i": i, "id": d.sequence_ids[i], "cls": display_name(names[int(d.actions[i])]),
                 "color": class_color(int(d.actions[i])), "held": bool(d.held_out[i]),
                 "afd": None if afd is None else round(float(afd[i]), 3)}
                for i in sorted({int(i) for i in indices if 0 <= int(i) < len(d)})]  # fmt: skip
        if sort == "afd" and afd is not None:
            rows.sort(key=lambda r: -r["afd"])
        elif sort == "class":
            rows.sort(key=lambda r: (r["cls"], r["id"]))
        else:
            rows.sort(key=lambda r: r["id"])
        return rows

    def on_selection_change(self, **_):
        s = self.page.state
        sort = s.latent_sort if s.latent_sort in SORT_KEYS else "afd"
        s.latent_rows = self.rows(s.latent_selection or [], sort)

    def pick_point(self, index) -> None:
        """A click on a point: open that sequence, with the filters cleared so that it is in the list, and play it."""
        if index is None:
            return
        self.open(int(index[0] if isinstance(index, list | tuple) else index))
        self.page.state.playing = True

    def open_listed(self, index) -> None:
        """A row of the selection list: open that sequence and play it, as a click on its point does."""
        self.open(int(index))
        self.page.state.playing = True

    def open(self, index: int) -> None:
        state = self.page.state
        with state:
            state.class_filter = ""
            state.pair_filter = ""
            state.held_filter = "all"
        self.open_sequence(index)
