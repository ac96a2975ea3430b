"""Canonical-frame invariants on the real SBU sequences (bundled file)."""

from __future__ import annotations

import numpy as np
import pytest

from imm_model.data.canonical import FACING_WINDOW, CanonicalFrame, facing_direction, joined
from imm_model.data.dataset import InteractionDataset
from imm_model.data.sbu import read_sbu_sequence
from imm_model.skeleton import KINECT15

from .test_data_readers import FIXTURES


def test_leader_root_at_origin_and_facing_fixed_at_reference_frame(sample_data):
    for i in range(len(sample_data)):
        leader, _ = sample_data.canonical(i)
        np.testing.assert_allclose(leader[0, KINECT15.root], 0.0, atol=1e-5)
        # A's mean facing over the reference window is the fixed forward axis (+Z) in every sequence.
        mean_facing = facing_direction(leader[:FACING_WINDOW].astype(np.float64), KINECT15).mean(axis=0)
        np.testing.assert_allclose(mean_facing / np.linalg.norm(mean_facing), [0, 0, 1], atol=1e-5)


def test_follower_stands_in_front_of_the_leader(sample_data):
    # The facing rule (across x up) must point at the partner; a mirrored rule would give ~0.
    ahead = [sample_data.canonical(i)[1][0, KINECT15.root, 2] > 0 for i in range(len(sample_data))]
    assert np.mean(ahead) > 0.95


def test_round_trip_is_exact_and_bone_lengths_unchanged(sample_data):
    for i in range(0, len(sample_data), 7):
        leader_w, follower_w = sample_data.world(i)
        frame = sample_data.frame_of(i)
        for world in (leader_w, follower_w):
            canon = frame.to_canonical(world, KINECT15)
            np.testing.assert_allclose(frame.to_world(canon, KINECT15), world, atol=1e-12)
            np.testing.assert_allclose(KINECT15.bone_lengths(canon), KINECT15.bone_lengths(world), atol=1e-12)


def test_bundle_world_matches_the_raw_file():
    # The bundle stores float32 canonical poses; back in the world they match the raw metres to float32 precision.
    it = read_sbu_sequence(FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt")
    data = InteractionDataset.from_interactions([it], class_names=("kicking",))
    leader_w, follower_w = data.world(0)
    np.testing.assert_allclose(leader_w, it.leader, atol=2e-6)
    np.testing.assert_allclose(follower_w, it.follower, atol=2e-6)


@pytest.mark.parametrize("yaw_deg", [0, 37, 180, -120])
def test_per_frame_mode_removes_every_frames_rotation(yaw_deg):
    it = read_sbu_sequence(FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt")
    # Rotate the whole scene about the vertical axis: the canonical result must not change.
    rot = CanonicalFrame(yaw=np.full(it.num_frames, np.radians(yaw_deg)), origin=np.zeros((it.num_frames, 3)), mode="x")
    rotated = rot.to_world(it.leader, KINECT15)
    for mode in ("first_frame", "per_frame"):
        a = CanonicalFrame.from_leader(it.leader, KINECT15, mode)
        b = CanonicalFrame.from_leader(rotated, KINECT15, mode)
        np.testing.assert_allclose(a.to_canonical(it.leader, KINECT15), b.to_canonical(rotated, KINECT15), atol=1e-9)
    frame = CanonicalFrame.from_leader(it.leader, KINECT15, "per_frame")
    canon = frame.to_canonical(it.leader, KINECT15)
    np.testing.assert_allclose(canon[:, KINECT15.root], 0.0, atol=1e-12)
    np.testing.assert_allclose(facing_direction(canon, KINECT15), np.tile([0, 0, 1.0], (it.num_frames, 1)), atol=1e-9)


def test_unknown_mode_is_rejected():
    with pytest.raises(ValueError, match="canonical mode"):
        CanonicalFrame.from_leader(np.zeros((3, 15, 3)), KINECT15, "sideways")  # type: ignore[arg-type]


def test_role_swap_recanonicalizes_on_the_follower(sample_data):
    sub = sample_data.subset([0, 50, 120])
    swapped = sub.role_swapped()
    for i in range(len(sub)):
        leader_w, follower_w = sub.world(i)
        new_leader_w, new_follower_w = swapped.world(i)
        np.testing.assert_allclose(new_leader_w, follower_w, atol=1e-5)
        np.testing.assert_allclose(new_follower_w, leader_w, atol=1e-5)
        np.testing.assert_allclose(swapped.canonical(i)[0][0, KINECT15.root], 0.0, atol=1e-5)
    assert swapped.sequence_ids[0].endswith(":swapped") and swapped.action_name(1) == sub.action_name(1)


def test_joined_clips_go_on_where_the_one_before_ended(sample_data):
    """A take of recorded clips joined (`joined`): each leader starts above where the one before ended, facing as it
    faced, on its own floor; every motion of a clip moves with its leader (the partner stays where it stood to it)."""
    clips = [sample_data.world(i) for i in (0, 40, 80)]
    (leader, follower), starts = joined(clips, KINECT15)
    assert starts == [0, len(clips[0][0]), len(clips[0][0]) + len(clips[1][0])]
    assert leader.shape == follower.shape == (sum(len(a) for a, _ in clips), 15, 3)
    up, root = KINECT15.vertical_axis, KINECT15.root
    horizontal = [a for a in range(3) if a != up]
    for k, s in enumerate(starts[1:], 1):
        np.testing.assert_allclose(leader[s, root, horizontal], leader[s - 1, root, horizontal], atol=1e-9)
        assert leader[s, root, up] == pytest.approx(clips[k][0][0, root, up])  # its own height
        before = CanonicalFrame.from_leader(leader[:s][::-1], KINECT15).yaw[0]
        after = CanonicalFrame.from_leader(leader[s:], KINECT15).yaw[0]
        assert abs((after - before + np.pi) % (2 * np.pi) - np.pi) < 1e-6
        for moved, recorded in ((leader, clips[k][0]), (follower, clips[k][1])):
            np.testing.assert_allclose(KINECT15.bone_lengths(moved[s:s + len(recorded)]), KINECT15.bone_lengths(recorded),
                                       atol=1e-9)
        apart = np.linalg.norm(follower[s, root] - leader[s, root])
        assert apart == pytest.approx(np.linalg.norm(clips[k][1][0, root] - clips[k][0][0, root]))
