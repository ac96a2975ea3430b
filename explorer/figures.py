"""The pieces of the 3D scene in plain VTK: stick figures (tubes and spheres around one persistent polydata whose
points are overwritten in place), the interpenetration overlay, and the helpers that build them (explorer/scene.py
puts them together)."""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
from vtkmodules.vtkFiltersCore import vtkGlyph3D, vtkTubeFilter
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper, vtkRenderer

from explorer.palette import WARNING, rgb
from imm_model.skeleton import Skeleton


def line_polydata(num_points: int) -> tuple[vtkPolyData, np.ndarray]:
    """Polydata of `num_points` points (no lines yet) and a numpy view of its coordinates: writes go straight to VTK."""
    poly = vtkPolyData()
    points = vtkPoints()
    points.SetData(numpy_to_vtk(np.zeros((num_points, 3), np.float32), deep=True))
    poly.SetPoints(points)
    poly.SetLines(vtkCellArray())
    return poly, vtk_to_numpy(points.GetData())


def set_lines(poly: vtkPolyData, segments) -> None:
    """Line cells between point pairs [(a, b), ...]."""
    cells = vtkCellArray()
    if len(segments):
        cells.SetData(numpy_to_vtkIdTypeArray(np.arange(0, 2 * len(segments) + 1, 2), deep=True),
                      numpy_to_vtkIdTypeArray(np.asarray(segments, np.int64).ravel(), deep=True))  # fmt: skip
    poly.SetLines(cells)
    poly.Modified()


def add_actor(renderer: vtkRenderer, source, color: str, *, ambient: float = 0.0, diffuse: float = 1.0,
              specular: float = 0.0, smooth: bool = False, lit: bool = True, wireframe: bool = False) -> vtkActor:
    """An actor for a VTK algorithm's output (filters re-run when their input changes) or for fixed polydata."""
    mapper = vtkPolyDataMapper()
    if isinstance(source, vtkPolyData):
        mapper.SetInputData(source)
    else:
        mapper.SetInputConnection(source.GetOutputPort())
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*rgb(color))
    prop.SetAmbient(ambient)
    prop.SetDiffuse(diffuse)
    prop.SetSpecular(specular)
    prop.SetSpecularPower(100.0)
    if smooth:
        prop.SetInterpolationToPhong()
    prop.SetLighting(lit)
    if wireframe:
        prop.SetRepresentationToWireframe()
    renderer.AddActor(actor)
    return actor


class StickFigure:
    """Bones as tubes and joints as spheres around one persistent polydata of J points."""

    def __init__(self, renderer: vtkRenderer, skeleton: Skeleton, color: str, bone_radius: float = 0.022, joint_radius: float = 0.034):
        self.poly, self._points = line_polydata(skeleton.num_joints)
        set_lines(self.poly, skeleton.bones)

        # 6-sided tubes and 8 x 6 spheres look the same at the view's scale as 10 sides and 12 x 10, and cost llvmpipe
        # ~3 ms less per full-size frame with three figures (docs/explorer.md, session 11)
        tube = vtkTubeFilter()
        tube.SetInputData(self.poly)
        tube.SetRadius(bone_radius)
        tube.SetNumberOfSides(6)
        tube.CappingOn()
        sphere = vtkSphereSource()
        sphere.SetRadius(joint_radius)
        sphere.SetThetaResolution(8)
        sphere.SetPhiResolution(6)
        glyph = vtkGlyph3D()
        glyph.SetInputData(self.poly)
        glyph.SetSourceConnection(sphere.GetOutputPort())
        glyph.ScalingOff()
        self.filters = (tube, glyph)
        kw = dict(ambient=0.3, diffuse=0.7, specular=0.25, smooth=True)
        self.actors = [add_actor(renderer, tube, color, **kw), add_actor(renderer, glyph, color, **kw)]

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

    def __init__(self, renderer: vtkRenderer, skeleton: Skeleton):
        self.bones = np.array(skeleton.bones)
        self.poly, self._points = line_polydata(2 * skeleton.num_joints)
        self.tube = vtkTubeFilter()
        self.tube.SetInputData(self.poly)
        self.tube.SetRadius(0.032)
        self.tube.SetNumberOfSides(10)
        self.actor = add_actor(renderer, self.tube, WARNING, ambient=0.4, diffuse=0.6)
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
