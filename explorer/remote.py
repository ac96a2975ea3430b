"""Remote (server-side) rendering tweaks for trame-vtk. Import before the trame server starts.

LATENCY PATCH (the one place this project changes trame-vtk behaviour): trame-vtk's publish-based
image delivery waits a hard-coded 0.5 s (`delta_stale_time_before_render`) before re-sending a view
whose JPEG was not encoded yet when it was first asked for. Nearly every interactive update hits that
path, so slider -> new picture took ~550 ms. trame-vtk 2.11 offers no setting for it; we lower the
wait to STALE_WAIT_S for every image-delivery protocol this process creates. Measured effect in
docs/explorer.md.

Same place, second fix: when the JPEG is still not ready at the retry, trame-vtk's retry asks for
`delta >= wait * (retries + 1)` while it was scheduled after `wait`, so a second miss in a row never
re-sends and the browser keeps the previous picture (seen under CPU load: the slider moved, the
picture did not). The retry below re-sends every `wait` until the image is ready (at most
STALE_RETRIES times).
"""

from __future__ import annotations

STALE_WAIT_S = 0.005
STALE_RETRIES = 400  # 2 s of retries at 5 ms
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

    def render_stale_image(self, v_id, stale_count=0):
        if self.stale_handler_count.get(v_id, 0) > 0:
            self.stale_handler_count[v_id] -= 1
        if self.last_stale_time.get(v_id, 0) != 0 and stale_count < STALE_RETRIES:
            self.push_render(v_id, False, stale_count + 1)

    pid.vtkWebPublishImageDelivery.__init__ = __init__
    pid.vtkWebPublishImageDelivery.render_stale_image = render_stale_image
    _patched = True
