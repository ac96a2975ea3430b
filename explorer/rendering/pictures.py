"""The scene's view as images: the picture on screen now, and every frame of the sequence (exports), at the view's
size or at a size of their own."""

from __future__ import annotations

import contextlib

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter


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
        grab = vtkWindowToImageFilter()
        grab.SetInput(scene.render_window)
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
