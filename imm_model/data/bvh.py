"""BVH in and out: a leader from any MoCap tool, the synthesized reaction back to Blender, Maya or MotionBuilder.

Import: bvhio parses the file (channel orders, Euler angles); forward kinematics here, vectorized over frames
with scipy rotations; then the 15 Kinect joints are picked by name (NAME_TABLE, overridable with a JSON
mapping), converted to metres (units detected from the leg length, or given) and to the project's Y-up axis,
and resampled to 15 fps. A skeleton that cannot be mapped is a one-line DataFormatError naming what is missing.

Export (one character per file, the project's 15-joint hierarchy rooted at the torso): every joint carries
translation channels, so re-importing reproduces each position exactly (Kinect bone lengths vary from frame to
frame, which rotations alone cannot express), and rotation channels holding the swing of each bone from the
rest pose (median bone lengths, upright), so tools that animate by rotations show the right limb directions.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from imm_model.errors import DataFormatError
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
    _check_text(path)
    try:
        container = bvhio.readAsBvh(str(path))
    except Exception as err:  # bvhio raises bare exceptions of many kinds for malformed text
        raise DataFormatError(f"{path}: not a readable BVH file ({type(err).__name__}: {str(err)[:120]})") from None
    if container.FrameCount < 2 or not container.FrameTime or container.FrameTime <= 0:
        raise DataFormatError(f"{path}: BVH with {container.FrameCount} frames and frame time {container.FrameTime}")
    world, names = forward_kinematics(container)
    kinect = world[:, joint_mapping(names, mapping)]
    if up == "z":  # Z-up files: (x, y, z) -> (x, z, -y), still right-handed
        kinect = np.stack([kinect[..., 0], kinect[..., 2], -kinect[..., 1]], axis=-1)
    elif up != "y":
        raise ValueError(f"up axis must be 'y' or 'z', not {up!r}")
    kinect = kinect * _unit_scale(kinect, units, path)
    if not np.isfinite(kinect).all():
        raise DataFormatError(f"{path}: the BVH motion has non-finite values")
    return resample(kinect, 1.0 / container.FrameTime, TARGET_FPS)


def _check_text(path: Path) -> None:
    """Refuse what is not BVH text before the parser sees it (bvhio never returns on an empty file)."""
    try:
        with path.open("rb") as f:
            head = f.read(4096)
        size = path.stat().st_size
    except OSError as err:
        raise DataFormatError(f"{path}: cannot read ({err.strerror})") from None
    if size > MAX_BYTES:
        raise DataFormatError(f"{path}: {size / 1e6:.0f} MB; BVH leaders up to {MAX_BYTES / 1e6:.0f} MB are accepted")
    if not head.lstrip().upper().startswith(b"HIERARCHY"):
        raise DataFormatError(f"{path}: not a BVH file (it does not begin with HIERARCHY)")
    if b"MOTION" not in path.read_bytes():
        raise DataFormatError(f"{path}: BVH without a MOTION section")


def _read_mapping(path: Path) -> dict[str, str]:
    try:
        d = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, RecursionError) as err:
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
