"""The 3D scene: three stick figures (leader, ground truth, synthesized; explorer/rendering/figures.py), a floor grid,
captions, the camera presets and the layouts, in a PyVista Plotter rendering off screen.

Built once per process. A frame change only overwrites point coordinates of persistent meshes (the
tube and sphere filters re-run on their inputs); a layout change only moves actors. Nothing is
rebuilt while the user plays, scrubs or mixes labels.

Importing pyvista.plotting (which imports matplotlib) costs 1.4-2 s here: the zygote pays it once, before it forks
the studio processes (explorer/serving/zygote.py preload), so a tab's process starts with it loaded.
"""

from __future__ import annotations

import os

import numpy as np

# EGL (Mesa llvmpipe on CPU machines) renders off screen without an X server; set before VTK loads.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

import pyvista as pv  # noqa: E402
import pyvista.plotting  # noqa: E402, F401 - lazy in pyvista: imported with this module, so the zygote's preload pays it
from vtkmodules.vtkInteractionStyle import vtkInteractorStyleTrackballCamera  # noqa: E402
from vtkmodules.vtkRenderingUI import vtkGenericRenderWindowInteractor  # noqa: E402

from explorer.rendering.camera import PAIR_KEYS, SIDE_SPACING, TOP_CAPTION_OFFSET, SceneCamera  # noqa: E402
from explorer.rendering.captions import Captions, caption_px  # noqa: E402
from explorer.rendering.figures import ContactOverlay, StickFigure, Trail, add_actor, line_mesh, set_lines  # noqa: E402
from explorer.rendering.palette import CHARACTER_TITLES, CHARACTERS, COMPARED, PINNED  # noqa: E402
from imm_model.skeleton import Skeleton  # noqa: E402

CHARACTER_KEYS = ("leader", "ground_truth", "synthesized")
TRAIL_KEYS = PAIR_KEYS  # the figures whose last frames trail behind them
VARIATION_KEYS = ("variation_1", "variation_2", "variation_3")  # a seeded model's further followers, side by side
COMPARED_KEYS = ("compared_1", "compared_2", "compared_3")  # other models' followers, right of those (set_compared)
BESIDE_KEYS = VARIATION_KEYS + COMPARED_KEYS  # followers drawn only side by side, right of the synthesized one
LAYOUTS = ("overlay", "side_by_side")
BACKGROUND = "#f4f5f7"


class Scene:
    def __init__(self, skeleton: Skeleton, floor_y: float, window_size: tuple[int, int] = (1050, 500)):
        # One camera-following light: a light kit (5 lights, PyVista's default) doubled llvmpipe's per-frame cost.
        self.plotter = pv.Plotter(off_screen=True, window_size=window_size, lighting="none")
        self.plotter.add_light(pv.Light(light_type="headlight"))
        self.plotter.set_background(BACKGROUND)
        self.renderer = self.plotter.renderer
        self.render_window = self.plotter.render_window
        self.render_window.SetMultiSamples(0)  # MSAA costs ~3x per frame on llvmpipe (docs/experiments/studio-performance.md)
        # Mouse events from the page (explorer/rendering/view_stream.py) turn the camera through this interactor (an off-screen
        # Plotter has none of its own).
        interactor = vtkGenericRenderWindowInteractor()
        interactor.SetRenderWindow(self.render_window)
        interactor.SetInteractorStyle(vtkInteractorStyleTrackballCamera())
        interactor.Initialize()
        self.skeleton = skeleton
        self.floor_y = float(floor_y)
        self.figures = {k: StickFigure(self.plotter, skeleton, CHARACTERS[k]) for k in CHARACTER_KEYS}
        self.figures["pinned"] = StickFigure(self.plotter, skeleton, PINNED)  # A/B: shown only while a mix is pinned
        self.figures["pinned"].set_visible(False)
        self.contact = ContactOverlay(self.plotter, skeleton)
        # the last frames of the leader and the synthesized follower as ghosts (overlay layout, set_trails)
        self.trails = {k: Trail(self.plotter, skeleton, CHARACTERS[k]) for k in TRAIL_KEYS}
        self.trails_on = False
        self.captions = Captions(self.plotter)
        for k in CHARACTER_KEYS:
            self.captions.add(k, CHARACTER_TITLES[k], CHARACTERS[k])
        for k in BESIDE_KEYS:  # shown only side by side, right of the synthesized follower (set_variations, set_compared)
            color = COMPARED if k in COMPARED_KEYS else CHARACTERS["synthesized"]
            self.figures[k] = StickFigure(self.plotter, skeleton, color)
            self.figures[k].set_visible(False)
            self.captions.add(k, "", color)
        self.floor = self._floor()
        self.layout = "overlay"
        self.visible = {k: True for k in CHARACTER_KEYS}
        self.sequences: dict[str, np.ndarray] = {}
        self.frame = 0
        self.camera = SceneCamera(self)
        # at every render, after the camera's refit (priority 0): the captions fit the picture it frames
        self.renderer.AddObserver("StartEvent", lambda *_: self._fit_captions(), -1.0)

    def close(self) -> None:
        self.plotter.close()

    # ---- building blocks ----------------------------------------------------------------
    def _floor(self):
        """The floor as a grid of 2 (n + 1) lines on the background. Why no shaded plane under it: on llvmpipe that
        one quad's pixels were ~3 ms of a full-size frame and ~1 ms of a draft (docs/experiments/studio-performance.md); an
        n x n plane drawn again as wireframe had cost 2 ms more than these lines."""
        size, n, y = 9.0, 18, self.floor_y
        ticks = np.linspace(-size / 2, size / 2, n + 1)
        grid = line_mesh(4 * (n + 1))
        grid.points[:] = [p for u in ticks for p in ((u, y, 0.5 - size / 2), (u, y, 0.5 + size / 2),
                                                    (-size / 2, y, 0.5 + u), (size / 2, y, 0.5 + u))]
        set_lines(grid, [(2 * k, 2 * k + 1) for k in range(2 * (n + 1))])
        return add_actor(self.plotter, grid, "#b9bec8", lit=False)

    # ---- content ------------------------------------------------------------------------
    def set_sequence(self, leader: np.ndarray, ground_truth: np.ndarray | None, synthesized: np.ndarray, frame: int = 0) -> None:
        """ground_truth None (an uploaded leader): the red figure is hidden, whatever its checkbox says."""
        self.sequences = {"leader": leader, "ground_truth": ground_truth, "synthesized": synthesized}
        self.sequences = {k: v for k, v in self.sequences.items() if v is not None}
        for k in CHARACTER_KEYS:
            self.figures[k].set_visible(self.visible[k] and k in self.sequences)
        self.figures["pinned"].set_visible(False)  # until set_pinned gives it the new leader's follower
        for k in BESIDE_KEYS:  # until set_variations and set_compared give the new leader's
            self.figures[k].set_visible(False)
        self.contact.flags = None  # until set_contact gives the new sequence's
        self.camera.lost_pair()
        self.place_figures()
        self.set_frame(frame)

    def set_synthesized(self, synthesized: np.ndarray) -> None:
        """New label mix: only the green figure changes, at the current frame."""
        self.sequences["synthesized"] = synthesized
        if self.layout == "side_by_side":  # its spot follows its own first-frame root, which the mix moves
            self.place_figures()
        self.figures["synthesized"].set_pose(synthesized[min(self.frame, len(synthesized) - 1)])
        self._show_aids(contact=False)  # the contact of the new mix follows with its review (set_contact)

    def set_pinned(self, pinned: np.ndarray | None) -> None:
        """A/B: the pinned mix's follower, drawn where the synthesized one is (None hides it)."""
        if pinned is None:
            self.sequences.pop("pinned", None)
        else:
            self.sequences["pinned"] = pinned
            self.figures["pinned"].set_pose(pinned[min(self.frame, len(pinned) - 1)])
        self.figures["pinned"].set_visible(pinned is not None and self.visible["synthesized"])
        self.place_figures()

    def set_variations(self, followers: list[np.ndarray], seeds: list[int] | None, model_title: str = "") -> None:
        """A seeded model's followers for seeds[0], seeds[1], ... (the first is the synthesized one): the others
        stand right of it in the side-by-side layout, each captioned with its seed. `seeds` None: a deterministic
        model (one follower, captioned as usual). `model_title`: named under the synthesized follower's caption (when
        other models' followers stand beside it)."""
        second = " · ".join(filter(None, (model_title, "" if seeds is None else f"seed {seeds[0]}")))
        title = CHARACTER_TITLES["synthesized"]
        self.captions.set_text("synthesized", f"{title}\n{second}" if second else title)  # one line would reach its neighbour
        if seeds is None and self.slots() == len(CHARACTER_KEYS):
            return  # a deterministic model's follower, as before: set_synthesized placed it
        self._beside(VARIATION_KEYS, [] if seeds is None else [(f"seed {d}", f) for d, f in zip(seeds[1:], followers[1:], strict=False)])

    def set_compared(self, followers: list[tuple[str, np.ndarray]]) -> None:
        """Other models' followers [(caption, follower), ...] (up to len(COMPARED_KEYS)): they stand right of the
        synthesized follower and its variations in the side-by-side layout, and follow the frame as it does."""
        if len(followers) > len(COMPARED_KEYS):
            raise ValueError(f"at most {len(COMPARED_KEYS)} other models' followers side by side, not {len(followers)}")
        self._beside(COMPARED_KEYS, followers)

    def _beside(self, keys: tuple[str, ...], followers: list[tuple[str, np.ndarray]]) -> None:
        """Captioned followers on the spots of `keys` (those left over are emptied), right of the synthesized one."""
        slots = self.slots()
        for i, k in enumerate(keys):
            if i < len(followers):
                caption, follower = followers[i]
                self.sequences[k] = follower
                self.captions.set_text(k, caption)
                self.figures[k].set_pose(follower[min(self.frame, len(follower) - 1)])
            else:
                self.sequences.pop(k, None)
        self.place_figures()
        if self.layout == "side_by_side" and self.slots() != slots:
            self.camera.set(self.camera.preset)  # room for more or fewer figures (a camera the user turned stays else)

    def _fit_captions(self) -> None:
        if self.layout == "side_by_side":
            self.captions.fit(self.renderer)

    def caption_boxes(self) -> dict[str, tuple[float, float, float, float]]:
        """{figure key: (left, right, bottom, top)} of each caption in the last picture, in its pixels."""
        return self.captions.boxes(self.renderer)

    def captions_shown(self) -> list[str]:
        """The captions the view shows now, left to right (side by side only)."""
        return self.captions.shown([k for k in (*CHARACTER_KEYS, *BESIDE_KEYS) if k in self.sequences])

    def set_contact(self, leader_bones: np.ndarray | None, follower_bones: np.ndarray | None) -> bool:
        """Which bones interpenetrate, per frame ((T, K) each; None: none shown) -> whether that changed."""
        new = None if leader_bones is None else (leader_bones, follower_bones)
        old = self.contact.flags
        changed = (old is None) != (new is None) or (new is not None and not all(
            a.shape == b.shape and np.array_equal(a, b) for a, b in zip(old, new, strict=True)))
        self.contact.flags = new
        self._show_aids()
        return changed

    def set_trails(self, on: bool) -> None:
        """Ghosts of the last frames of the leader and the synthesized follower (overlay layout only)."""
        self.trails_on = bool(on)
        self._show_aids()

    def _show_aids(self, contact: bool = True) -> None:
        """The contact overlay (`contact`) and the trails at the current frame, in the overlay layout, where their
        figures show."""
        overlay = self.layout == "overlay"
        self.contact.enabled = overlay and self.visible["leader"] and self.visible["synthesized"]
        if contact and "synthesized" in self.sequences:
            self.contact.show(self.sequences["leader"], self.sequences["synthesized"], self.frame)
        for k, trail in self.trails.items():
            trail.show(self.sequences.get(k), self.frame, self.trails_on and overlay and self.visible[k])

    def set_frame(self, frame: int) -> None:
        if not self.sequences:
            return
        t = len(self.sequences["leader"])
        self.frame = int(np.clip(frame, 0, t - 1))
        for k, seq in self.sequences.items():
            self.figures[k].set_pose(seq[self.frame])
        self._show_aids()
        self.camera.follow_pair()

    def set_visible(self, key: str, visible: bool) -> None:
        self.visible[key] = bool(visible)
        shown = bool(visible) and (key in self.sequences or not self.sequences)
        self.figures[key].set_visible(shown)
        self.captions[key].SetVisibility(shown and self.layout == "side_by_side")
        if key == "synthesized":  # the pinned follower is a synthesized one too, as are its variations
            self.figures["pinned"].set_visible(shown and "pinned" in self.sequences)
            self.place_figures()
        self._show_aids()

    def set_layout(self, layout: str) -> None:
        if layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}")
        self.layout = layout
        self.place_figures()
        self._show_aids()
        self.camera.set(self.camera.preset)

    def place_figures(self) -> None:
        """Overlay: the canonical frame as is. Side by side: each figure on its own spot along X (along Z for the side
        camera, which looks along X and would stack them and their captions), the followers turned 180° about their
        first-frame root so that all three face the same way."""
        if not self.sequences:
            return
        top = float(max(s[..., 1].max() for s in self.sequences.values())) + 0.25
        along_z = self.camera.preset == "side"
        middle = (self.slots() - 1) / 2
        beside = [k for k in BESIDE_KEYS if k in self.sequences]  # variations, then other models' followers
        beside = [(len(CHARACTER_KEYS) + i, k) for i, k in enumerate(beside)]
        self.captions.set_base(caption_px(self.slots()))
        # seen from the top a caption over the head would be on the figure: it goes towards the top of the picture
        above = (0.0, 0.0, -TOP_CAPTION_OFFSET) if self.camera.preset == "top" else (0.0, 0.0, 0.0)
        for k in BESIDE_KEYS:
            if k not in self.sequences:
                self.figures[k].set_visible(False)
                self.captions[k].SetVisibility(False)
        for slot, k in (*enumerate(CHARACTER_KEYS), (2, "pinned"), *beside):  # the pinned one on the synthesized spot
            fig, cap = self.figures[k], self.captions.get(k)
            if k in BESIDE_KEYS:
                fig.set_visible(k in self.sequences and self.layout == "side_by_side" and self.visible["synthesized"])
            if k not in self.sequences or self.layout == "overlay":
                fig.place((0, 0, 0), (0, 0, 0), 0.0)
                if cap is not None:
                    cap.SetVisibility(False)
                continue
            root = self.sequences[k][0, self.skeleton.root]
            spot = (0.0, 0.0, (middle - slot) * SIDE_SPACING) if along_z else ((slot - middle) * SIDE_SPACING, 0.0, 0.0)  # left to right
            yaw = 0.0 if k == "leader" else 180.0
            fig.place((float(root[0]), 0.0, float(root[2])), (spot[0] - float(root[0]), 0.0, spot[2] - float(root[2])), yaw)
            if cap is not None:
                cap.position = (spot[0] + above[0], top, spot[2] + above[2])
                cap.SetVisibility(self.visible["synthesized" if k in BESIDE_KEYS else k])

    def shown(self, every_frame: bool = False) -> list[str]:
        """What the view shows: the figures of CHARACTER_KEYS and "pinned" that are drawn, then "contact" while limbs
        are drawn orange (at the current frame; `every_frame`: at any frame of the sequence)."""
        keys = [k for k in (*CHARACTER_KEYS, "pinned") if self.figures[k].actors[0].GetVisibility()]
        c = self.contact
        if every_frame:
            touching = c.enabled and c.flags is not None and any(bool(f.any()) for f in c.flags)
        else:
            touching = bool(c.actor.GetVisibility())
        return keys + ["contact"] * touching

    def slots(self) -> int:
        """Spots side by side: leader, ground truth, synthesized, its variations and other models' followers."""
        return len(CHARACTER_KEYS) + sum(k in self.sequences for k in BESIDE_KEYS)

    # ---- output -------------------------------------------------------------------------
    def render(self) -> None:
        self.render_window.Render()


def warm_up() -> None:
    """Pay PyVista's first-Plotter costs (its display check, the VTK modules it imports on first use: ~0.2 s) in the
    process that forks the studio processes. The throwaway Plotter is never rendered, so no OpenGL context exists
    before a fork."""
    pv.Plotter(off_screen=True).close()


def floor_height(leader: np.ndarray, follower: np.ndarray, skeleton: Skeleton) -> float:
    """Floor = low percentile of both characters' foot heights over the whole data set."""
    feet = [i for i, n in enumerate(skeleton.joint_names) if "foot" in n or "ankle" in n] or list(range(skeleton.num_joints))
    y = np.concatenate([leader[:, feet, skeleton.vertical_axis].ravel(), follower[:, feet, skeleton.vertical_axis].ravel()])
    return float(np.percentile(y, 1.0)) - 0.03
