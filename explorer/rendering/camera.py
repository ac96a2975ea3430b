"""The 3D scene's camera: presets that frame every frame of the figures shown, a camera that follows the pair, and
which joint is drawn under a point of the view."""

from __future__ import annotations

import numpy as np

CAMERA_PRESETS = ("default", "front", "side", "top")
SIDE_SPACING = 1.5  # metres between figures in the side-by-side layout
TOP_CAPTION_OFFSET = 0.8  # metres towards the top of the picture, for the top camera (above each figure, not on it)
HAND = "hand"  # the camera's name once dragged or zoomed by hand: the link carries its placement (`placement`)
PLACEMENT_RANGE_M = 100.0  # a hand-placed camera's coordinates in a link lie within this many metres of the origin
HOVER_REACH_PX = 14  # a joint is under the mouse within this many pixels of its centre
PAIR_KEYS = ("leader", "synthesized")  # the figures whose centre a following camera keeps in view


class SceneCamera:
    def __init__(self, scene) -> None:
        """The camera of `scene` (scene.py Scene): it reads the figures, their layout and the frame from it."""
        self.scene = scene
        self.preset = "default"
        self.fitted_size: tuple[int, int] = (0, 0)
        self.follow = False  # the camera follows the pair (set_follow): moved by the pair's centre from frame to frame
        self._followed: np.ndarray | None = None  # the pair's centre the camera was last placed for
        # The browser sizes the view when it likes (first load, window resize); every render at a new size refits
        # the preset, so the same view in two tabs of the same size is the same picture.
        scene.renderer.AddObserver("StartEvent", lambda *_: self._refit_if_resized())

    def set(self, preset: str = "default") -> None:
        """Look at the figures from a preset direction, at the distance that fits all their frames."""
        scene = self.scene
        if preset not in CAMERA_PRESETS:
            raise ValueError(f"camera preset must be one of {CAMERA_PRESETS}")
        self.preset = preset
        if scene.layout == "side_by_side":  # the side camera has the figures apart along another axis
            scene.place_figures()
        self.fitted_size = tuple(scene.render_window.GetSize())
        box = self._points_of_interest()
        center = (box.min(0) + box.max(0)) / 2
        direction = {
            "default": (0.75, 0.38, 0.55) if scene.layout == "overlay" else (0.25, 0.3, 1.0),
            "front": (0.0, 0.12, 1.0),  # along the leader's facing direction (+Z)
            "side": (1.0, 0.12, 0.0),  # profile of both characters: the paper's view
            "top": (0.0, 1.0, 0.001),
        }[preset]
        d = np.asarray(direction, float)
        d /= np.linalg.norm(d)
        up = np.array([0.0, 0.0, -1.0]) if preset == "top" else np.array([0.0, 1.0, 0.0])
        right = np.cross(up, d)
        right /= np.linalg.norm(right)
        up = np.cross(d, right)
        rel = box - center
        half_w, half_h = np.abs(rel @ right).max(), np.abs(rel @ up).max()
        depth = np.abs(rel @ d).max()
        w, h = scene.render_window.GetSize()
        aspect = max(w, 1) / max(h, 1)
        view_angle = 30.0
        t = np.tan(np.radians(view_angle / 2))
        dist = 1.08 * max(half_h / t, half_w / (t * aspect)) + depth
        cam = scene.renderer.GetActiveCamera()
        cam.SetFocalPoint(*center)
        cam.SetPosition(*(center + d * dist))
        cam.SetViewUp(*up)
        cam.SetViewAngle(view_angle)
        scene.renderer.ResetCameraClippingRange()
        if self.follow:  # the preset framed every frame: following moves on from here
            self._followed = self._pair_centre()

    def _refit_if_resized(self) -> None:
        if self.preset != HAND and self.scene.sequences and tuple(self.scene.render_window.GetSize()) != self.fitted_size:
            self.set(self.preset)

    # ---- a camera placed by hand ------------------------------------------------------------
    def moved_by_hand(self) -> None:
        """The user dragged or zoomed the view: the camera is theirs (a resize no longer refits a preset)."""
        self.preset = HAND
        if self.follow:
            self._followed = self._pair_centre()

    def placement(self) -> str:
        """The camera as the link spells it: a preset's name, or a hand-placed camera as `hand:` and its position, focal
        point and view-up, nine numbers (millimetres and thousandths)."""
        if self.preset != HAND:
            return self.preset
        cam = self.scene.renderer.GetActiveCamera()
        numbers = (*cam.GetPosition(), *cam.GetFocalPoint(), *cam.GetViewUp())
        return HAND + ":" + ",".join(f"{round(v, 3) + 0.0:g}" for v in numbers)

    def place(self, text: str) -> None:
        """A placement (`placement`) -> the camera there; a preset's name sets the preset."""
        if not text.startswith(HAND + ":"):
            self.set(text)
            return
        position, focal, up = hand_placement(text)
        cam = self.scene.renderer.GetActiveCamera()
        cam.SetPosition(*position)
        cam.SetFocalPoint(*focal)
        cam.SetViewUp(*up)
        self.scene.renderer.ResetCameraClippingRange()
        self.moved_by_hand()

    def _points_of_interest(self) -> np.ndarray:
        """Corners of the box the camera must show: all frames of the figures as placed."""
        scene = self.scene
        if scene.layout == "side_by_side" or not scene.sequences:
            half = (scene.slots() - 1) / 2 * SIDE_SPACING + 0.6
            depth = TOP_CAPTION_OFFSET + 0.2 if self.preset == "top" else 0.6  # room for the captions (Scene.place_figures)
            spread = [half, 0.0, depth][:: -1 if self.preset == "side" else 1]  # along X, or Z (Scene.place_figures)
            lo = np.array([-spread[0], scene.floor_y, -spread[2]])
            hi = np.array([spread[0], scene.floor_y + 2.0, spread[2]])
        else:
            pts = np.concatenate([s.reshape(-1, 3) for s in scene.sequences.values()])
            lo, hi = pts.min(0), pts.max(0)
            lo[1] = min(lo[1], scene.floor_y)
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])

    # ---- following the pair ---------------------------------------------------------------
    def set_follow(self, on: bool) -> None:
        """The camera follows the pair: from frame to frame it moves with the centre of the leader's and the synthesized
        follower's roots (on the floor's plane; the user's turn and zoom are kept)."""
        self.follow = bool(on)
        self._followed = self._pair_centre() if on else None

    def lost_pair(self) -> None:
        """A new sequence: following starts again from its first frame."""
        self._followed = None

    def follow_pair(self) -> None:
        """After a frame change: a following camera moves by the pair's move."""
        if not self.follow:
            return
        centre = self._pair_centre()
        if centre is not None and self._followed is not None:
            cam = self.scene.renderer.GetActiveCamera()
            cam.SetFocalPoint(*(np.asarray(cam.GetFocalPoint()) + centre - self._followed))
            cam.SetPosition(*(np.asarray(cam.GetPosition()) + centre - self._followed))
            self.scene.renderer.ResetCameraClippingRange()
        self._followed = centre

    def _pair_centre(self) -> np.ndarray | None:
        scene = self.scene
        roots = [seq[min(scene.frame, len(seq) - 1), scene.skeleton.root] for k, seq in scene.sequences.items() if k in PAIR_KEYS]
        if not roots:
            return None
        centre = np.mean(roots, axis=0).astype(float)
        centre[1] = 0.0  # along the floor only: the camera does not bob with the bodies
        return centre

    # ---- picking --------------------------------------------------------------------------
    def joint_at(self, x: float, y: float, reach_px: float = HOVER_REACH_PX) -> tuple[str, int] | None:
        """The joint drawn nearest to the view's point (x, y), fractions of its width and height from the top left, within
        `reach_px` pixels: (figure key, joint index), or None. Figures in front win ties (the nearer to the camera)."""
        scene = self.scene
        width, height = scene.render_window.GetSize()
        px, py = x * width, (1.0 - y) * height  # VTK's display y grows upwards
        best, best_key = None, None
        for key, seq in scene.sequences.items():
            actor = scene.figures[key].actors[0]
            if not actor.GetVisibility():
                continue
            matrix = actor.GetMatrix()
            for j, point in enumerate(seq[min(scene.frame, len(seq) - 1)]):
                scene.renderer.SetWorldPoint(*matrix.MultiplyPoint((*map(float, point), 1.0))[:3], 1.0)
                scene.renderer.WorldToDisplay()
                dx, dy, depth = scene.renderer.GetDisplayPoint()
                gap = float(np.hypot(dx - px, dy - py))
                if gap <= reach_px and (best is None or (gap, depth) < best):
                    best, best_key = (gap, depth), (key, j)
        return best_key


def hand_placement(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """"hand:px,py,pz,fx,fy,fz,ux,uy,uz" -> position, focal point, view-up; ValueError (one line) for anything else:
    not nine finite numbers within PLACEMENT_RANGE_M, the position on the focal point, a view-up of zero or along
    the view."""
    body = text[len(HAND) + 1:] if text.startswith(HAND + ":") else ""
    try:
        values = np.array([float(v) for v in body.split(",")])
    except ValueError:
        values = np.zeros(0)
    if values.shape != (9,) or not np.isfinite(values).all() or np.abs(values).max() > PLACEMENT_RANGE_M:
        raise ValueError(f"a hand-placed camera is {HAND}: and nine numbers within {PLACEMENT_RANGE_M:g} m")
    position, focal, up = values[:3], values[3:6], values[6:]
    view = focal - position
    if np.linalg.norm(view) < 1e-3 or np.linalg.norm(np.cross(view, up)) < 1e-6:
        raise ValueError("a hand-placed camera needs its position off its focal point and a view-up across the view")
    return position, focal, up
