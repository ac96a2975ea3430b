"""The latent map beside the 3D view: every sequence's latent as a point (t-SNE or UMAP), the current mix as a
star, and a click on a point that opens that sequence. A method not fitted yet (UMAP until asked for; t-SNE too on
a cold cache) is fitted in a separate process while the page works, with a progress message (explorer/latent.py
keeps one fit per method at a time, across the studio's processes)."""

from __future__ import annotations

from trame.app import asynchronous

from explorer import charts
from explorer.exports import one_line
from explorer.latent import METHODS, LatentMap


class LatentPanel:
    def __init__(self, studio, latent: LatentMap):
        self.studio = studio
        self.latent = latent
        self._drawn = ""  # the method whose points the page holds
        self._fitting: set[str] = set()  # methods being fitted (explorer/latent.py fit_elsewhere)
        studio.state.change("projection")(self.on_projection_change)
        studio.ctrl.pick_latent_point = studio.guarded(self.pick_point)
        studio.ctrl.on_server_ready.add(lambda **_: self.on_projection_change(studio.state.projection or "tsne"))

    def redraw(self) -> None:
        """The map for the chosen method (nothing while that method is still being fitted). Its points are sent
        when the method changes; after that only the current sequence's ring and the mix's star move."""
        s, ses, d = self.studio.state, self.studio.session, self.studio.session.data
        method = s.projection or "tsne"
        if not self.latent.has(method):
            return
        coords = self.latent.coords[method]
        if self._drawn != method:
            s.latent_chart = charts.latent_chart(coords, d.actions, d.held_out, d.sequence_ids, ses.class_names, method)
            self._drawn = method
        star = self.latent.place(ses.mix_latent(), method)
        s.latent_marks = {
            "ring": None if ses.upload else charts.map_position(coords, coords[ses.index]),  # an upload has no point
            "star": None if star is None else charts.map_position(coords, star),
        }

    def on_projection_change(self, projection, **_):
        if projection not in METHODS:
            return
        if self.latent.has(projection):
            self.redraw()
            return
        self.studio.state.projection_busy = True
        if projection not in self._fitting:
            self._fitting.add(projection)
            asynchronous.create_task(self._fit(projection))

    async def _fit(self, method: str):
        state = self.studio.state
        try:
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

    def pick_point(self, index) -> None:
        """A click on a point: open that sequence, with the filters cleared so that it is in the list."""
        if index is None:
            return
        index = int(index[0] if isinstance(index, list | tuple) else index)
        state = self.studio.state
        with state:
            state.class_filter = ""
            state.pair_filter = ""
            state.held_filter = "all"
        self.studio.load_sequence(index)
