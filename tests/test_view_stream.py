"""explorer/rendering/view_stream.py's PictureGate: at most one picture on its way to the page, the latest held back
until the page reports the one before shown (or a timeout), and playback's wait for its picture to be encoded.
No trame server: the gate is given stand-in send() callables."""

from __future__ import annotations

import asyncio

import pytest

pytest.importorskip("trame_rca")

from explorer.rendering.view_stream import PictureGate  # noqa: E402


def picture(sent: list, name: str):
    return lambda: sent.append(name)


def test_one_picture_in_flight_and_the_latest_held_back_goes_when_the_page_shows_it():
    async def run():
        gate, sent = PictureGate(timeout_s=10), []
        gate.deliver(picture(sent, "a"))  # nothing in flight: goes at once
        gate.deliver(picture(sent, "b"))  # a not shown yet: held
        gate.deliver(picture(sent, "c"))  # replaces b (the latest wins)
        assert sent == ["a"] and gate.in_flight
        gate.shown()  # the page showed a: c goes, b never
        assert sent == ["a", "c"] and gate.in_flight and gate.held is None
        gate.shown()
        assert not gate.in_flight
        gate.deliver(picture(sent, "d"))  # nothing in flight again: at once
        return sent, gate

    sent, gate = asyncio.run(run())
    assert sent == ["a", "c", "d"] and (gate.sent, gate.shown_count, gate.replaced) == (3, 2, 1)


async def until(condition, timeout_s: float = 60.0) -> None:
    """Poll `condition()` on the running loop until it holds (a generous deadline: a busy 2-core machine)."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not condition():
        assert loop.time() < deadline, "the condition never held"
        await asyncio.sleep(0.01)


def test_a_picture_never_reported_shown_holds_the_next_only_until_the_timeout():
    async def run():
        gate, sent = PictureGate(timeout_s=0.05), []
        gate.deliver(picture(sent, "a"))
        gate.deliver(picture(sent, "b"))
        held_then = list(sent)  # the timeout cannot have fired: the loop has not run since
        await until(lambda: len(sent) == 2)  # no acknowledgement (a hidden tab): b goes after the timeout
        return held_then, sent

    held_then, sent = asyncio.run(run())
    assert held_then == ["a"] and sent == ["a", "b"]


def test_playback_waits_for_its_picture_encoded_not_for_the_one_before_to_be_shown():
    async def run():
        gate, sent = PictureGate(timeout_s=10), []
        await asyncio.wait_for(gate.wait_encoded(), 60)  # nothing asked for: no wait
        gate.asked()
        waiter = asyncio.ensure_future(gate.wait_encoded())
        await asyncio.sleep(0)  # one turn of the loop: the waiter runs up to its wait
        waiting = not waiter.done()
        gate.deliver(picture(sent, "a"))
        await asyncio.wait_for(waiter, 60)
        gate.asked()
        gate.deliver(picture(sent, "b"))  # held (a is not shown) but encoded: the next frame may render meanwhile
        await asyncio.wait_for(gate.wait_encoded(), 60)
        return waiting, sent

    waiting, sent = asyncio.run(run())
    assert waiting and sent == ["a"]


def test_playback_sets_no_new_frame_until_the_last_ones_picture_is_encoded(monkeypatch):
    """explorer/ui/playback.py over a stand-in studio (synthetic: a 1000-frame session, 2x): while the view has not
    encoded the picture of the frame just set, playback sets no other; once it has, playback goes on."""
    from types import SimpleNamespace

    from explorer.ui import playback
    from explorer.ui.playback import play

    monkeypatch.setattr(playback, "ENCODED_TIMEOUT_S", 10.0)  # the wait below is not a lost picture

    class State(SimpleNamespace):
        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    async def run():
        encoded = asyncio.Event()
        studio = SimpleNamespace(state=State(frame=0, playing=True, speed=2.0, loop=False),
                                 session=SimpleNamespace(num_frames=1000), frames=[])

        async def picture_encoded():
            studio.frames.append(studio.state.frame)
            await encoded.wait()
            return True

        studio.picture_encoded = picture_encoded
        task = asyncio.ensure_future(play(studio))
        await until(lambda: studio.frames)  # the first frame set: playback waits for its picture
        await asyncio.sleep(0.3)  # 9 frames' time at 2x, in which it must set no other
        blocked = list(studio.frames)
        encoded.set()
        await until(lambda: len(studio.frames) >= 4)
        studio.state.playing = False
        await asyncio.wait_for(task, 60)
        return blocked, studio.frames

    blocked, frames = asyncio.run(run())
    assert len(blocked) == 1 and len(frames) >= 4 and frames == sorted(frames), (blocked, frames)


def test_the_view_is_at_rest_once_the_still_picture_after_the_last_ask_is_shown():
    """PictureGate.at_rest(), what the browser tests wait for after an action (tests/studio_probe.py)."""
    async def run():
        gate, sent, rest = PictureGate(timeout_s=10), [], []
        gate.asked()
        rest.append(gate.at_rest())  # asked, nothing encoded yet
        gate.deliver(picture(sent, "interactive"), still=False)
        gate.deliver(picture(sent, "still"), still=True)  # held: the interactive one is not shown yet
        rest.append(gate.at_rest())
        gate.shown()  # the interactive one: the still one goes
        rest.append(gate.at_rest())
        gate.shown()
        rest.append(gate.at_rest())
        gate.asked()  # the next change
        rest.append(gate.at_rest())
        return rest, sent

    rest, sent = asyncio.run(run())
    assert rest == [False, False, False, True, False] and sent == ["interactive", "still"]


def test_captions_keep_their_size_in_a_picture_drawn_smaller_while_playing(sample_data):
    """Playback's pictures are drawn at a fraction of the view and stretched by the page: their captions are drawn at
    that fraction too, so that they show the same size playing or paused (they grew 1.7x and piled up)."""
    from explorer.rendering.scene import Scene
    from explorer.rendering.view_stream import texts_scaled

    scene = Scene(sample_data.skeleton, 0.0)
    try:
        scene.set_layout("side_by_side")
        sizes = {k: c.GetTextProperty().GetFontSize() for k, c in scene.captions.items()}
        with texts_scaled(scene.render_window, 0.6):
            assert {k: c.GetTextProperty().GetFontSize() for k, c in scene.captions.items()} == \
                {k: max(1, round(v * 0.6)) for k, v in sizes.items()}
        assert {k: c.GetTextProperty().GetFontSize() for k, c in scene.captions.items()} == sizes
    finally:
        scene.close()
