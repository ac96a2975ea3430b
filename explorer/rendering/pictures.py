"""The scene's view as images: the picture on screen now, and every frame of the sequence (exports)."""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter


def screenshot(scene) -> np.ndarray:
    """(H, W, 3) uint8 of `scene`'s (scene.py Scene) current view."""
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


def frames(scene, start: int = 0) -> list[np.ndarray]:
    """Every frame of the scene's sequence as an image; the current frame is restored afterwards."""
    keep = scene.frame
    images = []
    for f in range(start, len(scene.sequences["leader"])):
        scene.set_frame(f)
        images.append(screenshot(scene))
    scene.set_frame(keep)
    return images
