"""The chart under the view: each frame's error and contact (the default), or the distance between two joints or the
speed of one that the user picks above it; and the frames of contact, marked on the timeline."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from explorer.rendering import charts
from explorer.session.files import FPS
from explorer.session.joint_plot import JointPlot

if TYPE_CHECKING:
    from explorer.ui.panel_api import Page

DEFAULT_PICK = {"plot_kind": "", "plot_a": "A.right_hand", "plot_b": "B.right_hand", "plot_joint": "B.right_hand"}


def picked_plot(state, joint_names) -> JointPlot | None:
    """The quantity the page's picker names, None for the default chart (or a crafted pick that names none)."""
    joints = {"distance": f":{state.plot_a}:{state.plot_b}", "speed": f":{state.plot_joint}"}.get(state.plot_kind)
    try:
        return JointPlot.parse(f"{state.plot_kind}{joints}", joint_names) if joints else None
    except ValueError:
        return None


def pick_state(plot: JointPlot) -> dict:
    """The picker's state that names `plot` (a link's plot put back on the picker)."""
    if plot.kind == "speed":
        return {"plot_kind": "speed", "plot_joint": plot.joints[0]}
    return {"plot_kind": "distance", "plot_a": plot.joints[0], "plot_b": plot.joints[1]}


class ChartPanel:
    def __init__(self, page: Page, *, write_url: Callable[[], None]):
        """`write_url()` puts the view, with the plot picked, into the page's address bar."""
        self.page, self.write_url = page, write_url
        self._default = (np.zeros(0), np.zeros(0), np.zeros(0))  # the default chart's lines, kept for a pick undone
        page.state.update({**DEFAULT_PICK, "contact_marks": []})
        page.state.change(*DEFAULT_PICK)(self.on_plot_picked)

    def draw(self, distances: np.ndarray, ab_distances: np.ndarray, closest: np.ndarray) -> None:
        """The chart of the follower drawn now, from the session's distances (app.py reads them once per follower),
        and its contact frames on the timeline."""
        self._default = (distances, ab_distances, closest)
        self.page.state.contact_marks = charts.contact_frames(closest)
        self._draw()

    def on_plot_picked(self, **_) -> None:
        self._draw()
        self.write_url()

    def _draw(self) -> None:
        ses, (distances, ab_distances, closest) = self.page.session, self._default
        plot = picked_plot(self.page.state, ses.data.skeleton.joint_names)
        self.page.state.distance_chart = (charts.distance_chart(distances, FPS, ab_distances, closest) if plot is None
                                          else charts.joint_chart(plot.series(ses), FPS, plot.unit))
