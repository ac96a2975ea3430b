"""The PyVista scene off screen: poses move points in place; layouts, visibility and camera presets."""

from __future__ import annotations

import io

import numpy as np
import pytest

pytest.importorskip("pyvista")

from explorer.rendering.pictures import frames, screenshot  # noqa: E402 - after the skip: it imports VTK


@pytest.fixture(scope="module")
def scene(sample_data):
    from explorer.rendering.scene import Scene, floor_height

    sc = Scene(sample_data.skeleton, floor_height(sample_data.leader, sample_data.follower, sample_data.skeleton), (320, 240))
    leader, follower = sample_data.canonical(0)
    sc.set_sequence(leader, follower, follower + np.float32([0.0, 0.0, 0.3]))
    sc.camera.set("default")
    yield sc
    sc.close()


def _count(img, hex_color):
    from tests.studio_probe import color_mask

    return int(color_mask(img, hex_color).sum())


def test_frame_moves_points_in_place(scene, sample_data):
    fig = scene.figures["leader"]
    actors = [id(a) for a in scene.renderer.GetActors()]
    points_before = fig.poly.GetPoints()
    scene.set_frame(5)
    from vtkmodules.util.numpy_support import vtk_to_numpy

    np.testing.assert_allclose(vtk_to_numpy(fig.poly.GetPoints().GetData()), sample_data.canonical(0)[0][5], atol=1e-6)
    assert fig.poly.GetPoints() is points_before  # same VTK array, only its values changed
    scene.set_frame(10_000)  # clamped
    assert scene.frame == int(sample_data.lengths[0]) - 1
    assert [id(a) for a in scene.renderer.GetActors()] == actors  # nothing rebuilt


def test_three_colors_visible_and_hideable(scene):
    from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED

    img = screenshot(scene)
    assert all(_count(img, c) > 50 for c in (LEADER, GROUND_TRUTH, SYNTHESIZED))
    scene.set_visible("synthesized", False)
    assert _count(screenshot(scene), SYNTHESIZED) < 20
    scene.set_visible("synthesized", True)


def test_layouts_and_cameras(scene):
    from explorer.rendering.camera import CAMERA_PRESETS

    overlay = screenshot(scene)
    scene.set_layout("side_by_side")
    assert scene.captions["leader"].GetVisibility()
    assert not np.array_equal(overlay, screenshot(scene))
    scene.set_layout("overlay")
    assert not scene.captions["leader"].GetVisibility()
    shots = []
    for preset in CAMERA_PRESETS:
        scene.camera.set(preset)
        shots.append(screenshot(scene))
    assert len({s.tobytes() for s in shots}) == len(CAMERA_PRESETS)
    with pytest.raises(ValueError):
        scene.set_layout("grid")


def test_export_frames(scene):
    keep = scene.frame
    images = frames(scene)
    assert len(images) == len(scene.sequences["leader"]) and images[0].shape[2] == 3
    assert scene.frame == keep


def test_the_scene_is_made_of_pyvista_objects(scene):
    import pyvista as pv

    assert isinstance(scene.plotter, pv.Plotter) and scene.render_window is scene.plotter.render_window
    assert all(isinstance(f.poly, pv.PolyData) and all(isinstance(a, pv.Actor) for a in f.actors) for f in scene.figures.values())
    assert isinstance(scene.captions["leader"], pv.Label) and isinstance(scene.floor, pv.Actor)
    assert scene.figures["leader"].poly.n_verts == 0 and scene.figures["leader"].poly.n_lines == len(scene.skeleton.bones)


def test_side_by_side_figures_and_captions_stay_apart_from_every_camera(scene):
    """The three figures stand left to right (leader, ground truth, synthesized) with their captions apart, also for
    the side camera, which looks along the axis they stand on in the other views."""
    from explorer.rendering.camera import CAMERA_PRESETS
    from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED
    from tests.studio_probe import color_mask

    scene.set_layout("side_by_side")
    try:
        for preset in ("front", "side", "default"):
            scene.camera.set(preset)
            img = screenshot(scene)
            centres = [np.flatnonzero(color_mask(img, c).any(0)).mean() for c in (LEADER, GROUND_TRUTH, SYNTHESIZED)]
            assert np.all(np.diff(centres) > 0.15 * img.shape[1]), (preset, centres)
            captions = []
            for key in ("leader", "ground_truth", "synthesized"):
                scene.renderer.SetWorldPoint(*scene.captions[key].position, 1.0)
                scene.renderer.WorldToDisplay()
                captions.append(scene.renderer.GetDisplayPoint()[0])
            assert np.all(np.diff(captions) > 0.15 * img.shape[1]), (preset, captions)
        assert set(CAMERA_PRESETS) >= {"front", "side", "default"}
    finally:
        scene.set_layout("overlay")
        scene.camera.set("default")


def test_variations_stand_right_of_the_synthesized_follower_with_their_seeds(scene):
    """A stochastic model's further followers: side by side only, each on its own spot and captioned with its seed;
    a turned camera stays while their number does not change; a deterministic model's follower brings the three
    figures back."""
    from explorer.rendering.palette import CHARACTER_TITLES
    from explorer.rendering.scene import VARIATION_KEYS

    followers = [scene.sequences["synthesized"] + np.float32([dx, 0.0, 0.0]) for dx in (0.0, 0.2, 0.4)]
    scene.set_variations(followers, [7, 8, 9])
    assert not any(scene.figures[k].actors[0].GetVisibility() for k in VARIATION_KEYS)  # overlay: the three figures only
    scene.set_layout("side_by_side")
    try:
        shown = [k for k in VARIATION_KEYS if scene.figures[k].actors[0].GetVisibility()]
        assert shown == ["variation_1", "variation_2"]
        assert [scene.captions[k].input for k in ("synthesized", *shown)] == [f"{CHARACTER_TITLES['synthesized']}\nseed 7",
                                                                            "seed 8", "seed 9"]
        xs = [scene.captions[k].position[0] for k in ("leader", "ground_truth", "synthesized", *shown)]
        assert np.all(np.diff(xs) > 1.0), xs  # five spots, left to right
        camera = scene.renderer.GetActiveCamera()
        camera.Azimuth(30)
        turned = camera.GetPosition()
        scene.set_variations(followers, [7, 8, 9])  # a new mix, as many followers: the user's camera stays
        assert camera.GetPosition() == turned
        scene.set_variations(followers[:1], None)
        assert not any(scene.figures[k].actors[0].GetVisibility() for k in VARIATION_KEYS)
        assert scene.captions["synthesized"].input == CHARACTER_TITLES["synthesized"] and camera.GetPosition() != turned
    finally:
        scene.set_layout("overlay")
        scene.camera.set("default")


def test_other_models_followers_stand_right_of_the_variations_captioned_and_follow_the_frame(scene):
    """Other models' followers: side by side only, right of the synthesized follower and its variations, each in its
    own colour under its own caption, on the same timeline; the synthesized follower's caption names its model."""
    from explorer.rendering.palette import CHARACTER_TITLES, COMPARED
    from explorer.rendering.scene import COMPARED_KEYS

    synth = scene.sequences["synthesized"]
    others = [("the diffusion model\nseed 7", synth + np.float32([0.0, 0.1, 0.0])), ("1-NN retrieval", synth[::-1].copy())]
    scene.set_variations([synth, synth + np.float32([0.1, 0.0, 0.0])], [7, 8], "the paper's GAN")
    scene.set_compared(others)
    assert scene.captions_shown() == [] and not scene.figures["compared_1"].actors[0].GetVisibility()  # overlay
    scene.set_layout("side_by_side")
    try:
        assert scene.captions_shown() == [CHARACTER_TITLES["leader"], CHARACTER_TITLES["ground_truth"],
                                          f"{CHARACTER_TITLES['synthesized']}\nthe paper's GAN · seed 7", "seed 8",
                                          "the diffusion model\nseed 7", "1-NN retrieval"]
        xs = [scene.captions[k].position[0] for k in ("synthesized", "variation_1", *COMPARED_KEYS[:2])]
        assert np.all(np.diff(xs) > 1.0), xs
        assert _count(screenshot(scene), COMPARED) > 100
        scene.set_frame(5)
        np.testing.assert_allclose(np.asarray(scene.figures["compared_2"].poly.points), synth[::-1][5], atol=1e-6)
        scene.render()  # the mouse over one of its joints names it (the page's hover)
        pose = synth[::-1][5]
        j = int(np.argmax(np.linalg.norm(pose - pose[scene.skeleton.root], axis=-1)))  # a limb's end, apart from others
        point = scene.figures["compared_2"].actors[0].GetMatrix().MultiplyPoint((*map(float, pose[j]), 1.0))[:3]
        scene.renderer.SetWorldPoint(*point, 1.0)
        scene.renderer.WorldToDisplay()
        dx, dy, _ = scene.renderer.GetDisplayPoint()
        width, height = scene.render_window.GetSize()
        assert scene.camera.joint_at(dx / width, 1.0 - dy / height) == ("compared_2", j)
        scene.set_compared(others[:1])
        assert not scene.figures["compared_2"].actors[0].GetVisibility() and scene.captions_shown()[-1] == others[0][0]
    finally:
        scene.set_compared([])
        scene.set_variations([synth], None)
        scene.set_frame(0)
        scene.set_layout("overlay")
        scene.camera.set("default")


def test_exported_pictures_carry_the_legend_and_the_frame_number_and_the_view_stays_plain(scene, sample_data, tmp_path):
    """Every frame of an exported GIF carries its own number in the strip along the top (here the figures stand still,
    so only the number changes); a PNG's legend names only the figures shown; the view itself gets no strip."""
    from types import SimpleNamespace

    import imageio.v3 as iio

    from explorer.rendering.palette import GROUND_TRUTH, LEADER, SYNTHESIZED
    from explorer.session.session import Session, load_model
    from explorer.ui.exports import Exports
    from imm_model.paths import SAMPLE_GAN

    if not SAMPLE_GAN.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_GAN}")
    session = Session(sample_data, {"gan": load_model(SAMPLE_GAN, sample_data)}, index=0)
    page = SimpleNamespace(session=session, state=SimpleNamespace(notice=""), guarded=lambda fn: fn,
                           trigger=lambda name: (lambda fn: fn), ctrl=SimpleNamespace(view_update=lambda: None))
    exports = Exports(page, scene, tmp_path, attach=bytes)
    keep = dict(scene.sequences)
    scene.set_sequence(*(np.repeat(m[:1], 4, 0) for m in (session.leader, session.ground_truth, session.synth)))
    try:
        plain = screenshot(scene)
        gif = exports.export_video("gif")
        frames = iio.imread(gif, index=None)[..., :3]
        assert frames.shape == (4, *plain.shape)
        from PIL import Image

        with Image.open(io.BytesIO(gif)) as im:  # plays at the data's 15 frames a second, not 16.7
            delays = []
            for k in range(im.n_frames):
                im.seek(k)
                delays.append(im.info["duration"])
        assert delays == [70, 60, 70, 70], delays
        text_rows = np.flatnonzero(np.abs(frames[0].astype(int) - plain).max(axis=(1, 2)) > 100)  # dark text on light
        top = text_rows.max() + 1
        assert len(text_rows) > 10 and top < 0.2 * plain.shape[0]
        strips = {f[:top].tobytes() for f in frames}
        assert len(strips) == len(frames)  # frame 1 / 4, 2 / 4, ...
        assert np.abs(frames[1:, top + 10:].astype(int) - frames[0, top + 10:]).max() < 40  # the scene did not move
        assert all(_count(frames[0][:top], c) > 10 for c in (LEADER, GROUND_TRUTH, SYNTHESIZED))
        np.testing.assert_array_equal(screenshot(scene), plain)

        scene.set_visible("ground_truth", False)
        png = iio.imread(exports.export_png())
        assert _count(png[:top], LEADER) > 10 and _count(png, GROUND_TRUTH) == 0
        assert sorted(p.suffix for p in tmp_path.iterdir()) == [".gif", ".png"]
    finally:
        scene.set_visible("ground_truth", True)
        scene.set_sequence(keep["leader"], keep["ground_truth"], keep["synthesized"])
        scene.camera.set("default")


def test_captions_of_many_figures_shrink_and_from_the_top_stand_clear_of_the_figures(scene):
    """Six figures side by side (three variations more) get smaller captions, so that neighbours do not run into each
    other; seen from the top each caption stands above its figure in the picture, not on it."""
    from explorer.rendering.captions import CAPTION_PX
    from explorer.rendering.scene import VARIATION_KEYS

    followers = [scene.sequences["synthesized"] + np.float32([dx, 0.0, 0.0]) for dx in (0.0, 0.2, 0.4, 0.6)]
    scene.set_layout("side_by_side")
    try:
        assert scene.captions["leader"].size == CAPTION_PX
        scene.set_variations(followers, [1, 2, 3, 4])
        sizes = {scene.captions[k].size for k in ("leader", "ground_truth", "synthesized", *VARIATION_KEYS[:3])}
        assert sizes == {min(sizes)} and min(sizes) < CAPTION_PX
        scene.camera.set("top")
        scene.render()

        def display_y(point) -> float:
            scene.renderer.SetWorldPoint(*point, 1.0)
            scene.renderer.WorldToDisplay()
            return scene.renderer.GetDisplayPoint()[1]

        leader = scene.figures["leader"]
        from vtkmodules.util.numpy_support import vtk_to_numpy

        joints = vtk_to_numpy(leader.actors[0].GetMapper().GetInput().GetPoints().GetData())
        joints = [leader.actors[0].GetMatrix().MultiplyPoint((*p, 1.0))[:3] for p in joints]
        caption_y, window_h = display_y(scene.captions["leader"].position), scene.render_window.GetSize()[1]
        assert caption_y > max(display_y(p) for p in joints) and caption_y < window_h, caption_y
    finally:
        scene.set_variations([scene.sequences["synthesized"]], None)
        scene.set_layout("overlay")
        scene.camera.set("default")


def test_trails_show_the_last_frames_as_ghosts_in_the_overlay_only(scene):
    """Trails on: the leader's and the synthesized follower's ghosts hold their poses some frames back (frame 0's where
    there is none); off, side by side or with the figure hidden, none is drawn."""
    leader = scene.sequences["leader"]
    scene.set_frame(10)
    trail = scene.trails["leader"]
    assert not trail.actor.GetVisibility()
    scene.set_trails(True)
    try:
        assert trail.actor.GetVisibility() and scene.trails["synthesized"].actor.GetVisibility()
        j = scene.skeleton.num_joints
        for g, step in enumerate(trail.steps):
            np.testing.assert_allclose(trail.poly.points[g * j:(g + 1) * j], leader[10 - step], atol=1e-6)
        scene.set_frame(1)
        np.testing.assert_allclose(trail.poly.points[-j:], leader[0], atol=1e-6)
        scene.set_layout("side_by_side")
        assert not trail.actor.GetVisibility()
        scene.set_layout("overlay")
        scene.set_visible("leader", False)
        assert not trail.actor.GetVisibility() and scene.trails["synthesized"].actor.GetVisibility()
        scene.set_visible("leader", True)
    finally:
        scene.set_trails(False)
        scene.camera.set("default")
    assert not trail.actor.GetVisibility()


def test_a_following_camera_moves_with_the_pair_and_keeps_the_users_turn(scene):
    """Following, the camera moves along the floor with the centre of the two roots from frame to frame; the direction
    it looks from (the user's turn) is kept."""
    scene.set_frame(0)
    camera = scene.renderer.GetActiveCamera()
    camera.Azimuth(20)
    scene.camera.set_follow(True)
    try:
        before = np.array(camera.GetFocalPoint()), np.array(camera.GetPosition())
        root = scene.skeleton.root
        last = len(scene.sequences["leader"]) - 1
        moved = np.mean([scene.sequences[k][last, root] - scene.sequences[k][0, root] for k in ("leader", "synthesized")], axis=0)
        moved[1] = 0.0
        scene.set_frame(last)
        np.testing.assert_allclose(np.array(camera.GetFocalPoint()) - before[0], moved, atol=1e-5)
        np.testing.assert_allclose(np.array(camera.GetPosition()) - before[1], moved, atol=1e-5)
    finally:
        scene.camera.set_follow(False)
        scene.set_frame(0)
        scene.camera.set("default")
    fixed = camera.GetPosition()
    scene.set_frame(5)
    assert camera.GetPosition() == fixed  # not following: the camera stays


def test_the_joint_under_the_mouse_is_found_by_its_picture_position(scene):
    """A point of the picture where a joint is drawn names that figure and joint; an empty corner names none."""
    scene.set_frame(3)
    scene.render()
    width, height = scene.render_window.GetSize()
    point = scene.sequences["leader"][3, 5]
    scene.renderer.SetWorldPoint(*map(float, point), 1.0)
    scene.renderer.WorldToDisplay()
    dx, dy, _ = scene.renderer.GetDisplayPoint()
    found = scene.camera.joint_at(dx / width, 1.0 - dy / height)
    assert found == ("leader", 5), found
    assert scene.camera.joint_at(0.01, 0.01) is None
    scene.set_visible("leader", False)
    try:
        assert scene.camera.joint_at(dx / width, 1.0 - dy / height) != ("leader", 5)  # a hidden figure is not hovered
    finally:
        scene.set_visible("leader", True)
