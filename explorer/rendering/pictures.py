"""The scene's view as images: the picture on screen now, and every frame of the sequence (exports), at the view's
size or at a size of their own; and small still pictures of a leader and a follower (Thumbnails: the variations
gallery)."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

from explorer.rendering.figures import StickFigure
from explorer.rendering.palette import CHARACTERS
from explorer.rendering.scene import BACKGROUND
from imm_model.skeleton import Skeleton

THUMBNAIL_SIZE = (208, 156)  # four in a row of the gallery at 1280x720
THUMBNAIL_DIRECTION = (0.75, 0.38, 0.55)  # from where the overlay's default camera looks (explorer/rendering/camera.py)


@contextlib.contextmanager
def sized(scene, size: tuple[int, int] | None):
    """The scene's window at `size` (width, height) meanwhile; None: at the view's size. The camera refits a preset to
    that size (explorer/rendering/camera.py) and the captions fit it, and both do again at the view's next render."""
    if size is None:
        yield
        return
    keep = scene.render_window.GetSize()
    scene.render_window.SetSize(*size)
    try:
        yield
    finally:
        scene.render_window.SetSize(*keep)


def screenshot(scene, size: tuple[int, int] | None = None) -> np.ndarray:
    """(H, W, 3) uint8 of `scene`'s (scene.py Scene) current view, at `size` (width, height; None: the view's)."""
    with sized(scene, size):
        scene.render()
        return _grab(scene.render_window)


def _grab(render_window) -> np.ndarray:
    """(H, W, 3) uint8 of what `render_window` rendered last."""
    grab = vtkWindowToImageFilter()
    grab.SetInput(render_window)
    grab.ReadFrontBufferOff()
    grab.ShouldRerenderOff()
    grab.Update()
    image = grab.GetOutput()
    w, h, _ = image.GetDimensions()
    pixels = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)
    return np.ascontiguousarray(pixels[::-1, :, :3])  # VTK's rows go bottom to top


def frames(scene, start: int = 0, size: tuple[int, int] | None = None) -> list[np.ndarray]:
    """Every frame of the scene's sequence as an image (at `size`, as screenshot); the current frame is restored
    afterwards."""
    keep = scene.frame
    images = []
    with sized(scene, size):
        for f in range(start, len(scene.sequences["leader"])):
            scene.set_frame(f)
            images.append(screenshot(scene))
    scene.set_frame(keep)
    return images


class Thumbnails:
    """Still pictures of a leader and a follower at one frame, overlaid as in the view, in a small off-screen Plotter of
    their own: the view's scene, its camera and its stream stay untouched."""

    def __init__(self, skeleton: Skeleton, size: tuple[int, int] = THUMBNAIL_SIZE):
        self.plotter = pv.Plotter(off_screen=True, window_size=size, lighting="none")
        self.plotter.add_light(pv.Light(light_type="headlight"))
        self.plotter.set_background(BACKGROUND)
        self.plotter.render_window.SetMultiSamples(0)
        self.figures = [StickFigure(self.plotter, skeleton, CHARACTERS[k]) for k in ("leader", "synthesized")]

    def jpeg(self, leader: np.ndarray, follower: np.ndarray) -> bytes:
        """The two poses (J, 3) each, framed together, as JPEG bytes."""
        from PIL import Image

        for figure, pose in zip(self.figures, (leader, follower), strict=True):
            figure.set_pose(pose)
        points = np.concatenate([leader, follower])
        lo, hi = points.min(0) - 0.15, points.max(0) + 0.15
        camera = self.plotter.renderer.GetActiveCamera()
        camera.SetFocalPoint(*((lo + hi) / 2))
        camera.SetPosition(*((lo + hi) / 2 + THUMBNAIL_DIRECTION))
        camera.SetViewUp(0.0, 1.0, 0.0)
        self.plotter.renderer.ResetCamera(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
        camera.Zoom(1.4)  # ResetCamera fits the box's bounding sphere: the bodies filled half the picture
        self.plotter.render_window.Render()
        out = io.BytesIO()
        Image.fromarray(_grab(self.plotter.render_window)).save(out, format="JPEG", quality=85)
        return out.getvalue()

    def close(self) -> None:
        self.plotter.close()
