"""The studio page's layout (trame + Vuetify 3): what is on screen and which controller each control calls.

The Studio (app.py) owns state and controllers; this module only places widgets, in pieces small enough to read,
from the LayoutParts it is given.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from trame.ui.vuetify3 import VAppLayout
from trame.widgets import client, html
from trame.widgets import vuetify3 as v3

from explorer.rendering.camera import CAMERA_PRESETS
from explorer.rendering.charts import CHART_CSS, DISTANCE_BOX
from explorer.rendering.palette import CHARACTER_TITLES, CHARACTERS, COMPARED, PINNED, WARNING, class_color, display_name
from explorer.rendering.scene import CHARACTER_KEYS
from explorer.rendering.view_stream import ViewStream
from explorer.trame_adapter import rendered_once

if TYPE_CHECKING:
    from explorer.rendering.scene import Scene
    from explorer.session.session import Session
from explorer.ui.exports import export_menu, screenshot_button
from explorer.ui.keys import KEY_HELP, LISTENER_JS
from explorer.ui.model_switch import model_chip, model_panel
from explorer.ui.reads_as_panel import reads_as_panel
from explorer.ui.review_panel import review_button, review_overlay

SPEEDS = [0.25, 0.5, 1.0, 1.5, 2.0]
# Sliders jump to a new value at once, as Vuetify's already do while dragged (a key or a click glides for 0.3 s), and
# the 'reads as' bars change without a 0.2 s glide: repainting those animations took the CPU that the new picture is
# made with on a small machine (slider p95 71-77 -> 52-53 ms in one back-to-back run, docs/experiments/studio-performance.md).
STILL_CONTROLS_CSS = """
.v-slider .v-slider-thumb, .v-slider .v-slider-track__fill, .v-slider .v-slider-track__background { transition: none; }
.reads-as-bar, .reads-as-bar .v-progress-linear__determinate { transition: none; }
"""

# The page fits the window, from 1280x720 up: the main area is exactly the window below the app bar, and its column
# (3D view, playback bar, chart and map) never wraps; the 3D view takes what the chart row leaves, down to a floor,
# and below that floor the column scrolls inside the main area (the page body never scrolls).
# The review, open, shares the window's height with the 3D view (the fold: the view keeps 400 px, the review the rest)
# and the chart and map row goes just below it, a scroll or the review's "chart & map" button away.
# A map with a selection listed beside it widens into the chart's half rather than squeezing its plot.
WINDOW_CSS = """
html { overflow: hidden; }
.imm-main { height: 100vh; }
.imm-column { height: 100%; display: flex; flex-direction: column; flex-wrap: nowrap; gap: 6px; padding: 8px;
              overflow: auto; min-width: 0; }
.imm-fold { flex: 1 1 auto; display: flex; flex-direction: column; gap: 6px; }
.imm-stage { flex: 1 1 auto; min-height: 280px; display: flex; flex-direction: column; gap: 6px; }
.imm-stage:fullscreen { background: rgb(var(--v-theme-surface)); padding: 8px; }
.imm-scene { flex: 1 1 auto; min-height: 240px; position: relative; width: 100%; }
.imm-fold.imm-fold-review { flex: 0 0 100%; min-height: 0; }
.imm-fold-review .imm-stage { min-height: auto; }
.imm-fold-review .imm-scene { min-height: 400px; }
.imm-review-panel { flex: 1 1 46vh; min-height: 160px; display: flex; flex-direction: column; }
.imm-review { flex: 0 0 clamp(220px, 34vh, 440px); display: flex; gap: 8px; width: 100%; min-height: 0; position: relative; }
.imm-review > .v-card { flex: 1 1 50%; min-width: 0; display: flex; flex-direction: column; }
.imm-review > #latent-card.imm-selecting { flex: 0 0 calc(50% + 150px); }
.imm-fill { flex: 1 1 auto; min-height: 120px; position: relative; }
.imm-toolbar-row { overflow-x: auto; overflow-y: hidden; flex-wrap: nowrap; }
.imm-alert { position: absolute; left: 4px; right: 4px; top: 4px; z-index: 3; }
.imm-alert .v-alert { padding-top: 2px !important; padding-bottom: 2px !important; }
.imm-alert .v-alert__content { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; align-self: center; }
.imm-alert .v-alert__close .v-btn { width: 24px !important; height: 24px !important; }
.imm-alert .v-alert__prepend { align-self: center; }
.imm-value { flex: 0 0 60px; width: 60px; height: 24px; padding: 0 4px; text-align: right; font-size: 13px;
             border: 1px solid #bdbdbd; border-radius: 4px; }
"""


@dataclass(frozen=True)
class LayoutParts:
    """What the layout places and wires: the trame server (its controllers are what the controls call), the session
    (class and model names), the scene, the render mode, and `attach_view(view)`, called with the 3D view widget once
    made (the Studio sends its pictures through it)."""

    server: Any
    session: Session
    scene: Scene
    render_mode: str
    attach_view: Callable[[Any], None]

    @property
    def ctrl(self):
        return self.server.controller


def build_layout(page: LayoutParts) -> VAppLayout:
    # Built from VAppLayout rather than trame's SinglePageWithDrawerLayout: that one adds a footer (hidden here anyway)
    # whose list of trame versions reads every installed package's metadata, ~0.2 s at every tab's start.
    page.server.state.trame__title = "IMM Studio"
    with rendered_once(), VAppLayout(page.server, full_height=True) as layout:
        with v3.VAppBar(density="compact", color="#263238", theme="dark"):
            v3.VAppBarNavIcon(click="main_drawer = !main_drawer")
            v3.VToolbarTitle("IMM Studio", style="flex: 0 0 auto")
            toolbar(page)
        with v3.VNavigationDrawer(v_model=("main_drawer", True), permanent=True, location="left", width=330):
            with html.Div(classes="pa-3 pt-0"):
                review_button()  # at the top of the side panel, however far it is scrolled
                label_mix(page)  # first: the mix is the studio's main control, on screen at load on a laptop
                v3.VDivider(classes="my-3")
                model_panel(page.session)
                v3.VDivider(classes="my-3")
                sequence_picker(page)
                v3.VDivider(classes="my-3")
                character_toggles(page)
        with v3.VMain(classes="imm-main"):
            with html.Div(classes="imm-column"):
                with html.Div(classes=("review_open ? 'imm-fold imm-fold-review' : 'imm-fold'",)):
                    with html.Div(classes="imm-stage"):  # what full screen shows: the view and its playback bar
                        scene_view(page)
                        playback_bar(page)
                    review_overlay(len(page.session.models))  # under the view while open
                review_cards(page)
                v3.VSnackbar("{{ notice }}", model_value=("!!notice",), timeout=4000, update_modelValue="notice = ''")
                page_hooks()
                keys_card()
                client.Style(STILL_CONTROLS_CSS + WINDOW_CSS)
    return layout


# The studio page lives under /s/<token>/; the link to share is the front page with the same view.
SHARE_LINK_JS = "utils.get('location.href').replace(/\\/s\\/[^/?#]+\\/(index\\.html)?(?=[?#]|$)/, '/')"


def page_hooks() -> None:
    """Keys, the view named in the page's URL (on load), and the URL kept on what is shown."""
    client.ClientTriggers(mounted=f"{LISTENER_JS}; trigger('open_url_view', [utils.get('location.search')]); "
                                  f"show_hints = !utils.get('localStorage').getItem('{HINTS_SEEN}')")
    with rendered_apart():  # the query changes after every move: read here, not by the page's whole template
        client.ClientStateChange(value="url_query", change="url_query && utils.get('history').replaceState(null, '', url_query)")


def keys_card() -> None:
    with v3.VDialog(v_model=("show_keys",), max_width=440):
        with v3.VCard(title="Keyboard", id="keys-card"):
            with v3.VCardText():
                for key, what in KEY_HELP:
                    with html.Div(classes="d-flex py-1"):
                        html.Kbd(key, style="min-width: 84px; text-align: center", classes="mr-3")
                        html.Span(what)


def toolbar(page: LayoutParts) -> None:
    """The top bar: the sequence and whether the model saw it, layout, camera presets, export."""
    v3.VSpacer()
    v3.VChip(
        "{{ sequence_title }}",
        size="small",
        variant="outlined",
        classes="mr-2",
        id="sequence-chip",
    )
    v3.VChip("uploaded: no ground truth", v_if="sequence_uploaded", size="small", color="teal-lighten-3", variant="flat",
             classes="mr-2", id="uploaded-chip")
    v3.VChip("held out", v_else_if="sequence_held_out", size="small", color="amber", variant="flat", classes="mr-2",
             title="held out: the model never saw this sequence in training (generalization)")
    v3.VChip("seen", v_else=True, size="small", color="blue-grey-lighten-3", variant="flat", classes="mr-2",
             title="seen in training: the model learnt from this sequence (memorization)")
    model_chip()
    v3.VSpacer()
    with v3.VBtnToggle(v_model=("scene_layout",), density="compact", mandatory=True, variant="outlined", classes="mr-2"):
        v3.VBtn("Overlay", value="overlay", size="small", classes="px-2")
        v3.VBtn("Side by side", value="side_by_side", size="small", classes="px-2")
    for preset in CAMERA_PRESETS:  # compact: the toolbar fits 1280 px with the longest sequence name
        v3.VBtn(
            None if preset == "default" else preset,
            icon="mdi-camera-retake" if preset == "default" else None,
            size="small",
            variant="text",
            title="reset the camera" if preset == "default" else f"camera: {preset}",
            classes="" if preset == "default" else "px-1",
            style="min-width: 0",
            click=(page.ctrl.set_camera, f"['{preset}']"),
            id=f"camera-{preset}",
        )
    export_menu()
    screenshot_button()
    share_link()
    v3.VBtn(icon="mdi-keyboard-outline", size="small", variant="text", title="Keyboard shortcuts (?)", click="show_keys = true")


def share_link() -> None:
    """A link that reopens this view (sequence, mix, scale, frame, layout, camera, map), copied when the browser allows."""
    with v3.VMenu(close_on_content_click=False):
        with v3.Template(v_slot_activator="{ props }"):
            v3.VBtn(icon="mdi-link-variant", v_bind="props", size="small", variant="text", title="Link to this view", id="copy-link",
                    click=f"share_link = {SHARE_LINK_JS}; utils.get('navigator.clipboard') && "
                          "utils.get('navigator.clipboard').writeText(share_link).then(() => notice = 'link copied')")
        with v3.VCard(min_width=420):
            v3.VTextField(v_model=("share_link", ""), label="link to this view", readonly=True, density="compact",
                          hide_details=True, id="share-link", classes="pa-2")


def sequence_picker(page: LayoutParts) -> None:
    """Filters (class, subject pair, held out) and the sequence picker."""
    html.Div("Sequence", classes="text-overline")
    for label, key in (("Class", "class_filter"), ("Subject pair", "pair_filter")):
        v3.VSelect(label=label, v_model=(key,), items=(f"{key}_items",), density="compact", hide_details=True, classes="mb-2")
    with v3.VBtnToggle(
        v_model=("held_filter",), density="compact", mandatory=True, variant="outlined", divided=True, classes="mb-2"
    ):
        v3.VBtn("all", value="all", size="x-small")
        v3.VBtn("held out", value="held", size="x-small")
        v3.VBtn("seen", value="seen", size="x-small")
    v3.VAutocomplete(
        label="Sequence",
        v_model=("sequence_index",),
        items=("sequence_items",),
        density="compact",
        hide_details=True,
        id="sequence-picker",
        # typing replaces the name shown instead of going into it (Vuetify fills the field with it on focus)
        focus="$nextTick(() => $event.target && $event.target.select && $event.target.select())",
        click="$event.target && $event.target.select && $event.target.select()",
    )
    html.Div(
        "Held out = subject {{ held_out_subject }}: the bundled model never saw these (generalization); "
        "the others were in its training set (memorization).",
        classes="text-caption text-medium-emphasis mt-1",
    )
    v3.VFileInput(
        label="Upload a leader (.bvh, .npz, SBU .txt; up to 20 MB)",
        v_model=("upload_file", None),
        accept=".bvh,.npz,.txt",
        density="compact",
        hide_details=True,
        prepend_icon="mdi-upload",
        classes="mt-2",
        id="leader-upload",
    )


def label_mix(page: LayoutParts) -> None:
    """One slider per class (-1 avoid .. +1 perform), the scale, the label in words and what it reads as. With a model
    that reads a label per body part, a class's parts can be set apart: its slider is then the upper body's (trunk and
    arms) and a second one, under it, the lower body's (legs and where the follower stands)."""
    with html.Div(classes="d-flex align-center"):
        html.Div("Label mix", classes="text-overline")
        v3.VSpacer()
        v3.VBtn("match", size="x-small", variant="tonal", click=page.ctrl.match_label, id="match-label", classes="mr-1")
        v3.VBtn("reset", size="x-small", variant="tonal", click=page.ctrl.reset_label, id="reset-label")
    for i, name in enumerate(page.session.class_names):
        # the class's name over a slider as wide as the drawer allows, and its value to type
        with html.Div(classes="d-flex align-center", style="height: 22px"):
            html.Div(
                f"{i + 1} {display_name(name)}", classes=(f"key_slider === {i} ? 'text-body-2 text-decoration-underline' : 'text-body-2'",),
                style=f"flex: 1 1 auto; color: {class_color(i)}; font-weight: 600", title="keys: 1-6 select, up/down move",
            )
            # the parts apart: the lower body's slider starts where the class's is; linked again, both take the class's
            v3.VBtn(f"{{{{ apart_{i} ? 'one for the whole body' : 'by body part' }}}}", v_if="part_labels", size="x-small",
                    variant=(f"apart_{i} ? 'flat' : 'text'",), height=22, id=f"parts-{i}", classes="part-toggle px-1",
                    prepend_icon="mdi-human", color=(f"apart_{i} ? 'primary' : undefined",),
                    click=f"lower_{i} = w_{i}; apart_{i} = !apart_{i}",
                    title=(f"apart_{i} ? 'link the parts: {display_name(name)} for the whole body' : "
                           f"'set {display_name(name)} apart for the upper body (trunk, arms) and the lower body (legs, stance)'",))
        with html.Div(classes="d-flex align-center", style="height: 30px"):
            part_tag("upper", f"part_labels && apart_{i}")
            class_slider(f"w_{i}", i, f"class-slider slider-{name}", f"slider-{i}")
        with html.Div(v_if=f"part_labels && apart_{i}", classes="d-flex align-center", style="height: 30px"):
            part_tag("lower")
            class_slider(f"lower_{i}", i, f"lower-slider lower-slider-{name}", f"lower-slider-{i}")
    with html.Div(classes="d-flex align-center", style="height: 30px"):
        html.Div("scale", classes="text-body-2", style="flex: 0 0 48px; font-weight: 600")
        with rendered_apart():
            v3.VSlider(v_model=("scale",), min=0, max=2, step=0.05, density="compact", hide_details=True, id="scale-slider")
            html.Input(type="number", min=0, max=2, step=0.05, value=("Number(scale).toFixed(2)",), classes="ml-2 imm-value",
                       id="value-scale", title="type the scale, 0 .. 2: Enter or leaving the field sets it",
                       __events=["change"], change="scale = Math.max(0, Math.min(2, Number($event.target.value) || 0))")
    with rendered_apart():
        html.Div("{{ label_text }}", classes="text-body-2 mt-1 pa-2 rounded bg-grey-lighten-4", id="label-text",
                 style="overflow-wrap: anywhere")  # part keys are long words
    compare_row(page)
    with rendered_apart():  # it changes with every follower drawn
        reads_as_panel()


def class_slider(key: str, i: int, classes: str, slider_id: str) -> None:
    """A class's slider (-1 .. +1, in its colour) and its value, which the user may type (Enter or leaving the field
    sets it, within -1 .. +1)."""
    with rendered_apart():
        v3.VSlider(v_model=(key,), min=-1, max=1, step=0.05, density="compact", hide_details=True, color=class_color(i),
                   track_color="grey-lighten-2", classes=classes, id=slider_id)
        html.Input(type="number", min=-1, max=1, step=0.05, value=(f"Number({key}).toFixed(2)",), classes="ml-2 imm-value",
                   id=f"value-{slider_id}", title="type a value, -1 (avoid) .. +1 (perform): Enter or leaving the field sets it",
                   __events=["change"], change=f"{key} = Math.max(-1, Math.min(1, Number($event.target.value) || 0))")


def part_tag(part: str, shown: str | None = None) -> None:
    """Which body part the slider beside it weighs."""
    html.Div(part, v_if=shown, classes="text-caption text-medium-emphasis", style="flex: 0 0 36px")


def character_toggles(page: LayoutParts) -> None:
    """Show or hide each of the three characters."""
    html.Div("Characters", classes="text-overline")
    for key, var in zip(CHARACTER_KEYS, ("show_leader", "show_ground_truth", "show_synthesized"), strict=True):
        v3.VCheckbox(
            v_model=(var,),
            label=CHARACTER_TITLES[key],
            disabled=("sequence_uploaded",) if key == "ground_truth" else False,
            color=CHARACTERS[key],
            density="compact",
            hide_details=True,
            base_color=CHARACTERS[key],
            style=f"color: {CHARACTERS[key]}",
        )
    v3.VCheckbox(
        v_model=("clean_up",),
        label="Clean-up: rigid bones, planted feet",
        density="compact",
        hide_details=True,
        id="clean-up",
        title="Off: the network's own follower, as it predicted the joints",
    )


def compare_row(page: LayoutParts) -> None:
    """A/B: pin this mix (purple in the view), then move the sliders; swap or clear."""
    with html.Div(classes="d-flex align-center mt-1", style="gap: 4px"):
        v3.VBtn("pin this mix", size="x-small", variant="tonal", prepend_icon="mdi-pin", click=page.ctrl.pin_mix, id="pin-mix",
                title="keep this mix to compare the next ones with")
        v3.VBtn("swap", size="x-small", variant="tonal", click=page.ctrl.swap_mix, disabled=("!pinned_text",), id="swap-mix")
        v3.VBtn("clear", size="x-small", variant="tonal", click=page.ctrl.clear_pin, disabled=("!pinned_text",), id="clear-pin")
    html.Div("pinned: {{ pinned_text }} · {{ ab_text }}", v_if="pinned_text", classes="text-caption mt-1",
             style=f"color: {PINNED}", id="pinned-text")


def scene_view(page: LayoutParts) -> None:
    """The error alert and the 3D view (rendered on the server, or by vtk.js with --render local)."""
    # the first drag or wheel on the view does what the first-use hint says: the hint has done its job and goes
    with html.Div(classes="rounded border imm-scene", __events=["pointerdown", "wheel"], pointerdown=HINTS_DONE,
                  wheel=HINTS_DONE):
        # one line over the top of the view, the whole message on hover: the view keeps its size
        with html.Div(v_if="error", classes="imm-alert", title=("error",)):
            v3.VAlert("{{ error }}", type="error", density="compact", closable=True, click_close="error = ''", id="error-alert")
        if page.render_mode == "local":  # vtk.js in the browser (docs/experiments/studio-performance.md), through trame's PyVista view
            from trame.widgets import pyvista as pyvista_widgets  # only here: trame-pyvista's import is for this mode

            view = pyvista_widgets.PyVistaLocalView(page.scene.plotter)
        else:  # rendered on the server, streamed as pictures (explorer/rendering/view_stream.py)
            view = ViewStream(page.server, page.scene.render_window)
        page.attach_view(view)
        with html.Div(style="position: absolute; left: 8px; top: 6px; pointer-events: none", classes="text-caption"):
            for key in CHARACTER_KEYS:  # the figures shown: a hidden one, or an uploaded leader's ground truth, is not listed
                html.Span(
                    "● " + CHARACTER_TITLES[key], style=f"color: {CHARACTERS[key]}; font-weight: 600; margin-right: 10px",
                    v_if=f"show_{key}" + (" && !sequence_uploaded" if key == "ground_truth" else ""), classes=f"legend-{key}",
                )
            html.Span("● pinned: {{ pinned_text }}", v_if="pinned_text", style=f"color: {PINNED}; font-weight: 600")
            html.Span("● other models", v_if="scene_layout === 'side_by_side' && compare_models.some(n => n !== model_name)",
                      style=f"color: {COMPARED}; font-weight: 600; margin-left: 10px", classes="legend-compared")
        viewer_tools()
        first_use_hints()
        html.Div("{{ joint_hover.text }}", v_if="joint_hover", id="joint-hover", classes="text-caption px-1 rounded",
                 style=("{position: 'absolute', left: joint_hover.x + '%', top: joint_hover.y + '%', transform: "
                        "'translate(12px, -130%)', background: 'rgba(255,255,255,.92)', border: '1px solid #bbb', "
                        "pointerEvents: 'none', whiteSpace: 'nowrap', zIndex: 2}",))


# Full screen for the 3D view (the button's own element, so no script of its own); again, or Esc, leaves it.
FULL_SCREEN_JS = ("utils.get('document.fullscreenElement') ? utils.get('document').exitFullscreen()"
                  " : $event.currentTarget.closest('.imm-stage').requestFullscreen()")


def viewer_tools() -> None:
    """The view's corner: trails of the last frames, a camera that follows the pair, full screen."""
    with html.Div(style="position: absolute; right: 6px; top: 4px; z-index: 2; display: flex; gap: 2px", id="viewer-tools"):
        v3.VBtn(icon="mdi-motion-outline", size="small", density="comfortable", id="trails-button",
                variant=("trails ? 'tonal' : 'text'",), color=("trails ? 'primary' : undefined",),
                click="trails = !trails", title="trails: ghosts of the last frames (overlay)")
        v3.VBtn(icon="mdi-crosshairs-gps", size="small", density="comfortable", id="follow-button",
                variant=("follow_camera ? 'tonal' : 'text'",), color=("follow_camera ? 'primary' : undefined",),
                click="follow_camera = !follow_camera", title="camera follows the pair")
        v3.VBtn(icon="mdi-fullscreen", size="small", density="comfortable", variant="text", id="fullscreen-button",
                click=FULL_SCREEN_JS, title="full screen (Esc leaves it)")


HINTS_SEEN = "imm-studio-hints-seen"  # the browser's localStorage key: the hints were dismissed once
HINTS_DONE = f"if (show_hints) {{ show_hints = false; utils.get('localStorage').setItem('{HINTS_SEEN}', '1'); }}"


def first_use_hints() -> None:
    """What a newcomer cannot guess, over the bottom of the 3D view until dismissed or the view first dragged or
    zoomed (remembered by the browser)."""
    with html.Div(v_if="show_hints", id="first-use-hints", classes="text-caption d-flex align-center pa-1 rounded",
                  style="position: absolute; left: 8px; bottom: 8px; z-index: 2; background: rgba(38, 50, 56, .85); color: #fff; gap: 6px"):
        v3.VIcon("mdi-gesture-swipe", size="small")
        html.Span("drag: rotate · wheel: zoom · a click on a latent map point opens and plays it · ?: keys")
        v3.VBtn(icon="mdi-close", size="x-small", variant="text", title="got it", id="hints-close",
                click=HINTS_DONE)


def rendered_apart():
    """A wrapper for what changes often outside any other component's slot (the frame slider, the time and the
    chart's cursor with every frame played; the class sliders, the label in words, the reads-as panel, the contact
    ticks, the map's marks and the URL with every move): its contents are a slot, rendered by a component of their
    own, so a change to the state they read re-renders them and not the whole component around them (the page's
    template, or the drawer with most of the controls), which took ~10 ms of the browser's main thread a frame on 2
    cores and held a slider's state back as long (benchmarks/page_render_cost.py, docs/experiments/studio-performance.md)."""
    return v3.VDefaultsProvider()


# The loop range and the contact frames drawn over the frame slider's track, which Vuetify insets 8 px from each side.
TIMELINE_CSS = f"""
.imm-timeline {{ flex: 1 1 auto; position: relative; min-width: 0; align-self: stretch; display: flex; align-items: center; }}
.imm-timeline-marks {{ position: absolute; left: 8px; right: 8px; top: 0; bottom: 0; pointer-events: none; }}
.imm-loop-span {{ position: absolute; top: calc(50% - 8px); height: 16px; background: rgba(var(--v-theme-primary), .18);
                  border: solid rgb(var(--v-theme-primary)); border-width: 0 2px; }}
.imm-loop-span > span {{ position: absolute; top: 15px; font-size: 10px; line-height: 11px; color: rgb(var(--v-theme-primary)); }}
.imm-loop-span > .imm-loop-in {{ right: calc(100% - 2px); }}
.imm-loop-span > .imm-loop-out {{ left: calc(100% - 2px); }}
.imm-contact-tick {{ position: absolute; top: calc(50% - 18px); width: 10px; height: 8px; margin-left: -5px; cursor: pointer;
                     background: {WARNING}; clip-path: polygon(0 0, 100% 0, 50% 100%); pointer-events: auto; }}
"""
AT_FRAME = "(100 * ({}) / Math.max(1, num_frames - 1)) + '%'"  # a frame's place along the track


def timeline() -> None:
    """The frame slider, with the loop range on its track (a span, its first and last frame numbered as the time
    is) and the frames of contact as ticks above it (a click seeks there)."""
    client.Style(TIMELINE_CSS)
    with html.Div(classes="imm-timeline", id="timeline"):
        with rendered_apart():
            v3.VSlider(
                v_model=("frame",),
                min=0,
                max=("num_frames - 1",),
                step=1,
                hide_details=True,
                density="compact",
                id="frame-slider",
                style="flex: 1 1 auto",
            )
        with html.Div(classes="imm-timeline-marks"):
            with html.Div(v_if="loop_range.length === 2", classes="imm-loop-span", id="loop-span",
                          style=(f"{{left: {AT_FRAME.format('loop_range[0]')}, "
                                 f"width: {AT_FRAME.format('loop_range[1] - loop_range[0]')}}}",)):
                html.Span("{{ loop_range[0] + 1 }}", classes="imm-loop-in")
                html.Span("{{ loop_range[1] + 1 }}", classes="imm-loop-out")
            with rendered_apart():  # the contact frames change with every follower drawn
                html.Div(v_for="m in contact_marks", key=("m",), classes="imm-contact-tick", click="frame = m",
                         style=(f"{{left: {AT_FRAME.format('m')}}}",), title=("'contact: the bodies closest at frame ' + (m + 1)",))


def loop_range_buttons(page: LayoutParts) -> None:
    """The loop range's in and out at the frame shown (keys [ and ]), and a clear back to the whole take."""
    for end, icon, what in (("in", "mdi-contain-start", "loop from this frame ([)"),
                            ("out", "mdi-contain-end", "loop up to this frame (])")):
        v3.VBtn(icon=icon, size="small", density="comfortable", variant="text", title=what, id=f"loop-{end}",
                click=page.ctrl.set_loop_in if end == "in" else page.ctrl.set_loop_out)
    v3.VBtn(icon="mdi-close", v_if="loop_range.length", size="x-small", density="comfortable", variant="text",
            title="clear the loop range: the whole take", id="loop-clear", click=page.ctrl.clear_loop)


def playback_bar(page: LayoutParts) -> None:
    """Play/pause, step, the frame slider and its loop range, time, speed and loop."""
    with html.Div(classes="d-flex align-center", style="width: 100%; gap: 8px; flex: 0 0 auto"):
        v3.VBtn(icon="mdi-skip-previous", size="small", variant="text", click=(page.ctrl.step_frame, "[-1]"))
        v3.VBtn(
            icon=("playing ? 'mdi-pause' : 'mdi-play'",),
            size="small",
            color="primary",
            click="playing = !playing",
            id="play-button",
        )
        v3.VBtn(icon="mdi-skip-next", size="small", variant="text", click=(page.ctrl.step_frame, "[1]"))
        timeline()
        with rendered_apart():
            html.Div("{{ time_text }}", classes="text-caption", style="width: 190px", id="time-text")
        v3.VSelect(
            v_model=("speed",),
            items=("speeds", [{"title": f"{x:g}×", "value": x} for x in SPEEDS]),
            density="compact",
            hide_details=True,
            style="max-width: 92px",
            variant="outlined",
            id="speed-select",
        )
        loop_range_buttons(page)
        v3.VCheckbox(v_model=("loop",), label="loop", density="compact", hide_details=True, style="flex: 0 0 auto")
        v3.VCheckbox(v_model=("live",), label="live", density="compact", hide_details=True, style="flex: 0 0 auto",
                     disabled=("!can_go_live",), id="live-toggle",
                     title=("can_go_live ? 'live: the follower made frame by frame as the leader plays; move a slider "
                            "while it plays to steer it' : 'this model cannot react live, frame by frame'",))


def review_cards(page: LayoutParts) -> None:
    """The per-frame error chart and the latent map."""
    with html.Div(classes="imm-review"):
        with v3.VCard(variant="outlined", classes="pa-1", id="chart-card"):
            with html.Div(classes="d-flex align-center px-2", style="gap: 4px"):
                chart_picker(page)
                v3.VSpacer()
                html.Div("{{ afd_text }}", v_if="!plot_kind", classes="text-caption", id="afd-text")
            html.Div("{{ contact_text }}", v_if="!plot_kind", classes="text-caption px-2", style=f"color: {WARNING}",
                     id="contact-text")
            distance_chart()
        with v3.VCard(variant="outlined", classes=("latent_rows.length ? 'pa-1 imm-selecting' : 'pa-1'",), id="latent-card"):
            with html.Div(classes="d-flex align-center px-2", style="gap: 6px"):
                html.Div("Latent map", classes="text-caption font-weight-bold", style="white-space: nowrap")
                v3.VProgressCircular(v_if="projection_busy", indeterminate=True, size=14, width=2)
                v3.VSpacer()
                with v3.VBtnToggle(v_model=("latent_color",), density="compact", mandatory=True, variant="outlined", divided=True,
                                   id="latent-color"):
                    v3.VBtn("class", value="class", size="x-small")
                    v3.VBtn("AFD", value="afd", size="x-small", disabled=("!(latent_points && latent_points.afd)",),
                            id="latent-color-afd")
                    v3.VBtn("held out", value="held", size="x-small")
                with v3.VBtnToggle(
                    v_model=("projection",), density="compact", mandatory=True, variant="outlined", divided=True
                ):
                    v3.VBtn("t-SNE", value="tsne", size="x-small")
                    v3.VBtn("UMAP", value="umap", size="x-small", id="umap-button")
            with html.Div(classes="d-flex imm-fill", style="gap: 6px"):
                latent_map()
                selection_list(page)


PLOTS = (("", "error and contact"), ("distance", "joint distance"), ("speed", "joint speed"))  # explorer/session/joint_plot.py
PICK_CSS = ".imm-pick { font-size: 12px; height: 22px; max-width: 132px; padding: 0 2px; border: 1px solid #bdbdbd; " \
           "border-radius: 4px; appearance: auto; }"


def chart_picker(page: LayoutParts) -> None:
    """What the chart plots per frame: the error and contact (by default), the distance between two joints, each of
    the leader (A) or the follower (B), or the speed of one of the follower's joints. Native selects: one line high,
    and the keys (explorer/ui/keys.py) leave them alone."""
    client.Style(PICK_CSS)
    html.Div("Per frame:", classes="text-caption font-weight-bold", style="white-space: nowrap")
    with html.Select(v_model=("plot_kind",), classes="imm-pick", id="plot-kind", title="what the chart plots"):
        for value, title in PLOTS:
            html.Option(title, value=value)
    distance = "plot_kind === 'distance'"
    joint_select(page, "plot_a", "AB", distance)
    html.Span("↔", v_if=distance)
    joint_select(page, "plot_b", "AB", distance)
    joint_select(page, "plot_joint", "B", "plot_kind === 'speed'")


def joint_select(page: LayoutParts, key: str, characters: str, shown: str) -> None:
    with html.Select(v_model=(key,), v_if=shown, classes="imm-pick", id=key.replace("_", "-")):
        for who in characters:
            for name in page.session.data.skeleton.joint_names:
                html.Option(f"{who} · {name.replace('_', ' ')}", value=f"{who}.{name}")


# A click on the chart moves to the frame under the mouse.
SEEK_JS = ("frame = Math.max(0, Math.min(num_frames - 1, Math.round((num_frames - 1) * ($event.clientX -"
           " $event.currentTarget.getBoundingClientRect().left) / $event.currentTarget.clientWidth)))")


def distance_chart() -> None:
    """explorer/rendering/charts.py's markup, with the frame cursor on top (it follows playback without a redraw)."""
    client.Style(CHART_CSS)
    with html.Div(classes="imm-fill", id="distance-chart"):
        html.Div(v_html=("distance_chart",))
        with html.Div(classes="imm-plot", style=f"{DISTANCE_BOX}; cursor: crosshair", click=SEEK_JS, id="distance-seek"):
            with rendered_apart():
                html.Div(classes="imm-cursor", style=("{left: (100 * frame / Math.max(1, num_frames - 1)) + '%'}",))


# The map's tool bar upright in the figure's left margin (static/latent_map.js sets the margin and the orientation):
# Plotly has no setting for where it goes, and at its top-right place it covered the legend.
LATENT_CSS = """
#latent-plotly .modebar-container { right: auto !important; left: 0; }
#latent-plotly .modebar { right: auto; left: 2px; }
"""


def latent_map() -> None:
    """The Plotly figure (static/latent_map.js draws it from the state latent_panel.py writes): hover a point for its
    readout, click it to open and play it, zoom, pan, box or lasso select from the figure's own tool bar."""
    client.Style(LATENT_CSS)
    with html.Div(style="flex: 1 1 auto; min-width: 0; position: relative", id="latent-plot"):
        html.Div(id="latent-plotly", style="position: absolute; inset: 0")
        html.Div("fitting the {{ projection === 'umap' ? 'UMAP' : 't-SNE' }} map (a few seconds; UMAP's first fit up to a minute)...",
                 v_if="projection_busy", classes="text-caption text-medium-emphasis", id="latent-busy",
                 style="position: absolute; left: 50%; top: 45%; transform: translateX(-50%); background: rgba(255,255,255,.85)")
    draw = "utils.get('immLatent').draw(latent_points, latent_marks, latent_color, latent_colors)"
    with rendered_apart():  # the marks change with every follower drawn: read here, not by the page's whole template
        client.ClientStateChange(value="latent_points", trigger_on_create=True, change=draw)
        client.ClientStateChange(value="latent_color", change=draw)
        client.ClientStateChange(value="latent_marks", change="utils.get('immLatent').marks(latent_marks)")


def selection_list(page: LayoutParts) -> None:
    """The sequences a box or lasso selected on the map: worst AFD first (or by id or class); a click opens one."""
    with html.Div(v_if="latent_rows.length", id="latent-selection",
                  style="flex: 0 0 200px; display: flex; flex-direction: column; min-height: 0; border-left: 1px solid #ddd"):
        with html.Div(classes="d-flex align-center px-1", style="gap: 4px"):
            html.Div("{{ latent_rows.length }} selected", classes="text-caption font-weight-bold", style="white-space: nowrap")
            v3.VSpacer()
            v3.VSelect(v_model=("latent_sort",), items=("latent_sort_items", [{"title": "worst AFD", "value": "afd"},
                       {"title": "id", "value": "id"}, {"title": "class", "value": "class"}]), density="compact",
                       hide_details=True, variant="plain", style="max-width: 96px; font-size: 11px", id="latent-sort")
            v3.VBtn(icon="mdi-close", size="x-small", variant="text", title="clear the selection", click="latent_selection = []")
        with html.Div(style="overflow-y: auto; flex: 1 1 auto; min-height: 0"):
            with html.Div(v_for="row in latent_rows", key=("row.i",), classes="latent-row text-caption d-flex align-center px-1",
                          style="cursor: pointer; gap: 4px; line-height: 18px", click=(page.ctrl.open_listed, "[row.i]"),
                          title=("row.cls + (row.held ? ' · held out' : ' · seen in training')",)):
                html.Span("●", style=("{color: row.color}",))
                html.Span("{{ row.id }}", style="flex: 1 1 auto; white-space: nowrap")
                html.Span("{{ row.held ? 'held' : '' }}", classes="text-medium-emphasis")
                html.Span("{{ row.afd === null ? '' : row.afd.toFixed(2) }}", style="width: 34px; text-align: right")
