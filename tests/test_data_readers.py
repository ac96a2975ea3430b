"""SBU and K3HI readers on real files: the bundled fixtures always, the full raw sets when present."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imm_model.data import load_k3hi, load_sbu, metres_to_normalized, normalized_to_metres
from imm_model.data.sbu import parse_skeleton_file, read_sbu_sequence
from imm_model.skeleton import KINECT15

FIXTURES = Path(__file__).parent / "fixtures"


def test_parse_fixture_file_matches_the_raw_text():
    path = FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt"
    frames, pos = parse_skeleton_file(path)
    first = [float(v) for v in path.read_text().splitlines()[0].split(",")]
    assert pos.shape == (2, len(frames), 15, 3)
    assert frames[0] == int(first[0])
    # PA joint 1 is values 1..3, PB joint 1 values 46..48 (xyz interleaved)
    np.testing.assert_allclose(pos[0, 0, 0], first[1:4])
    np.testing.assert_allclose(pos[1, 0, 0], first[46:49])
    np.testing.assert_allclose(pos[1, 0, 14], first[88:91])


def test_metric_conversion_follows_the_readme_formulas_and_inverts():
    xyz = np.array([[0.25, 0.5, 1.5625]])
    m = normalized_to_metres(xyz)
    np.testing.assert_allclose(m * 1000, [[1280 - 2560 * 0.25, 960 - 1920 * 0.5, 1.5625 * 10000 / 7.8125]])
    np.testing.assert_allclose(metres_to_normalized(m), xyz)


def test_fixture_folder_uses_interformer_actor_then_motion_energy():
    result = load_sbu(FIXTURES / "sbu", classes="all", strict=True)
    by_id = {it.sequence_id: it for it in result.interactions}
    assert set(by_id) == {"s01s02/03/001", "s01s02/06/001", "s03s04/01/001"}
    kick = by_id["s01s02/03/001"]
    assert (kick.leader_rule, kick.leader_source) == ("interformer", "PB")
    assert by_id["s01s02/06/001"].leader_rule == "motion_energy"  # hugging is not in InterFormer's csv
    assert kick.action == "kicking" and kick.subjects == ("s01", "s02")
    # Paper classes leave out approaching (01).
    assert len(load_sbu(FIXTURES / "sbu", strict=True)) == 2


def test_leader_left_right_and_role_swap():
    path = FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt"
    left = read_sbu_sequence(path, leader="left")
    right = read_sbu_sequence(path, leader="right")
    np.testing.assert_array_equal(left.leader, right.follower)
    swapped = left.swapped()
    np.testing.assert_array_equal(swapped.leader, left.follower)
    np.testing.assert_array_equal(swapped.follower, left.leader)
    with pytest.raises(ValueError, match="leader must be"):
        read_sbu_sequence(path, leader="tallest")  # type: ignore[arg-type]


def test_sbu_metric_bone_lengths_are_human_sized():
    it = read_sbu_sequence(FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt")
    bones = KINECT15.bone_lengths(it.leader)
    assert 0.1 < np.median(bones) < 0.5  # metres


@pytest.mark.shared
def test_full_sbu_counts(sbu_root):
    everything = load_sbu(sbu_root, classes="all")
    assert len(everything) == 282 and not everything.skipped
    assert sum(it.num_frames for it in everything.interactions) == 6822
    paper = load_sbu(sbu_root)
    assert len(paper) == 197
    lengths = [it.num_frames for it in paper.interactions]
    assert min(lengths) == 10 and max(lengths) == 46
    assert {it.subject_pair for it in paper.interactions}.__len__() == 21


@pytest.mark.shared
def test_full_k3hi_counts_and_joint_mapping(k3hi_root):
    result = load_k3hi(k3hi_root)
    assert len(result) == 312 and not result.skipped
    assert sum(it.num_frames for it in result.interactions) == 13753
    rules = {it.leader_rule for it in result.interactions}
    assert rules == {"k3hi_list", "motion_energy"}
    assert sum(it.leader_rule == "k3hi_list" for it in result.interactions) == 264
    # Mapped onto KINECT15, left and right limbs have matching lengths (symmetry check of the mapping).
    bones = np.median(np.concatenate([KINECT15.bone_lengths(it.leader) for it in result.interactions]), axis=0)
    names = [KINECT15.joint_names[c] for _, c in KINECT15.bones]
    for side in ("elbow", "hand", "knee", "foot"):
        left, right = bones[names.index(f"left_{side}")], bones[names.index(f"right_{side}")]
        assert abs(left - right) / max(left, right) < 0.2, side


def test_k3hi_fixture_actor_from_train_list():
    result = load_k3hi(FIXTURES / "k3hi", strict=True)
    (it,) = result.interactions
    assert it.sequence_id == "kicking/1" and it.leader_rule == "k3hi_list" and it.leader_source == "A"
    assert it.leader.shape[1:] == (15, 3)
