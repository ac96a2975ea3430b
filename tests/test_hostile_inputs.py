"""Hostile inputs generated from the fixture files and the bundled checkpoint's sidecar: each file truncated at every
section, its claimed counts multiplied by a million, NaN / infinity / 1e30 in each numeric header field and value,
cycles and duplicate names. Every reader answers each within seconds and bounded memory, with one line naming the
file; the CLI exits 2 and writes nothing.

The file readers run in one child process (a hang there must not hang the suite) under an address-space limit, each
case with its own alarm; the child reports what each case raised, how long it took and its peak memory.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from imm_model.errors import CheckpointError, DataFormatError, LabelError
from imm_model.skeleton import KINECT15, Skeleton

FIXTURES = Path(__file__).parent / "fixtures"
BVH = FIXTURES / "bvh/cmu_01_01.bvh"
SBU = FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt"
MAT = FIXTURES / "k3hi/Skeletons/kicking/1/skeleton_A.mat"
CASE_SECONDS = 5  # each case's alarm in the child, and the bound asserted
RSS_MB = 500  # the child's peak resident memory over all cases
ADDRESS_SPACE = 1 << 30  # the child's RLIMIT_AS: an allocation of gigabytes fails there instead of succeeding

CHILD = r"""
import json, resource, signal, sys, time, traceback
resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[2]), int(sys.argv[2])))
from pathlib import Path
from imm_model.data.bvh import read_bvh
from imm_model.data.dataset import InteractionDataset
from imm_model.data.k3hi import read_mat_skeleton
from imm_model.data.sbu import parse_skeleton_file
from imm_model.errors import IMMError
from imm_model.data.leader_file import read_leader_file

READERS = {"bvh": read_bvh, "leader": read_leader_file, "bundle": InteractionDataset.load, "sbu": parse_skeleton_file,
           "k3hi": read_mat_skeleton}

class Overrun(Exception):
    pass

def alarm(signum, frame):
    raise Overrun()

signal.signal(signal.SIGALRM, alarm)
results = {}
for name, (reader, path) in json.loads(Path(sys.argv[1]).read_text()).items():
    start = time.perf_counter()
    signal.alarm(int(sys.argv[3]))
    try:
        shape = getattr(READERS[reader](Path(path)), "shape", None)
        outcome = {"kind": "accepted", "shape": list(shape) if shape is not None else None}
    except IMMError as err:
        outcome = {"kind": "refused", "type": type(err).__name__, "message": str(err)}
    except Overrun:
        outcome = {"kind": "overrun"}
    except BaseException as err:
        outcome = {"kind": "crashed", "type": type(err).__name__, "message": traceback.format_exc()[-600:]}
    signal.alarm(0)
    outcome["seconds"] = time.perf_counter() - start
    # VmHWM, not ru_maxrss: Linux carries ru_maxrss across execve, so it would report the forking test process's peak
    outcome["rss_mb"] = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM")) / 1024
    results[name] = outcome
print(json.dumps(results))
"""


# ---- hostile files ------------------------------------------------------------------------------------------------
def bvh_variants() -> dict[str, str]:
    text = BVH.read_text()
    rows_at = text.index("\n", text.index("Frame Time")) + 1
    first_row, last_row = text[rows_at:].split("\n", 1)[0], text.rstrip("\n").rsplit("\n", 1)[1]
    second_offset = text.index("OFFSET", text.index("JOINT"))
    offset_line = text[second_offset : text.index("\n", second_offset)]

    def cut_before(marker: str, nth: int = 0) -> str:
        at = -1
        for _ in range(nth + 1):
            at = text.index(marker, at + 1)
        return text[:at]

    out = {f"cut before {m}": cut_before(m) for m in ("ROOT", "{", "OFFSET", "CHANNELS", "JOINT", "End Site", "MOTION",
                                                      "Frames:", "Frame Time")}
    out |= {
        "cut inside an end site": cut_before("}", text[: text.index("End Site")].count("}")),
        "cut before the first row": text[:rows_at],
        "last row missing": text.rstrip("\n").rsplit("\n", 1)[0] + "\n",
        "last row cut in half": text.rstrip("\n")[: -len(last_row) // 2],
        "cut at half the file": text[: len(text) // 2],
        "empty": "",
        "frames x 1e6": text.replace("Frames: 240", "Frames: 240000000"),
        "frames off by one": text.replace("Frames: 240", "Frames: 241"),
        "channels x 1e6": text.replace("CHANNELS 6", "CHANNELS 6000000", 1),
        "deep hierarchy": "HIERARCHY\nROOT j0\n" + "".join(
            f"{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nJOINT j{i + 1}\n" for i in range(5000)),
        "2000 joints": text.replace("JOINT LHipJoint", "".join(
            f"JOINT extra{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{{\nOFFSET 0 1 0\n}}\n}}\n"
            for i in range(2000)) + "JOINT LHipJoint", 1),
        "duplicate joint name": text.replace("JOINT LowerBack", "JOINT LHipJoint", 1),
        "unknown channel": text.replace("Zrotation", "Wrotation", 1),
        "binary": "\x00\x01HIERARCHY\x02" * 100,
        "no motion rows at all, frames 1e9": text[:rows_at].replace("Frames: 240", "Frames: 1000000000"),
        "6 million blank lines before the motion": text.replace("MOTION", " \t\n" * 6_000_000 + "MOTION", 1),
        "200,000 blank lines before the motion": text.replace("MOTION", " \t\n" * 200_000 + "MOTION", 1),
        "a row of 3 million values": text[:rows_at] + "0 " * 3_000_000 + "\n" + text[rows_at:],
    }
    for bad in ("nan", "inf", "-inf", "1e30", "-1e30", "0", "-0.0083"):
        out[f"frame time {bad}"] = text.replace("Frame Time: .0083333", f"Frame Time: {bad}")
    for bad in ("nan", "inf", "1e30", "-5", "2.5"):
        out[f"frames {bad}"] = text.replace("Frames: 240", f"Frames: {bad}")
    for bad in ("nan", "inf", "1e30"):
        out[f"offset {bad}"] = text.replace(offset_line, f"OFFSET {bad} 0 0", 1)
        values = first_row.split()
        out[f"motion value {bad}"] = text.replace(first_row, " ".join([bad] + values[1:]), 1)
    return out


def sbu_variants() -> dict[str, bytes]:
    lines = SBU.read_text().splitlines()
    row = lines[1].split(",")

    def with_value(index: int, value: str) -> bytes:
        changed = row.copy()
        changed[index] = value
        return "\n".join(lines[:1] + [",".join(changed)] + lines[2:]).encode()

    out = {"empty": b"", "one frame": lines[0].encode(), "last line cut in half": "\n".join(lines)[: -len(lines[-1]) // 2].encode(),
           "cut at half the file": "\n".join(lines)[: len("\n".join(lines)) // 2].encode(),
           "a row of 180,000 values": "\n".join(lines[:1] + [",".join(row * 2000)]).encode(),
           "11 MB": ("\n".join(lines) + "\n").encode() * (11_000_000 // len("\n".join(lines)) + 1),
           "binary": b"\x89PNG\x00\xff" * 100}
    for bad in ("nan", "inf", "1e30", "-1e30"):
        out[f"coordinate {bad}"] = with_value(5, bad)
        out[f"frame number {bad}"] = with_value(0, bad)
    return out


def mat_variants(tmp: Path) -> dict[str, Path]:
    from scipy.io import loadmat, savemat

    data, curve = MAT.read_bytes(), loadmat(MAT)["curve_B"]
    out: dict[str, Path] = {}

    def put(name: str, content: bytes) -> None:
        out[name] = tmp / f"{len(out)}.mat"
        out[name].write_bytes(content)

    for at in (0, 64, 128, 136, len(data) // 2, len(data) - 8):
        put(f"cut at byte {at}", data[:at])
    for name, arr in {"shape (44, 2)": curve[:44, :2], "nan": np.where(np.arange(curve.size).reshape(curve.shape) == 7, np.nan, curve),
                      "inf": curve * np.inf, "1e30": curve * 1e30, "200000 frames of zeros": np.zeros((45, 200_000))}.items():
        path = tmp / f"{len(out)}.mat"
        savemat(path, {"curve_B": arr}, do_compression=True)
        out[name] = path
    plain = tmp / "plain.mat"
    savemat(plain, {"curve_B": curve}, do_compression=False)
    dims = struct.pack("<ii", *curve.shape)
    put("frames x 1e6", plain.read_bytes().replace(dims, struct.pack("<ii", 45, curve.shape[1] * 10**6), 1))
    return out


def _zip_declaring(path: Path, members: dict[str, bytes], name: str, declared: int) -> None:
    """A zip of `members` whose local and central headers declare `declared` uncompressed bytes for member `name`."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for member, content in members.items():
            zf.writestr(member, content)
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, _header(data, b"PK\x03\x04", 30, name) + 22, declared)
    struct.pack_into("<I", data, _header(data, b"PK\x01\x02", 46, name) + 24, declared)
    path.write_bytes(bytes(data))


def _header(data: bytearray, signature: bytes, name_at: int, name: str) -> int:
    """Offset of the zip header with `signature` whose file name (at `name_at` bytes into it) is `name`."""
    at = data.index(signature)
    while data[at + name_at : at + name_at + len(name)] != name.encode():
        at = data.index(signature, at + 1)
    return at


def _npy(arr: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr)
    return buf.getvalue()


def _npy_claiming(arr: np.ndarray, shape: tuple[int, ...]) -> bytes:
    """`arr` as .npy bytes whose header claims `shape` (same header length: the padding absorbs the change)."""
    raw = _npy(arr)
    header_len = struct.unpack("<H", raw[8:10])[0]
    header = raw[10 : 10 + header_len].decode("latin1")
    claimed = header.replace(f"'shape': {arr.shape}", f"'shape': {shape}").rstrip()
    return raw[:10] + (claimed + " " * (header_len - len(claimed) - 1) + "\n").encode("latin1") + raw[10 + header_len :]


def npz_variants(tmp: Path, sample_data) -> dict[str, tuple[str, Path]]:
    leader = sample_data.world(0)[0]
    out: dict[str, tuple[str, Path]] = {}

    def put(name: str, reader: str, suffix: str = ".npz") -> Path:
        path = tmp / f"{len(out)}{suffix}"
        out[name] = (reader, path)
        return path

    np.savez(put("leader (T, 45) flattened", "leader"), leader=leader.reshape(len(leader), 45))
    with put("upper-case suffix", "leader", ".NPZ").open("wb") as f:  # (given a name, np.savez would append ".npz")
        np.savez(f, leader=leader)
    with zipfile.ZipFile(put("3e6 zero frames", "leader"), "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf, \
            zf.open("leader.npy", "w", force_zip64=True) as f:  # the real thing, streamed: 540 MB of zeros, 0.5 MB on disk
        f.write(_npy_claiming(np.zeros((0, 15, 3), np.float32), (3_000_000, 15, 3)))
        zeros = bytes(1 << 20)
        for _ in range(3_000_000 * 45 * 4 >> 20):
            f.write(zeros)
    _zip_declaring(put("member declares 1 GB", "leader"), {"leader.npy": _npy(leader)}, "leader.npy", 1 << 30)
    small = put("header claims shape x 1e6", "leader")
    with zipfile.ZipFile(small, "w") as zf:
        zf.writestr("leader.npy", _npy_claiming(leader, (len(leader) * 10**6, 15, 3)))
    np.savez(put("pickled objects", "leader"), leader=np.array([{"a": 1}, None], dtype=object))
    put("text named .npz", "leader").write_text("HIERARCHY\n" * 10)
    np.savez(put("no leader array", "leader"), follower=leader)
    ok = put("cut at half the file", "leader")
    np.savez(ok, leader=leader)
    ok.write_bytes(ok.read_bytes()[: ok.stat().st_size // 2])
    for bad in ("nan", "inf", "1e30"):
        np.savez(put(f"leader {bad}", "leader"), leader=np.where(np.arange(leader.size).reshape(leader.shape) == 5, float(bad), leader))
    np.savez(put("leader (T, 44)", "leader"), leader=leader.reshape(len(leader), 45)[:, :44])
    np.savez(put("leader of strings", "leader"), leader=np.array(["a", "b"]))
    out["bundle: bvh given as --data"] = ("bundle", BVH)
    out |= bundle_variants(tmp)
    return out


def bundle_variants(tmp: Path) -> dict[str, tuple[str, Path]]:
    from imm_model.paths import SAMPLE_DATA

    with np.load(SAMPLE_DATA) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(arrays["metadata"].tobytes())
    out = {}

    def put(name: str, change) -> None:
        a, m = copy.deepcopy(arrays), copy.deepcopy(meta)
        change(a, m)
        if not isinstance(a["metadata"], bytes):
            a["metadata"] = np.frombuffer(json.dumps(m).encode(), np.uint8)
        else:
            a["metadata"] = np.frombuffer(a["metadata"], np.uint8)
        path = tmp / f"bundle{len(out)}.npz"
        np.savez(path, **a)
        out[f"bundle: {name}"] = ("bundle", path)

    put("as saved", lambda a, m: None)
    put("metadata not JSON", lambda a, m: a.__setitem__("metadata", b"{\x00 not json"))
    put("skeleton parents cycle", lambda a, m: m["skeleton"]["parents"].__setitem__(1, 0))
    put("skeleton joint 99", lambda a, m: m["skeleton"]["facing_joints"].__setitem__(0, 99))
    put("skeleton vertical axis 7", lambda a, m: m["skeleton"].__setitem__("vertical_axis", 7))
    put("class names twice", lambda a, m: m["class_names"].__setitem__(1, m["class_names"][0]))
    put("no class names", lambda a, m: m.pop("class_names"))
    put("lengths x 1e6", lambda a, m: a.__setitem__("lengths", a["lengths"] * 10**6))
    put("a length of -5", lambda a, m: a["lengths"].__setitem__(0, -5))
    put("positions 1e30", lambda a, m: a.__setitem__("leader", a["leader"] * np.float32(1e30)))
    put("class index 99", lambda a, m: a["actions"].__setitem__(0, 99))
    put("a follower value NaN", lambda a, m: a["follower"].__setitem__((a["lengths"][0] + 2, 4, 1), np.nan))
    put("canonical mode unknown", lambda a, m: m.__setitem__("canonical_mode", "sideways"))
    declaring = tmp / "bundle_declares.npz"
    _zip_declaring(declaring, {f"{k}.npy": _npy(v) for k, v in arrays.items()}, "follower.npy", (1 << 32) - 1)
    out["bundle: a member declares 4 GB"] = ("bundle", declaring)
    return out


# valid files among them, still read within the bounds (bvhio skips blank lines)
ACCEPTED = {"leader (T, 45) flattened", "upper-case suffix", "bundle: as saved", "bvh: 200,000 blank lines before the motion"}


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory, sample_data) -> dict[str, tuple[str, dict]]:
    tmp = tmp_path_factory.mktemp("hostile")
    cases: dict[str, tuple[str, Path]] = {}
    for kind, variants in (("bvh", bvh_variants()), ("sbu", sbu_variants())):
        for name, content in variants.items():
            path = tmp / f"{kind}{len(cases)}" / ("take.bvh" if kind == "bvh" else "skeleton_pos.txt")
            path.parent.mkdir()
            path.write_bytes(content.encode() if isinstance(content, str) else content)
            cases[f"{kind}: {name}"] = (kind, path)
    cases |= {f"k3hi: {n}": ("k3hi", p) for n, p in mat_variants(tmp).items()}
    cases |= {f"npz: {n}" if not n.startswith("bundle") else n: v for n, v in npz_variants(tmp, sample_data).items()}
    listing = tmp / "cases.json"
    listing.write_text(json.dumps({n: (r, str(p)) for n, (r, p) in cases.items()}))
    run = subprocess.run([sys.executable, "-c", CHILD, str(listing), str(ADDRESS_SPACE), str(CASE_SECONDS)],
                         capture_output=True, text=True, timeout=240, env=os.environ | {"OMP_NUM_THREADS": "1"})
    assert run.returncode == 0, run.stderr[-3000:]
    results = json.loads(run.stdout)
    return {n: (str(cases[n][1]), results[n]) for n in cases}


def test_every_hostile_file_is_refused_in_one_line_naming_it_within_seconds_and_bounded_memory(outcomes):
    problems = []
    for name, (path, result) in outcomes.items():
        expected = "accepted" if name.removeprefix("npz: ") in ACCEPTED else "refused"
        if result["kind"] != expected:
            problems.append(f"{name}: {result['kind']} {result.get('type', '')} {result.get('message', result.get('shape'))}")
        elif expected == "refused" and (result["type"] != "DataFormatError" or "\n" in result["message"]
                                        or path not in result["message"]):
            problems.append(f"{name}: {result['type']} {result['message']!r} (one line naming {path} expected)")
        if result["seconds"] > CASE_SECONDS or result["rss_mb"] > RSS_MB:
            problems.append(f"{name}: {result['seconds']:.1f} s, {result['rss_mb']:.0f} MB")
    assert not problems, "\n".join(problems)
    assert len(outcomes) > 80


def test_the_messages_name_the_field(outcomes, sample_data):
    def message(name: str) -> str:
        return outcomes[name][1].get("message", "")

    assert "Frame Time" in message("bvh: frame time nan") and "0.0001 to 1 s" in message("bvh: frame time 1e30")
    assert "says 241" in message("bvh: frames off by one") and "240 frames" in message("bvh: frames off by one")
    assert "'LHipJoint' is used twice" in message("bvh: duplicate joint name")
    assert "not a finite number" in message("bvh: motion value nan")
    assert "1000 m" in message("bvh: motion value 1e30") and "1000 m" in message("npz: leader 1e30")
    assert "allow_pickle" not in message("bundle: bvh given as --data") + message("npz: text named .npz")
    assert "16 MB" in message("npz: 3e6 zero frames") and "dtype object" in message("npz: pickled objects")
    assert "cycle" in message("bundle: skeleton parents cycle") and "vertical_axis" in message("bundle: skeleton vertical axis 7")
    assert "facing_joints must be joint indices below the joint count" in message("bundle: skeleton joint 99")
    assert "class_names names" in message("bundle: class names twice")
    first, second = sample_data.sequence_ids[:2]
    assert f"leader of sequence {first} has positions beyond 1000 m" in message("bundle: positions 1e30")
    assert f"follower of sequence {second} holds NaN" in message("bundle: a follower value NaN")
    assert "MB uncompressed; interaction bundle files up to 256 MB" in message("bundle: a member declares 4 GB")
    assert "declares shape (17000000, 15, 3)" in message("npz: header claims shape x 1e6")
    assert "characters for 96 channels" in message("bvh: a row of 3 million values")
    assert "a line of" in message("sbu: a row of 180,000 values") and "inflates past" in message("k3hi: 200000 frames of zeros")


def test_flattened_and_upper_case_npz_leaders_read_as_the_plain_one(outcomes, sample_data):
    from imm_model.data.leader_file import read_leader_file

    leader = sample_data.world(0)[0]
    for name in ("npz: leader (T, 45) flattened", "npz: upper-case suffix"):
        np.testing.assert_array_equal(read_leader_file(Path(outcomes[name][0])), leader)


# ---- sidecars and skeleton dicts ------------------------------------------------------------------------------------
def _set(path: tuple, value):
    def change(d: dict) -> None:
        for key in path[:-1]:
            d = d[key]
        d[path[-1]] = value
    return change


SKELETON_CASES = {
    "parent 99": (_set(("parents", 0), 99), "parents must be joint indices below the joint count"),
    "parents cycle": (_set(("parents", 1), 0), "cycle"),
    "no root": (_set(("parents", 2), 1), "with -1 for exactly one root"),
    "two roots": (_set(("parents", 0), -1), "with -1 for exactly one root"),
    "facing joint 99": (_set(("facing_joints", 3), 99), "facing_joints must be joint indices below the joint count"),
    "facing joint -1": (_set(("facing_joints", 0), -1), "facing_joints must be a list of 4 items, each an integer in 0..999"),
    "three facing joints": (_set(("facing_joints",), [9, 12, 3]), "facing_joints must be a list of 4 items"),
    "body part joint 99": (_set(("body_parts", "trunk"), [0, 99]), "body_parts must be joint indices below the joint count"),
    "empty body part": (_set(("body_parts", "trunk"), []), "each a non-empty list of joint indices"),
    "vertical axis 7": (_set(("vertical_axis",), 7), "vertical_axis must be an integer in 0..2, not 7"),
    "vertical axis 1.0": (_set(("vertical_axis",), 1.0), "vertical_axis must be an integer in 0..2"),
    "duplicate joint names": (_set(("joint_names", 3), "head"), "joint_names must be a list of 1 to 1000 distinct items"),
    "parents a string": (_set(("parents",), "1,2"), "parents must be a list"),
    "joint index true": (_set(("parents", 0), True), "parents must be a list of 1 to 1000 items, each an integer"),
    "100000 joints": (_set(("joint_names",), [f"j{i}" for i in range(100_000)]), "a list of 1 to 1000 distinct items"),
    "missing field": (lambda d: d.pop("facing_joints"), "skeleton lacks facing_joints"),
    "unknown key": (_set(("hands",), 2), "unknown skeleton keys"),
}


@pytest.mark.parametrize("case", SKELETON_CASES)
def test_hostile_skeleton_dict_is_one_value_error_naming_the_field(case):
    change, expected = SKELETON_CASES[case]
    d = KINECT15.to_dict()
    change(d)
    with pytest.raises(ValueError) as info:
        Skeleton.from_dict(d)
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_a_long_cycle_is_found_at_once():
    chain = [-1] + [(i + 1) % 1000 or 1 for i in range(1, 1000)]  # 1 -> 2 -> ... -> 999 -> 1, joint 0 the root
    d = KINECT15.to_dict() | {"joint_names": [f"j{i}" for i in range(1000)], "parents": chain, "body_parts": {},
                              "facing_joints": [1, 2, 3, 4]}
    with pytest.raises(ValueError, match="cycle"):
        Skeleton.from_dict(d)


SIDECAR_CASES = {
    "skeleton parents cycle": (_set(("skeleton", "parents", 1), 0), "cycle"),
    "skeleton joint 99": (_set(("skeleton", "body_parts", "left_arm"), [3, 4, 99]), "body_parts must be joint indices below"),
    "vertical axis 7": (_set(("skeleton", "vertical_axis"), 7), "vertical_axis"),
    "max_train_length -5": (_set(("max_train_length",), -5), "max_train_length must be a frame count in 1..100000"),
    "max_train_length 1e9": (_set(("max_train_length",), 10**9), "max_train_length"),
    "bone lengths 1e30": (lambda m: m.__setitem__("follower_bone_lengths", [1e30] * 14), "lengths in (0, 5] m"),
    "bone length nan": (lambda m: m.__setitem__("follower_bone_lengths", [float("nan")] * 14), "lengths in (0, 5] m"),
    "bone length 0": (lambda m: m.__setitem__("follower_bone_lengths", [0.0] * 14), "lengths in (0, 5] m"),
    "class names twice": (lambda m: m["class_names"].__setitem__(1, m["class_names"][0]), "names 'kicking' twice"),
    "canonical mode unknown": (_set(("canonical_mode",), "sideways"), "canonical_mode"),
    "model body part joint 99": (lambda m: m["model_config"]["body_parts"][0].__setitem__(0, 99), "body_parts"),
    "mirror classes a string": (_set(("train_config", "mirror_exclude_classes"), "kicking"), "mirror_exclude_classes"),
}


@pytest.fixture(scope="module")
def checkpoint_meta():
    from imm_model.checkpoint import load_checkpoint
    from imm_model.paths import SAMPLE_GAN

    return load_checkpoint(SAMPLE_GAN, framework="np")[1]


def _checkpoint_with(tmp_path: Path, meta: dict) -> Path:
    from imm_model.checkpoint import sidecar_path
    from imm_model.paths import SAMPLE_GAN

    path = tmp_path / "hostile.safetensors"
    shutil.copy(SAMPLE_GAN, path)
    sidecar_path(path).write_text(json.dumps(meta))
    return path


@pytest.mark.parametrize("case", SIDECAR_CASES)
def test_hostile_sidecar_is_one_checkpoint_error_naming_the_field(case, tmp_path, checkpoint_meta):
    from imm_model.inference import ReactionModel

    change, expected = SIDECAR_CASES[case]
    meta = copy.deepcopy(checkpoint_meta)
    change(meta)
    with pytest.raises(CheckpointError) as info:
        ReactionModel.load(_checkpoint_with(tmp_path, meta))
    assert expected in str(info.value) and "hostile.safetensors" in str(info.value) and "\n" not in str(info.value)


# ---- labels -------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def model():
    from imm_model.inference import ReactionModel

    return ReactionModel.load()


@pytest.mark.parametrize("text, expected", [
    ("kicking=1e300", "kicking=1e+300 (after the scale) is outside the range of label values, -10..10"),
    ("kicking=-11", "outside the range of label values"),
    ("kicking=1,kicking=-5", "gives kicking twice"),
    ("kicking=1, kicking =1", "gives kicking twice"),
    ("kicking=nan", "finite"),
    ("1e30,0,0,0,0,0", "outside the range of label values"),
    ("kicking=1,dancing=1", "unknown class 'dancing'"),
])
def test_hostile_label_is_refused_naming_the_value(model, text, expected):
    from imm_model.inference import Label

    with pytest.raises(LabelError) as info:
        model.label_vector(Label.parse(text, model.class_names))
    assert expected in str(info.value)


def test_label_range_applies_after_the_scale(model):
    assert model.label_vector({"kicking": 5.0}, 2.0)[0] == 10.0
    with pytest.raises(LabelError, match="range of label values"):
        model.label_vector({"kicking": 5.0}, 2.5)


def test_leader_beyond_the_physical_range_is_refused_naming_it(model, sample_data):
    leader = sample_data.world(0)[0].copy()
    leader[3, 4, 0] = 2e3
    with pytest.raises(DataFormatError, match=r"2e\+03 m from the origin; positions within 1000 m"):
        model.check_leader(leader)


# ---- the CLI: rc 2, one line, nothing written ------------------------------------------------------------------------
CLI_CHILD = r"""
import contextlib, io, json, sys, time
from imm_model.cli import main
results = []
for argv in json.loads(sys.argv[1]):
    err, start = io.StringIO(), time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    results.append({"rc": rc, "err": err.getvalue(), "seconds": time.perf_counter() - start})
print(json.dumps(results))
"""


def test_cli_answers_hostile_inputs_with_rc_2_one_line_and_writes_nothing(tmp_path, checkpoint_meta, outcomes):
    meta = copy.deepcopy(checkpoint_meta)
    meta["skeleton"]["parents"][1] = 0  # a cycle: the BVH writer would never return
    cycle = _checkpoint_with(tmp_path, meta)
    out = tmp_path / "out"
    label = ["--label", "kicking=1"]
    np.savez(tmp_path / "one_frame.npz", leader=np.zeros((1, 15, 3), np.float32))  # synthetic: a leader of one frame
    argvs = [
        ["generate", "--leader", outcomes["bvh: frames off by one"][0], *label, "--out", str(out / "a.bvh")],
        ["generate", "--leader", outcomes["npz: 3e6 zero frames"][0], *label, "--out", str(out / "b.npz")],
        ["generate", "--sequence", "s01s02/03/001", *label, "--checkpoint", str(cycle), "--out", str(out / "c.bvh")],
        ["generate", "--sequence", "s01s02/03/001", "--label", "kicking=1e300", "--out", str(out / "d.npz")],
        ["generate", "--sequence", "s01s02/03/001", *label, "--data", str(BVH), "--out", str(out / "e.npz")],
        ["data", "summary", "--data", outcomes["bundle: skeleton parents cycle"][0]],
        ["generate", "--sequence", "s01s02/03/001", "--grid", "--scale", "1e300", "--out", str(out / "f")],
        ["generate", "--sequence", "s01s02/03/001", "--grid", "--scale", "nan", "--out", str(out / "g")],
        ["generate", "--sequence", "s01s02/03/001", "--grid", *label, "--out", str(out / "h")],
        ["generate", "--leader", str(tmp_path / "one_frame.npz"), str(BVH), *label, "--out", str(out / "i")],
    ]
    expected = {"f": "outside the range of label values", "g": "must be finite", "h": "give --label or --grid, not both",
                "i": "one_frame.npz: leader motion has 1 frame"}
    run = subprocess.run([sys.executable, "-c", CLI_CHILD, json.dumps(argvs)], capture_output=True, text=True, timeout=120,
                         env=os.environ | {"OMP_NUM_THREADS": "1"})
    assert run.returncode == 0, run.stderr[-3000:]
    for argv, result in zip(argvs, json.loads(run.stdout), strict=True):
        lines = result["err"].strip().splitlines()
        assert result["rc"] == 2 and len(lines) == 1 and lines[0].startswith("imm "), (argv, result)
        assert result["seconds"] < 10, (argv, result)
        assert expected.get(Path(argv[-1]).name, "") in lines[0], (argv, result)
    assert not out.exists() or not any(out.iterdir())
