"""BVH import and export (imm_model/data/bvh.py): real files from other tools, round trips through an
independent reader (bvhio's own forward kinematics), name mapping, units, frame rate, bad files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from imm_model.cli import main
from imm_model.data.bvh import REST_DIRECTIONS, joint_mapping, read_bvh, resample, write_bvh
from imm_model.errors import DataFormatError
from imm_model.skeleton import KINECT15

bvhio = pytest.importorskip("bvhio")
FIXTURES = Path(__file__).parent / "fixtures" / "bvh"
REAL_FILES = sorted(FIXTURES.glob("*.bvh"))


def bvhio_positions(path: Path) -> np.ndarray:
    """(T, 15, 3) Kinect joints by bvhio's own forward kinematics (not ours)."""
    h = bvhio.readAsHierarchy(str(path))
    joints = [j for j, _, _ in h.layout()]
    idx = [[j.Name for j in joints].index(n) for n in KINECT15.joint_names]
    frames = []
    for f in range(len(joints[0].Keyframes)):
        h.loadPose(f)
        frames.append([[joints[i].PositionWorld.x, joints[i].PositionWorld.y, joints[i].PositionWorld.z] for i in idx])
    return np.array(frames)


def test_export_reimports_within_a_millimetre(sample_data, tmp_path):
    leader, follower = sample_data.world(5)
    path = tmp_path / "b.bvh"
    write_bvh(path, follower)
    assert np.abs(read_bvh(path) - follower).max() < 1e-3  # our importer
    assert np.abs(bvhio_positions(path) - follower).max() < 1e-3  # an independent reader


def test_export_rotations_hold_each_bones_swing(sample_data, tmp_path):
    """Tools that animate by rotations alone (rest offsets, no translation channels) see the right bone directions."""
    from imm_model.data.bvh import bone_rotations

    follower = sample_data.world(7)[1]
    world, rest = bone_rotations(follower)
    for j, name in enumerate(KINECT15.joint_names):
        p = KINECT15.parents[j]
        if p < 0 or sum(q == p for q in KINECT15.parents) > 1:
            continue  # children of torso and neck: a best fit of several bones, not exact
        along = world[p].apply(np.tile(rest[j], (len(follower), 1)))
        actual = follower[:, j] - follower[:, p]
        cos = (along * actual).sum(-1) / np.linalg.norm(along, axis=-1) / np.linalg.norm(actual, axis=-1)
        assert cos.min() > 0.9999, name
    assert set(REST_DIRECTIONS) == set(KINECT15.joint_names) - {"torso"}


def test_units_frame_rate_and_up_axis(sample_data, tmp_path):
    follower = sample_data.world(3)[1]
    cm = tmp_path / "cm.bvh"
    write_bvh(cm, resample(follower * 100.0, 15.0, 120.0), fps=120.0)  # centimetres at 120 fps
    back = read_bvh(cm)
    assert back.shape == follower.shape and np.abs(back - follower).max() < 2e-3
    zup = tmp_path / "zup.bvh"
    write_bvh(zup, np.stack([follower[..., 0], -follower[..., 2], follower[..., 1]], axis=-1))
    assert np.abs(read_bvh(zup, up="z") - follower).max() < 1e-3


def synthetic_hierarchy(names: list[str]) -> str:
    """A chain of the given joint names, 2 frames (synthetic: for name-mapping unit tests only)."""
    text = "HIERARCHY\n"
    for k, n in enumerate(names):
        text += ("ROOT " if k == 0 else "JOINT ") + n + "\n{\nOFFSET 0 10 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
    text += "End Site\n{\nOFFSET 0 1 0\n}\n" + "}\n" * len(names)
    return text + "MOTION\nFrames: 2\nFrame Time: 0.0333333\n" + ("0 " * 3 * len(names) + "\n") * 2


CMU_ASF = ["hip", "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head", "lclavicle", "lhumerus", "lradius",
           "lwrist", "rclavicle", "rhumerus", "rradius", "rwrist", "lhipjoint", "lfemur", "ltibia", "lfoot", "rhipjoint",
           "rfemur", "rtibia", "rfoot"]
MIXAMO = ["mixamorig:" + n for n in ("Hips", "Spine", "Spine1", "Spine2", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm",
                                      "LeftHand", "RightShoulder", "RightArm", "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg",
                                      "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")]


@pytest.mark.parametrize("names", [CMU_ASF, MIXAMO], ids=["cmu-asf", "mixamo"])
def test_name_table_maps_common_skeletons(names):
    mapping = joint_mapping(names)
    picked = [names[i].rsplit(":", 1)[-1] for i in mapping]
    assert picked[KINECT15.joint_names.index("left_elbow")] in ("lradius", "LeftForeArm")
    assert picked[KINECT15.joint_names.index("left_shoulder")] in ("lhumerus", "LeftArm")  # the arm, not the clavicle


def test_unmapped_skeleton_names_what_is_missing_and_a_json_map_fixes_it(tmp_path, capsys):
    names = [n.replace("femur", "upleg_x") for n in CMU_ASF]
    path = tmp_path / "odd.bvh"
    path.write_text(synthetic_hierarchy(names))
    with pytest.raises(DataFormatError, match=r"no joint for left_hip .*right_hip"):
        read_bvh(path)
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"left_hip": "lupleg_x", "right_hip": "rupleg_x"}))
    assert read_bvh(path, mapping, units="cm").shape[1:] == (15, 3)
    assert main(["generate", "--leader", str(path), "--label", "kicking=1", "--out", str(tmp_path / "o.npz")]) == 2
    err = capsys.readouterr().err
    assert "no joint for left_hip" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("text", ["", "HIERARCHY\nROOT a\n{\nOFFSET 0 0\n", "not a bvh at all\n" * 3,
                                  synthetic_hierarchy(CMU_ASF).replace("Frames: 2", "Frames: 1").rsplit("\n", 2)[0]])
def test_malformed_bvh_is_one_line(tmp_path, text):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(DataFormatError) as err:
        read_bvh(path)
    assert "\n" not in str(err.value)


@pytest.mark.skipif(not REAL_FILES, reason="no real BVH fixtures in tests/fixtures/bvh")
@pytest.mark.parametrize("path", REAL_FILES, ids=[p.stem for p in REAL_FILES])
def test_real_bvh_leader_end_to_end(path, tmp_path):
    """A BVH written by another tool: a plausible human in metres, Y up, 15 fps; `imm generate` answers it with a
    BVH that re-imports within 1 mm."""
    leader = read_bvh(path)
    legs = np.linalg.norm(leader[:, 9] - leader[:, 10], axis=-1) + np.linalg.norm(leader[:, 10] - leader[:, 11], axis=-1)
    assert 0.5 < np.median(legs) < 1.2
    assert np.median(leader[:, 0, 1] - leader[:, [11, 14], 1].min(-1)) > 1.0  # the head is a metre above the feet
    out = tmp_path / "y.bvh"
    assert main(["generate", "--leader", str(path), "--label", "shaking_hands=1", "--out", str(out)]) == 0
    follower = read_bvh(out)
    np.testing.assert_allclose(read_bvh(tmp_path / "y.leader.bvh"), leader, atol=1e-3)
    assert follower.shape == leader.shape and np.abs(bvhio_positions(out) - follower).max() < 1e-3


@pytest.mark.skipif(not Path("/usr/bin/blender").exists(), reason="needs Debian's blender (apt-get install -y blender)")
def test_blender_imports_the_export(sample_data, tmp_path):
    """Blender's own BVH importer (headless) puts every joint where we wrote it (its Z-up: x, -z, y)."""
    import subprocess

    follower = sample_data.world(5)[1]
    write_bvh(tmp_path / "b.bvh", follower)
    script = Path(__file__).parent / "blender_import.py"
    run = subprocess.run(["/usr/bin/blender", "-b", "--factory-startup", "--python", str(script), "--",
                          str(tmp_path / "b.bvh"), str(tmp_path / "b.json")], capture_output=True, text=True, timeout=180)
    assert (tmp_path / "b.json").exists(), run.stdout[-2000:] + run.stderr[-2000:]
    frames = json.loads((tmp_path / "b.json").read_text())
    for frame, joints in frames.items():
        blender = np.array([joints[n] for n in KINECT15.joint_names])
        ours = follower[int(frame) - 1]
        assert np.abs(blender - np.stack([ours[:, 0], -ours[:, 2], ours[:, 1]], axis=-1)).max() < 1e-3
