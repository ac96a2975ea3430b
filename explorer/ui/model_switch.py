"""The model switch (the paper's GAN / the diffusion model) and, for a model that takes a seed, its variations: the seed, a
"new variation" button, N followers drawn at once (seeds seed .. seed + N - 1) side by side, each captioned with
its seed, and, for a model trained with noised leaders, the spread (how loosely the reaction follows the leader);
and "compare with": other models' followers drawn beside the current one's, each captioned with its model; and the
variations gallery (VariationGallery), a dialog of GALLERY_SEEDS seeds' reactions as still pictures, one click from
opening one. The session (explorer/session/session.py) holds the models and draws the followers; this maps them onto
the page.

A diffusion reaction costs ~10x the GAN's (benchmarks/explorer_latency.py): slider moves are coalesced as for any
model (app.py, the latest mix wins), a slider's further variations are drawn after its first picture, with the
review panels, and a "computing" mark shows while it works (the page sets it at once for a click here; the server
around a slider's synthesis).
"""

from __future__ import annotations

import asyncio
import base64
from collections.abc import Callable
from typing import TYPE_CHECKING

from trame.app import asynchronous
from trame.widgets import client, html
from trame.widgets import vuetify3 as v3

from explorer.rendering.pictures import THUMBNAIL_SIZE, Thumbnails
from explorer.session.gallery import GALLERY_SEEDS, gallery_seeds, variation
from explorer.session.session import Session
from explorer.session.side_by_side import MAX_COMPARED, MAX_VARIATIONS
from explorer.session.words import one_line

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.ui.panel_api import Page

# The "computing" mark fades in only after 0.15 s: a reaction drawn sooner never makes the page blink.
COMPUTING_CSS = """
.imm-computing { animation: imm-computing-in 0s linear 0.15s both; }
@keyframes imm-computing-in { from { visibility: hidden; } to { visibility: visible; } }
"""


class ModelSwitch:
    def __init__(self, page: Page, scene: Scene, *, show_review: Callable[[], bool]):
        """`show_review()` writes the review panels' state for the current follower and says whether the view's
        contact limbs changed (the view then needs one more picture)."""
        self.page, self.scene, self.show_review = page, scene, show_review
        ses = page.session
        page.state.update({
            "model_name": ses.model_name,
            "model_items": [{"title": ses.model_title(name), "value": name} for name in ses.models],
            "model_title": ses.model_title(),
            "seeded": ses.seeded,
            "seed": ses.seed,
            "spread": ses.spread or 0.0,  # the mix's handler (app.py) applies it, as a slider of the mix
            "spread_available": ses.spread is not None,
            "variation_count": ses.side_by_side.count,
            "computing": False,  # a reaction is being drawn (COMPUTING_CSS)
            "variation_asked": 0,  # "new variation" presses
            "compare_models": list(ses.side_by_side.compared),  # other models drawn beside the current one ("compare with")
            "view_captions": [],  # the captions the view shows (side by side), left to right
        })  # fmt: skip
        page.state.change("model_name")(self._settled(self.on_model_picked))
        page.state.change("seed")(self._settled(self.on_seed_typed))
        page.state.change("variation_count")(self._settled(self.on_count_picked))
        # a state change, not a trigger: it reaches the server with the page's `computing`, which a trigger could overtake
        page.state.change("variation_asked")(self._settled(self.on_variation_asked))
        page.state.change("compare_models")(self._settled(self.on_compare_picked))
        self._asked = 0
        self.gallery = VariationGallery(page, scene)

    @property
    def state(self):
        return self.page.state

    def _settled(self, handler):
        """`handler` with its errors in the page's alert (page.guarded) and `computing` off after it, whatever it did."""
        guarded = self.page.guarded(handler)

        def call(*args, **kwargs):
            try:
                return guarded(*args, **kwargs)
            finally:
                self.settle()

        return call

    # ---- the page's controls ----------------------------------------------------------------
    def on_model_picked(self, model_name, **_):
        ses = self.page.session
        if model_name == ses.model_name:
            return
        try:
            ses.set_model(str(model_name))
        finally:
            self.state.model_name = ses.model_name  # a refused name leaves the switch where the session is
        self.refresh()

    def on_seed_typed(self, seed, **_):
        """The seed field: an integer in range draws that variation; anything else is named in the page's alert."""
        ses = self.page.session
        text = str(seed).strip() if seed is not None else ""
        if not text or text == str(ses.seed):
            return
        try:
            try:
                value = int(text)
            except ValueError:
                raise ValueError(f"seed {text[:20]!r} is not a whole number") from None
            ses.set_seed(value)
        except Exception:
            self.state.seed = ses.seed  # a refused seed leaves the field and the chip on the seed drawn
            raise
        self.refresh()

    def on_variation_asked(self, variation_asked, **_):
        asked = int(variation_asked or 0)
        if asked == self._asked:  # the page's first state, not a press
            return
        self._asked = asked
        self.new_variation()

    def new_variation(self):
        ses = self.page.session
        ses.new_variation()
        self.state.seed = ses.seed  # the field shows it; its change handler finds the session there already
        self.refresh()

    def on_count_picked(self, variation_count, **_):
        """N variations: drawn side by side (the overlay would put them on top of each other)."""
        ses = self.page.session
        n = int(variation_count or 1)
        if n == ses.side_by_side.count:
            return
        ses.side_by_side.set_count(n)
        if n > 1 and self.state.scene_layout != "side_by_side":
            self.state.scene_layout = "side_by_side"
        self.refresh()

    def on_compare_picked(self, compare_models, **_):
        """Other models to draw beside the current one: side by side (the overlay would put them on top of each other)."""
        ses = self.page.session
        names = [str(n) for n in compare_models or []]
        if tuple(n for n in ses.models if n in names) == ses.side_by_side.compared:
            return
        try:
            ses.side_by_side.set_compared(names)
        finally:
            self.state.compare_models = list(ses.side_by_side.compared)  # a refused choice leaves the buttons where the session is
        if ses.side_by_side.compared_names and self.state.scene_layout != "side_by_side":
            self.state.scene_layout = "side_by_side"
        self.refresh()

    # ---- what the studio calls ----------------------------------------------------------------
    def show_variations(self) -> None:
        """The session's followers beyond the first into the scene (after any re-synthesis): the seeded model's
        variations and the compared models' followers, each captioned."""
        ses = self.page.session
        others = [n for n in ses.side_by_side.compared_names if n in ses.side_by_side.compared_followers]
        self.scene.set_variations(ses.side_by_side.variations, ses.side_by_side.seeds() if ses.seeded else None,
                                  ses.model_title() if others else "")
        self.scene.set_compared([(ses.side_by_side.caption(n), ses.side_by_side.compared_followers[n]) for n in others])
        self.state.view_captions = self.scene.captions_shown()

    def draw_variations(self) -> None:
        """The side-by-side variations of a slider's mix, drawn after its first picture (they cost a reaction each)."""
        ses = self.page.session
        if ses.side_by_side.due:
            ses.side_by_side.draw()
            self.show_variations()
            self.page.ctrl.view_update()

    def refresh(self) -> None:
        """The followers after a switch, a seed or a count: the view, the pin's words, the review panels."""
        page, ses, s = self.page, self.page.session, self.state
        self.scene.set_synthesized(ses.synth)
        self.scene.set_pinned(ses.pinned.follower)
        self.show_variations()
        page.ctrl.view_update()  # the picture first, as after a slider; the panels follow it
        with s:
            s.model_title = ses.model_title()
            s.seeded = ses.seeded
            s.seed, s.variation_count = ses.seed, ses.side_by_side.count
            s.spread_available = ses.spread is not None
            if ses.spread is not None:
                s.spread = ses.spread
            s.pinned_text = ses.pinned.text()
            contact_changed = self.show_review()
            s.error = ""
            s.computing = False
        if contact_changed:  # the new follower's orange limbs
            page.ctrl.view_update()

    async def announce(self) -> None:
        """Before a seeded model's synthesis from a slider: the page learns it is computing (sent first)."""
        if self.page.session.seeded:
            with self.state:
                self.state.computing = True
            await asyncio.sleep(0)

    def settle(self) -> None:
        if self.state.computing:
            with self.state:
                self.state.computing = False


class VariationGallery:
    """The gallery of a seeded model's variations: GALLERY_SEEDS seeds from the seed drawn when it opened, each the
    leader and its follower at the frame where they come closest, captioned with its seed and what the judge reads it
    as. Drawn while open, again after each new follower (`mix_count`), one seed at a time after the view's picture:
    a reaction costs the diffusion model ~20 ms, and a slider's message and picture go between two."""

    def __init__(self, page: Page, scene: Scene):
        self.page, self.scene = page, scene
        self.first = 0  # the gallery's first seed
        self._task: asyncio.Task | None = None
        self._thumbnails: Thumbnails | None = None  # a plotter of its own, made at the first opening
        page.state.update({"gallery_open": False, "gallery_items": [], "gallery_note": ""})
        page.state.change("gallery_open")(page.guarded(self.on_gallery_toggled))
        page.state.change("mix_count")(page.guarded(self.on_follower_changed))

    def on_gallery_toggled(self, gallery_open, **_):
        if gallery_open:
            self.first = self.page.session.seed
            self.redraw()
        elif self._task is not None:
            self._task.cancel()

    def on_follower_changed(self, **_):
        if self.page.state.gallery_open:
            self.redraw()

    def redraw(self) -> None:
        """Empty frames captioned with their seeds at once, their pictures as they are drawn."""
        if self._task is not None:
            self._task.cancel()
        ses, s = self.page.session, self.page.state
        if not ses.seeded:  # the dialog opens from the variation controls, which such a model has not
            s.gallery_items, s.gallery_note = [], f"{ses.model_title()} draws one reaction per mix: no seeds to show"
            return
        seeds = gallery_seeds(self.first)
        s.gallery_items = [{"seed": seed, "src": "", "caption": f"seed {seed}"} for seed in seeds]
        s.gallery_note = f"{ses.model_title()}, seeds {seeds[0]} to {seeds[-1]}: a click opens one"
        self._task = asynchronous.create_task(self._draw(seeds))

    async def _draw(self, seeds: list[int]) -> None:
        ses, s = self.page.session, self.page.state
        if self._thumbnails is None:
            self._thumbnails = Thumbnails(self.scene.skeleton)
        for i, seed in enumerate(seeds):
            await asyncio.sleep(0)  # the view's picture, and what the page sent meanwhile, go first
            try:
                drawn = variation(ses, seed)
                jpeg = self._thumbnails.jpeg(ses.leader[drawn.frame], drawn.follower[drawn.frame])
            except Exception as err:  # the gallery stops where it failed; the page goes on
                with s:
                    s.gallery_note = f"seed {seed}: {one_line(err)}"
                return
            items = list(s.gallery_items)
            items[i] = {"seed": seed, "caption": drawn.caption,
                        "src": "data:image/jpeg;base64," + base64.b64encode(jpeg).decode("ascii")}
            with s:
                s.gallery_items = items


def gallery_dialog() -> None:
    """The variations gallery over the page: two rows of pictures at 1366x768; a click opens that seed in the view."""
    width, height = THUMBNAIL_SIZE
    with v3.VDialog(v_model=("gallery_open",), max_width=4 * (width + 16) + 48, scrollable=True):
        with v3.VCard(title="Variations", subtitle=("gallery_note",), id="gallery"):
            with v3.VCardText(classes="d-flex flex-wrap", style="gap: 12px"):
                with html.Div(v_for="(item, i) in gallery_items", key=("item.seed",), classes="gallery-item rounded border",
                              style=f"width: {width + 4}px; cursor: pointer", title="open this seed in the view",
                              click="if (String(item.seed) !== String(seed)) { computing = true; seed = item.seed; } "
                                    "gallery_open = false"):
                    html.Img(v_if="item.src", src=("item.src",), width=width, height=height, classes="d-block")
                    with html.Div(v_else=True, classes="d-flex align-center justify-center", style=f"height: {height}px"):
                        v3.VProgressCircular(indeterminate=True, size=20, width=2)
                    html.Div("{{ item.caption }}", classes="text-caption px-1", style="line-height: 16px")
            with v3.VCardActions():
                v3.VSpacer()
                v3.VBtn("close", variant="text", click="gallery_open = false", id="gallery-close")


def model_chip() -> None:
    """The status chip: which model draws the follower (and, for a seeded one, with which seed)."""
    with v3.VChip(size="small", variant="flat", color="indigo-lighten-4", classes="mr-2", id="model-chip"):
        html.Span("{{ model_title }}{{ seeded ? ' · seed ' + seed : '' }}")
        v3.VProgressCircular(v_show="computing", indeterminate=True, size=12, width=2, classes="ml-1 imm-computing",
                             id="computing")
    client.Style(COMPUTING_CSS)


def model_panel(session: Session) -> None:
    """The model switch above the label sliders, "compare with" under it, and the variation controls for a seeded
    model."""
    if len(session.models) > 1:
        html.Div("Model", classes="text-overline")
        # A click sets the choice and `computing` together, so that both reach the server in one message (with
        # v_model the choice could overtake `computing`, which would then stay on).
        with v3.VBtnToggle(model_value=("model_name",), density="compact", mandatory=True, variant="outlined", divided=True,
                           classes="mb-2", id="model-switch"):
            # each by the name `imm explore --model` gave it (short enough for three in the drawer), its title on hover
            for name in session.models:
                # a model without part labels is marked before the click while the mix sets parts apart (it would refuse)
                parts = session.models[name].part_labels
                v3.VBtn(name, value=name, size="x-small", id=f"model-{name}",
                        disabled=False if parts else ("parts_apart",),
                        title=session.model_title(name) if parts else
                        (f"parts_apart ? {_js(session.model_title(name) + ' takes no label per body part: link the parts first')}"
                         f" : {_js(session.model_title(name))}",),
                        click=f"if (model_name !== '{name}') {{ computing = true; model_name = '{name}'; }}")
        # other models' followers beside the current one's (the current model's chip is off: it is drawn already); chips
        # wrap in the drawer's width, where a button row would scroll its ends out of sight
        with html.Div(classes="mb-2", id="compare-row",
                      title="draw these models' followers beside the current one's, for the same leader, mix and seed"):
            html.Div("compare with", classes="text-body-2")
            with v3.VChipGroup(model_value=("compare_models",), multiple=True, max=MAX_COMPARED, column=True,
                               selected_class="text-teal-darken-2", id="compare-models",
                               update_modelValue="computing = true; compare_models = $event"):
                for name in session.models:
                    parts = session.models[name].part_labels
                    v3.VChip(session.model_title(name), value=name, size="small", filter=True, variant="outlined",
                             id=f"compare-{name}",
                             disabled=(f"model_name === '{name}'" + ("" if parts else " || parts_apart"),))
    with html.Div(v_if="seeded", classes="mb-2", id="variation-controls"):
        with html.Div(classes="d-flex align-center mb-1", style="gap: 6px"):
            v3.VTextField(v_model=("seed",), label="seed", type="number", min=0, density="compact", hide_details=True,
                          style="max-width: 96px", id="seed-field",
                          title="the same seed with a moved slider moves the reaction smoothly")
            v3.VBtn("new variation", size="x-small", variant="tonal", prepend_icon="mdi-dice-multiple", id="new-variation",
                    click="computing = true; variation_asked += 1")
            v3.VBtn("gallery", size="x-small", variant="tonal", prepend_icon="mdi-view-grid-outline", id="open-gallery",
                    click="gallery_open = true", title=f"{GALLERY_SEEDS} seeds' reactions as pictures, from this seed on")
        gallery_dialog()
        with html.Div(v_if="spread_available", classes="d-flex align-center mb-1", style="gap: 6px", id="spread-row",
                      title="how loosely the reaction follows the leader's motion: 0 follows it closely, higher "
                            "draws wider variations"):
            html.Div("spread", classes="text-body-2", style="width: 48px")
            v3.VSlider(v_model=("spread",), min=0, max=1, step=0.05, density="compact", hide_details=True, id="spread-slider")
            html.Div("{{ Number(spread).toFixed(2) }}", classes="text-caption ml-1", style="width: 38px; text-align: right")
        with html.Div(classes="d-flex align-center", style="gap: 6px"):
            html.Div("variations side by side", classes="text-body-2")
            with v3.VBtnToggle(model_value=("variation_count",), density="compact", mandatory=True, variant="outlined",
                               divided=True, id="variation-count", color="primary",
                               title="followers drawn at once, seeds seed, seed + 1, ..."):
                for n in range(1, MAX_VARIATIONS + 1):
                    v3.VBtn(str(n), value=(str(n),), size="x-small",  # a number, as variation_count is: it shows selected
                            click=f"if (variation_count !== {n}) {{ computing = true; variation_count = {n}; }}")


def _js(text: str) -> str:
    """`text` as a single-quoted JavaScript string inside a template attribute (a model's title may hold an apostrophe)."""
    return "'" + text.replace("\\", "\\\\").replace("'", "\\'") + "'"
