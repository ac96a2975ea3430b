"""BVH in and out: a leader from any MoCap tool, the synthesized reaction back to Blender, Maya or MotionBuilder.

Import: bvhio parses the file (channel orders, Euler angles); forward kinematics here, vectorized over frames
with scipy rotations; then the 15 Kinect joints are picked by name (NAME_TABLE, overridable with a JSON
mapping), converted to metres (units detected from the leg length, or given) and to the project's Y-up axis,
and resampled to 15 fps. A skeleton that cannot be mapped is a one-line DataFormatError naming what is missing.
Before bvhio sees a file, `_check_layout` walks it once without recursion and holds it to what bvhio relies on
(bvhio's line reader never returns at the end of the file, so a MOTION block shorter than its `Frames:` line would
hang it): the hierarchy complete and within MAX_JOINTS and MAX_DEPTH, unique joint names, a sane `Frame Time`,
and as many finite motion rows of the declared width as `Frames:` claims, within MAX_KEYFRAMES and MAX_SECONDS.

Export (one character per file, the project's 15-joint hierarchy rooted at the torso): every joint carries
translation channels, so re-importing reproduces each position exactly (Kinect bone lengths vary from frame to
frame, which rotations alone cannot express), and rotation channels holding the swing of each bone from the
rest pose (median bone lengths, upright), so tools that animate by rotations show the right limb directions.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from imm_model.data.sequence import check_world_positions
from imm_model.errors import DataFormatError
from imm_model.inputs import MAX_SETTINGS_BYTES, check_input, read_input_text
from imm_model.skeleton import KINECT15, Skeleton

TARGET_FPS = 15.0
# Kinect joint -> BVH joint names tried in order (case-insensitive, after any "namespace:" prefix): this project's
# own names, CMU ASF/AMC conversions (lfemur...), the CMU cgspeed, Mixamo and DAZ/Poser conventions, the Biovision sample.
NAME_TABLE: dict[str, tuple[str, ...]] = {
    "head": ("head",),
    "neck": ("neck", "upperneck", "lowerneck", "neck1"),
    "torso": ("torso", "spine1", "upperback", "spine", "chest", "thorax", "lowerback", "abdomen"),
    "left_shoulder": ("left_shoulder", "leftarm", "lhumerus", "leftuparm", "leftupperarm", "lshldr"),
    "left_elbow": ("left_elbow", "leftforearm", "lradius", "leftlowarm", "leftlowerarm", "lforearm"),
    "left_hand": ("left_hand", "lefthand", "lwrist", "lhand"),
    "right_shoulder": ("right_shoulder", "rightarm", "rhumerus", "rightuparm", "rightupperarm", "rshldr"),
    "right_elbow": ("right_elbow", "rightforearm", "rradius", "rightlowarm", "rightlowerarm", "rforearm"),
    "right_hand": ("right_hand", "righthand", "rwrist", "rhand"),
    "left_hip": ("left_hip", "leftupleg", "lfemur", "leftupperleg", "lefthip", "lthigh"),
    "left_knee": ("left_knee", "leftleg", "ltibia", "leftlowleg", "leftlowerleg", "leftknee", "lshin"),
    "left_foot": ("left_foot", "leftfoot", "lfoot", "leftankle"),
    "right_hip": ("right_hip", "rightupleg", "rfemur", "rightupperleg", "righthip", "rthigh"),
    "right_knee": ("right_knee", "rightleg", "rtibia", "rightlowleg", "rightlowerleg", "rightknee", "rshin"),
    "right_foot": ("right_foot", "rightfoot", "rfoot", "rightankle"),
}
# "cmu": the CMU database's ASF length unit, 1/0.45 inch, kept by its BVH conversions
UNITS = {"m": 1.0, "dm": 0.1, "cmu": 0.0254 / 0.45, "inch": 0.0254, "cm": 0.01, "mm": 0.001}
MAX_BYTES = 20_000_000
# bvhio keeps a Python object per joint per frame (measured: 807,000 of them, a 20 MB CMU file, take 10.6 s and 375 MB)
MAX_KEYFRAMES = 400_000  # frames x joints
MAX_JOINTS = 1000
MAX_LINES = 1_000_000  # bvhio reads a line in about a microsecond, blank or not; a real file has frames + ~8 per joint
MAX_DEPTH = 100  # joints from the root to the deepest leaf; a human rig has about a dozen
MAX_SECONDS = 600.0  # duration of the motion
MAX_HEADER_INTEGER = 10**9  # Frames: and CHANNELS counts (far beyond MAX_KEYFRAMES: only to keep the numbers floats)
# degrees in a rotation channel: far beyond any turn a take makes (bvhio's single-precision quaternions of 1e300
# degrees come out zero)
MAX_ANGLE = 1e6
FRAME_TIME_RANGE = (1e-4, 1.0)  # seconds per frame: 1 to 10000 frames per second
CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
LEG_M = 0.85  # hip to ankle of an adult, the yardstick for guessing a file's units


def _plain(name: str) -> str:
    return name.rsplit(":", 1)[-1].lower()


def joint_mapping(names: list[str], overrides: dict[str, str] | None = None) -> list[int]:
    """BVH joint names -> for each Kinect joint, the index of the BVH joint that stands for it."""
    index = {}
    for i, n in enumerate(names):
        index.setdefault(_plain(n), i)
    found, missing = [], []
    for kinect in KINECT15.joint_names:
        candidates = ((overrides or {}).get(kinect),) if overrides and kinect in overrides else NAME_TABLE[kinect]
        hit = next((index[_plain(c)] for c in candidates if c and _plain(c) in index), None)
        found.append(hit)
        if hit is None:
            missing.append(f"{kinect} ({' / '.join(candidates)})")
    if missing:
        raise DataFormatError(f"BVH skeleton not recognised: no joint for {', '.join(missing)}; "
                              "give a JSON mapping from Kinect joint names to this file's joint names")
    return found


def forward_kinematics(container) -> tuple[np.ndarray, list[str]]:
    """A bvhio BvhContainer -> (world positions (T, N, 3) in file units, joint names), parents before children."""
    layout = container.Root.layout()
    joints = [j for j, _, _ in layout]
    parent = {id(c): k for k, j in enumerate(joints) for c in j.Children}
    T = container.FrameCount
    pos = np.zeros((T, len(joints), 3))
    rot: list[Rotation] = []
    for k, j in enumerate(joints):
        if len(j.Keyframes) != T:
            raise DataFormatError(f"BVH joint {j.Name}: {len(j.Keyframes)} keyframes for {T} frames")
        local_t = np.array([[p.Position.x, p.Position.y, p.Position.z] for p in j.Keyframes])
        local_r = Rotation.from_quat([[p.Rotation.x, p.Rotation.y, p.Rotation.z, p.Rotation.w] for p in j.Keyframes])
        p = parent.get(id(j))
        if p is None:
            pos[:, k], r = local_t, local_r
        else:
            pos[:, k], r = pos[:, p] + rot[p].apply(local_t), rot[p] * local_r
        rot.append(r)
    return pos, [j.Name for j in joints]


def read_bvh(path: Path | str, mapping: dict[str, str] | Path | None = None, units: str = "auto",
             up: str = "y") -> np.ndarray:
    """A BVH file -> (T, 15, 3) Kinect joint positions in metres, Y up, resampled to 15 fps."""
    import bvhio

    path = Path(path)
    if isinstance(mapping, (str, Path)):
        mapping = _read_mapping(Path(mapping))
    _check_layout(path, _read_text(path))
    try:
        container = bvhio.readAsBvh(str(path))
    except Exception as err:  # bvhio raises bare exceptions of many kinds for malformed text
        raise DataFormatError(f"{path}: not a readable BVH file ({type(err).__name__}: {str(err)[:120]})") from None
    world, names = forward_kinematics(container)
    kinect = world[:, joint_mapping(names, mapping)]
    if up == "z":  # Z-up files: (x, y, z) -> (x, z, -y), still right-handed
        kinect = np.stack([kinect[..., 0], kinect[..., 2], -kinect[..., 1]], axis=-1)
    elif up != "y":
        raise ValueError(f"up axis must be 'y' or 'z', not {up!r}")
    kinect = kinect * _unit_scale(kinect, units, path)
    check_world_positions(kinect, str(path))
    return resample(kinect, 1.0 / container.FrameTime, TARGET_FPS)


def _read_text(path: Path) -> str:
    """The file's text as bvhio reads it (default encoding, universal newlines), refusing what is not BVH text."""
    check_input(path, "BVH leader", MAX_BYTES)
    try:
        with path.open("r") as f:  # as bvhio opens it
            text = f.read()
    except UnicodeDecodeError as err:
        raise DataFormatError(f"{path}: not a text file ({err.reason} at byte {err.start})") from None
    except OSError as err:
        raise DataFormatError(f"{path}: cannot read ({err.strerror})") from None
    if not text.lstrip().startswith("HIERARCHY"):
        raise DataFormatError(f"{path}: not a BVH file (it does not begin with HIERARCHY)")
    lines = text.count("\n")
    if lines > MAX_LINES:
        raise DataFormatError(f"{path}: {lines} lines; BVH files of up to {MAX_LINES} lines are read")
    return text


class _Lines:
    """The non-blank lines of a text as bvhio's reader sees them (split on whitespace), with their line numbers."""

    def __init__(self, path: Path, text: str):
        self.path, self.text = path, text
        self.matches = re.finditer(r"\S[^\n]*", text)  # each from its first non-space character to the line's end
        self.start = 0

    def line_number(self) -> int:
        return self.text.count("\n", 0, self.start) + 1

    def fail(self, problem: str) -> DataFormatError:
        return DataFormatError(f"{self.path}:{self.line_number()}: {problem}")

    def next(self, what: str) -> list[str]:
        match = next(self.matches, None)
        if match is None:
            raise DataFormatError(f"{self.path}: the file ends before {what} (truncated?)")
        self.start = match.start()
        return match.group().split()

    def expect(self, keyword: str, what: str, count: int | None = None) -> list[str]:
        """The next line, which must begin with `keyword` (and have `count` more tokens, where given)."""
        tokens = self.next(what)
        if tokens[0] != keyword or (count is not None and len(tokens) != count + 1):
            raise self.fail(f"expected {what}, found {' '.join(tokens)[:60]!r}")
        return tokens

    def offset(self, joint: str) -> None:
        values = self.expect("OFFSET", f"the OFFSET x y z of {joint}", 3)[1:]
        if not all(_finite(v) for v in values):
            raise self.fail(f"OFFSET of {joint} is not three finite numbers")


def _finite(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _check_layout(path: Path, text: str) -> None:
    """Hold the text to what bvhio needs in order to return (module docstring); DataFormatError naming the line."""
    lines = _Lines(path, text)
    lines.expect("HIERARCHY", "HIERARCHY")
    root = lines.expect("ROOT", "ROOT and the root joint's name")
    if len(root) < 2:
        raise lines.fail("the ROOT joint has no name")
    names: set[str] = set()
    open_joints: list[str] = []
    channels: list[str] = []  # every channel's name, in the order of the motion rows
    pending: str | None = root[1]
    while pending is not None or open_joints:
        if pending is not None:  # a joint's head: {, OFFSET, CHANNELS
            if pending in names:
                raise lines.fail(f"joint name {pending!r} is used twice")
            if len(names) >= MAX_JOINTS:
                raise lines.fail(f"more than {MAX_JOINTS} joints")
            if len(open_joints) >= MAX_DEPTH:
                raise lines.fail(f"the hierarchy is more than {MAX_DEPTH} joints deep")
            names.add(pending)
            open_joints.append(pending)
            lines.expect("{", f"'{{' opening joint {pending}", 0)
            lines.offset(pending)
            declared = lines.expect("CHANNELS", f"the CHANNELS of {pending}")
            count = declared[1] if len(declared) > 1 else ""
            if not (count.isascii() and count.isdigit()) or int(count) != len(declared) - 2:  # int() takes '³' as no digit
                raise lines.fail(f"CHANNELS of {pending}: a count followed by that many channel names is expected")
            unknown = [c for c in declared[2:] if c not in CHANNEL_NAMES]
            if unknown:
                raise lines.fail(f"CHANNELS of {pending}: unknown channel {unknown[0][:30]!r}; known: {', '.join(CHANNEL_NAMES)}")
            channels += declared[2:]
            pending = None
            continue
        tokens = lines.next(f"the closing '}}' of joint {open_joints[-1]}")
        if tokens[0] == "JOINT":
            if len(tokens) < 2:
                raise lines.fail("a JOINT without a name")
            pending = tokens[1]
        elif tokens[0] == "End":
            lines.expect("{", f"'{{' opening the end site of {open_joints[-1]}")
            lines.offset(f"the end site of {open_joints[-1]}")
            lines.expect("}", f"'}}' closing the end site of {open_joints[-1]}")
        elif tokens[0] == "}":
            open_joints.pop()
        else:
            raise lines.fail(f"expected JOINT, End Site or '}}' in joint {open_joints[-1]}, found {' '.join(tokens)[:60]!r}")
    lines.expect("MOTION", "MOTION", 0)
    frames = _header_number(lines, lines.expect("Frames:", "'Frames: N'", 1)[1], "Frames", int)
    frame_time = _header_number(lines, lines.expect("Frame", "'Frame Time: seconds'", 2)[2], "Frame Time", float)
    low, high = FRAME_TIME_RANGE
    if not low <= frame_time <= high:
        raise lines.fail(f"Frame Time {frame_time:g} s: frame times from {low:g} to {high:g} s are accepted (1 to 10000 frames per second)")
    if frames < 2:
        raise lines.fail(f"Frames: {frames}; at least 2 frames are needed")
    if frames * len(names) > MAX_KEYFRAMES:
        raise lines.fail(f"Frames: {frames} of {len(names)} joints; up to {MAX_KEYFRAMES} joint-frames are read")
    if (frames - 1) * frame_time > MAX_SECONDS:
        raise lines.fail(f"Frames: {frames} at Frame Time {frame_time:g} s lasts {(frames - 1) * frame_time:.0f} s; "
                         f"motions up to {MAX_SECONDS:.0f} s are read")
    _check_motion(lines, frames, channels)


def _header_number(lines: _Lines, text: str, field: str, kind: type) -> float:
    try:
        value = kind(text)
    except ValueError:
        raise lines.fail(f"{field}: {text[:30]!r} is not {'an integer' if kind is int else 'a number'}") from None
    if not math.isfinite(value) if kind is float else abs(value) > MAX_HEADER_INTEGER:  # a 400-digit int is no float
        raise lines.fail(f"{field}: {text[:30]!r}{'...' if len(text) > 30 else ''} is not "
                         f"{'finite' if kind is float else f'an integer up to {MAX_HEADER_INTEGER:.0e}'}")
    return value


def _check_motion(lines: _Lines, frames: int, names: list[str], chunk: int = 2048) -> None:
    """The first `frames` rows of the MOTION block: present, a number for each channel of `names` each, all finite,
    the angles within MAX_ANGLE."""
    channels = len(names)
    angle = np.array([n.endswith("rotation") for n in names])
    done = 0
    while done < frames:
        rows, starts = [], []
        for _ in range(min(chunk, frames - done)):
            match = next(lines.matches, None)
            if match is None:
                raise DataFormatError(f"{lines.path}: the MOTION block has {done + len(rows)} frames; its Frames: line "
                                      f"says {frames} (truncated?)")
            if len(match.group()) > 64 * channels:  # refused before it is split into far more values than declared
                lines.start = match.start()
                raise lines.fail(f"a motion row of {len(match.group())} characters for {channels} channels")
            rows.append(match.group().split())
            starts.append(match.start())
        for row, start in zip(rows, starts, strict=True):
            if len(row) != channels:
                lines.start = start
                raise lines.fail(f"a motion row of {len(row)} values; the hierarchy declares {channels} channels")
        try:
            values = np.array(rows, dtype=np.float64)
            sane = bool(np.isfinite(values).all() and (np.abs(values[:, angle]) <= MAX_ANGLE).all())
        except ValueError:
            sane = False
        if not sane:  # (bvhio parses each value with float(), as _finite does)
            k, c = next((k, c) for k, row in enumerate(rows) for c, v in enumerate(row)
                        if not _finite(v) or (angle[c] and abs(float(v)) > MAX_ANGLE))
            lines.start = starts[k]
            if not _finite(rows[k][c]):
                raise lines.fail("a motion value that is not a finite number (NaN, infinity or text)")
            raise lines.fail(f"a {names[c]} of {float(rows[k][c]):g} degrees; angles up to {MAX_ANGLE:g} are read")
        done += len(rows)


def _read_mapping(path: Path) -> dict[str, str]:
    text = read_input_text(path, "joint mapping", MAX_SETTINGS_BYTES)
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as err:
        raise DataFormatError(f"{path}: unreadable joint mapping ({type(err).__name__})") from None
    if not isinstance(d, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in d.items()):
        raise DataFormatError(f"{path}: a joint mapping is a JSON object of Kinect joint name -> BVH joint name")
    unknown = sorted(set(d) - set(KINECT15.joint_names))
    if unknown:
        raise DataFormatError(f"{path}: unknown Kinect joints {unknown}; expected some of {list(KINECT15.joint_names)}")
    return d


def _unit_scale(kinect: np.ndarray, units: str, path: Path) -> float:
    if units != "auto":
        if units not in UNITS:
            raise ValueError(f"units must be 'auto' or one of {sorted(UNITS)}, not {units!r}")
        return UNITS[units]
    legs = [(9, 10, 11), (12, 13, 14)]
    leg = np.median([np.linalg.norm(kinect[:, a] - kinect[:, b], axis=-1) + np.linalg.norm(kinect[:, b] - kinect[:, c], axis=-1)
                     for a, b, c in legs])
    if not leg > 0:
        raise DataFormatError(f"{path}: legs of zero length; cannot tell the units (give them)")
    return min(UNITS.values(), key=lambda s: abs(np.log(leg * s / LEG_M)))


def resample(motion: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Linear interpolation in time of (T, J, 3) from fps_in to fps_out (the first frame is kept)."""
    if abs(fps_in - fps_out) < 1e-6:
        return motion
    t_in = np.arange(len(motion)) / fps_in
    t_out = np.arange(int(np.floor(t_in[-1] * fps_out + 1e-3)) + 1) / fps_out  # frame times rounded in files: tolerate it
    flat = motion.reshape(len(motion), -1)
    return np.stack([np.interp(t_out, t_in, flat[:, c]) for c in range(flat.shape[1])], axis=1).reshape(len(t_out), *motion.shape[1:])


# ---- export ---------------------------------------------------------------------------------
# Rest pose (character facing +Z, Y up, left = +X): a T-pose, each bone along this direction at its median length.
REST_DIRECTIONS = {
    "neck": (0, 1, 0), "head": (0, 1, 0),
    "left_shoulder": (1, 0, 0), "left_elbow": (1, 0, 0), "left_hand": (1, 0, 0),
    "right_shoulder": (-1, 0, 0), "right_elbow": (-1, 0, 0), "right_hand": (-1, 0, 0),
    "left_hip": (0.35, -1, 0), "left_knee": (0, -1, 0), "left_foot": (0, -1, 0),
    "right_hip": (-0.35, -1, 0), "right_knee": (0, -1, 0), "right_foot": (0, -1, 0),
}
CHANNELS = "Xposition Yposition Zposition Zrotation Xrotation Yrotation"


def _swing(rest: np.ndarray, target: np.ndarray) -> Rotation:
    """Shortest-arc rotations taking the unit vector `rest` (3,) onto each row of `target` (T, 3)."""
    b = target / np.maximum(np.linalg.norm(target, axis=-1, keepdims=True), 1e-12)
    cross, dot = np.cross(rest, b), b @ rest
    sin = np.linalg.norm(cross, axis=-1)
    axis = np.where(sin[:, None] > 1e-9, cross / np.maximum(sin, 1e-12)[:, None], np.cross(rest, [0.0, 0.0, 1.0]) + [0.0, 0.0, 1e-6])
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    return Rotation.from_rotvec(axis * np.arctan2(sin, dot)[:, None])


def bone_rotations(positions: np.ndarray, skeleton: Skeleton = KINECT15) -> tuple[list[Rotation], np.ndarray]:
    """(T, J, 3) -> (world rotation per joint, rest offsets (J, 3)): each bone swung from its rest direction; a
    joint with several children (torso, neck) gets the rotation that best aligns all of them (Kabsch)."""
    names, parents = skeleton.joint_names, skeleton.parents
    lengths = np.median(np.linalg.norm(positions - positions[:, [max(p, 0) for p in parents]], axis=-1), axis=0)
    rest = np.zeros((len(names), 3))
    for j, n in enumerate(names):
        if parents[j] >= 0:
            d = np.asarray(REST_DIRECTIONS[n], float)
            rest[j] = d / np.linalg.norm(d) * lengths[j]
    children = {j: [c for c, p in enumerate(parents) if p == j] for j in range(len(names))}
    world: list[Rotation | None] = [None] * len(names)
    for j in _parents_first(parents):
        kids, p = children[j], parents[j]
        if len(kids) > 1:
            world[j] = Rotation.concatenate([Rotation.align_vectors(positions[t, kids] - positions[t, j], rest[kids])[0]
                                             for t in range(len(positions))])
        elif len(kids) == 1:
            parent_rot = world[p] if p >= 0 else Rotation.identity(len(positions))
            local_dir = parent_rot.inv().apply(positions[:, kids[0]] - positions[:, j])
            world[j] = parent_rot * _swing(rest[kids[0]] / max(lengths[kids[0]], 1e-9), local_dir)
        else:
            world[j] = world[p]
    return world, rest


def _parents_first(parents: tuple[int, ...]) -> list[int]:
    order, seen = [], set()
    while len(order) < len(parents):
        for j, p in enumerate(parents):
            if j not in seen and (p < 0 or p in seen):
                order.append(j)
                seen.add(j)
    return order


def write_bvh(path: Path | str, positions: np.ndarray, skeleton: Skeleton = KINECT15, fps: float = TARGET_FPS) -> None:
    """(T, J, 3) metres, Y up -> a BVH file in metres: exact positions (translation channels) + bone swings."""
    positions = np.asarray(positions, np.float64)
    if not np.isfinite(positions).all():
        raise DataFormatError("refusing to write a BVH of non-finite positions")
    world, rest = bone_rotations(positions, skeleton)
    parents = skeleton.parents
    order = _hierarchy_order(parents)
    columns = []
    for j in order:
        p = parents[j]
        if p < 0:
            local_t, local_r = positions[:, j], world[j]
        else:
            local_t, local_r = world[p].inv().apply(positions[:, j] - positions[:, p]), world[p].inv() * world[j]
        columns += [local_t, local_r.as_euler("ZXY", degrees=True)]
    motion = np.concatenate(columns, axis=1)
    lines = ["HIERARCHY"] + _hierarchy_lines(skeleton, rest, skeleton.root, 0)
    lines += ["MOTION", f"Frames: {len(positions)}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in motion]
    Path(path).write_text("\n".join(lines) + "\n")


def _hierarchy_order(parents: tuple[int, ...], j: int | None = None) -> list[int]:
    """Depth-first order in which the HIERARCHY section declares the joints (and MOTION lists their channels)."""
    j = parents.index(-1) if j is None else j
    return [j] + [k for c, p in enumerate(parents) if p == j for k in _hierarchy_order(parents, c)]


def _hierarchy_lines(skeleton: Skeleton, rest: np.ndarray, j: int, depth: int) -> list[str]:
    pad, name = "  " * depth, skeleton.joint_names[j]
    head = f"{pad}ROOT {name}" if depth == 0 else f"{pad}JOINT {name}"
    out = [head, pad + "{", f"{pad}  OFFSET {rest[j][0]:.6f} {rest[j][1]:.6f} {rest[j][2]:.6f}", f"{pad}  CHANNELS 6 {CHANNELS}"]
    kids = [c for c, p in enumerate(skeleton.parents) if p == j]
    for c in kids:
        out += _hierarchy_lines(skeleton, rest, c, depth + 1)
    if not kids:  # an end site 5 cm further, as most tools expect one
        out += [f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 0.000000 0.050000 0.000000", pad + "  }"]
    return out + [pad + "}"]
