"""Remote (server-side) rendering tweaks for trame-vtk. Import before the trame server starts.

LATENCY PATCH (the one place this project changes trame-vtk behaviour): trame-vtk's publish-based
image delivery waits a hard-coded 0.5 s (`delta_stale_time_before_render`) before re-sending a view
whose JPEG was not encoded yet when it was first asked for. Nearly every interactive update hits that
path, so slider -> new picture took ~550 ms. trame-vtk 2.11 offers no setting for it; we lower the
wait to STALE_WAIT_S for every image-delivery protocol this process creates. Measured effect in
docs/explorer.md.
"""

from __future__ import annotations

STALE_WAIT_S = 0.02
_patched = False


def patch_image_delivery(wait_s: float = STALE_WAIT_S) -> None:
    global _patched
    if _patched:
        return
    from trame_vtk.modules.vtk.protocols import publish_image_delivery as pid

    original_init = pid.vtkWebPublishImageDelivery.__init__

    def __init__(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        self.delta_stale_time_before_render = wait_s

    pid.vtkWebPublishImageDelivery.__init__ = __init__
    _patched = True
