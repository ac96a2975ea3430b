"""The pieces of the 3D scene as PyVista meshes and actors: stick figures (tubes and spheres around one persistent
PyVista mesh whose points are overwritten in place), the interpenetration overlay, and the helpers that build them
(explorer/rendering/scene.py puts them together in a PyVista Plotter).

The tubes and spheres are VTK filters fed by the PyVista mesh (vtkTubeFilter, vtkGlyph3D), which the Plotter draws
as a pipeline: PyVista's own `tube()` and `glyph()` return a new mesh on every call, and a frame change here must
only move points, never rebuild geometry."""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.vtkFiltersCore import vtkGlyph3D, vtkTubeFilter

from explorer.rendering.palette import WARNING
from imm_model.skeleton import Skeleton


def line_mesh(num_points: int) -> pv.PolyData:
    """A PyVista mesh of `num_points` points and no cells yet; its `points` are written in place."""
    mesh = pv.PolyData(np.zeros((num_points, 3), np.float32))
    mesh.verts = np.empty(0, np.int64)  # PyVista gives bare points a vertex each: only lines are drawn here
    return mesh


def set_lines(mesh: pv.PolyData, segments) -> None:
    """Line cells between point pairs [(a, b), ...]."""
    pairs = np.asarray(segments, np.int64).reshape(-1, 2)
    mesh.lines = np.column_stack([np.full(len(pairs), 2), pairs]).ravel()


def add_actor(plotter: pv.Plotter, source, color: str, *, ambient: float = 0.0, diffuse: float = 1.0,
              specular: float = 0.0, smooth: bool = False, lit: bool = True) -> pv.Actor:
    """The Plotter's actor for a mesh, or for a VTK filter's output (re-run when its input mesh changes)."""
    actor = plotter.add_mesh(source, color=color, ambient=ambient, diffuse=diffuse, specular=specular, specular_power=100.0,
                             lighting=lit, reset_camera=False, render=False)  # fmt: skip
    if smooth:  # the filters give normals: Phong shading without PyVista's extra normals pass
        actor.prop.interpolation = "phong"
    return actor


class StickFigure:
    """Bones as tubes and joints as spheres around one persistent polydata of J points."""

    def __init__(self, plotter: pv.Plotter, skeleton: Skeleton, color: str, bone_radius: float = 0.022, joint_radius: float = 0.034):
        self.poly = line_mesh(skeleton.num_joints)
        set_lines(self.poly, skeleton.bones)
        self._points = self.poly.points  # a view of the mesh's VTK points: writes go straight to VTK

        # 6-sided tubes and 8 x 6 spheres look the same at the view's scale as 10 sides and 12 x 10, and cost llvmpipe
        # ~3 ms less per full-size frame with three figures (docs/experiments/studio-performance.md)
        tube = vtkTubeFilter()
        tube.SetInputData(self.poly)
        tube.SetRadius(bone_radius)
        tube.SetNumberOfSides(6)
        tube.CappingOn()
        glyph = vtkGlyph3D()
        glyph.SetInputData(self.poly)
        glyph.SetSourceData(pv.Sphere(radius=joint_radius, theta_resolution=8, phi_resolution=6))
        glyph.ScalingOff()
        self.filters = (tube, glyph)
        kw = dict(ambient=0.3, diffuse=0.7, specular=0.25, smooth=True)
        self.actors = [add_actor(plotter, tube, color, **kw), add_actor(plotter, glyph, color, **kw)]

    def set_pose(self, joints: np.ndarray) -> None:
        self._points[:] = joints
        self.poly.GetPoints().Modified()

    def set_visible(self, visible: bool) -> None:
        for a in self.actors:
            a.SetVisibility(bool(visible))

    def place(self, origin: tuple[float, float, float], position: tuple[float, float, float], yaw_deg: float) -> None:
        for a in self.actors:
            a.SetOrigin(*origin)
            a.SetOrientation(0.0, yaw_deg, 0.0)
            a.SetPosition(*position)


class ContactOverlay:
    """The bones of the leader and the synthesized follower that interpenetrate at the current frame, as thicker
    tubes in the warning colour over both figures (overlay layout only: side by side the bodies are apart)."""

    def __init__(self, plotter: pv.Plotter, skeleton: Skeleton):
        self.bones = np.array(skeleton.bones)
        self.poly = line_mesh(2 * skeleton.num_joints)
        self._points = self.poly.points
        self.tube = vtkTubeFilter()
        self.tube.SetInputData(self.poly)
        self.tube.SetRadius(0.032)
        self.tube.SetNumberOfSides(10)
        self.actor = add_actor(plotter, self.tube, WARNING, ambient=0.4, diffuse=0.6)
        self.flags: tuple[np.ndarray, np.ndarray] | None = None  # (T, K) bones of the leader and of the follower
        self.enabled = True

    def show(self, leader: np.ndarray, follower: np.ndarray, frame: int) -> None:
        if self.flags is None or not self.enabled:
            self.actor.SetVisibility(False)
            return
        j = len(leader[frame])
        bad_a, bad_b = (f[min(frame, len(f) - 1)] for f in self.flags)
        segments = [(p, c) for p, c in self.bones[bad_a]] + [(j + p, j + c) for p, c in self.bones[bad_b]]
        self.actor.SetVisibility(bool(segments))
        if segments:
            self._points[:j], self._points[j:] = leader[frame], follower[min(frame, len(follower) - 1)]
            self.poly.GetPoints().Modified()
            set_lines(self.poly, segments)


class Trail:
    """Ghosts of one figure's last frames (`steps` frames back), as thin lines in its colour, fading: the motion's path
    at a glance. Lines only (no tubes, no spheres): a few hundred segments cost llvmpipe next to nothing."""

    def __init__(self, plotter: pv.Plotter, skeleton: Skeleton, color: str, steps: tuple[int, ...] = (2, 4, 6, 8)):
        self.steps, self.joints = steps, skeleton.num_joints
        self.poly = line_mesh(len(steps) * self.joints)
        set_lines(self.poly, [(g * self.joints + a, g * self.joints + b) for g in range(len(steps)) for a, b in skeleton.bones])
        self._points = self.poly.points
        self.actor = add_actor(plotter, self.poly, color, lit=False)
        self.actor.prop.opacity = 0.35
        self.actor.prop.line_width = 2.0
        self.actor.SetVisibility(False)

    def show(self, sequence: np.ndarray | None, frame: int, visible: bool) -> None:
        """The ghosts of `sequence` before `frame` (frame 0's pose where there is no earlier one); hidden if not `visible`."""
        if sequence is None or not visible:
            self.actor.SetVisibility(False)
            return
        for g, step in enumerate(self.steps):
            self._points[g * self.joints:(g + 1) * self.joints] = sequence[max(0, min(frame, len(sequence) - 1) - step)]
        self.poly.GetPoints().Modified()
        self.actor.SetVisibility(True)
