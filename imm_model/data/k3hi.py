"""Reader for K3HI as shipped by InterFormer (`Skeletons/<class>/<n>/skeleton_{A,B}.mat`).

Each file holds one variable `curve_B`, float64 (45, T), coordinate-major: rows 0-14 x, 15-29 y,
30-44 z, in the same normalized convention as SBU (so the same metric formulas apply). Its joint
order differs from SBU's and is mapped onto the shared 15-joint Kinect skeleton here.
The actor is the first file of each line in Train.txt/Test.txt; sequences those lists do not cover
fall back to the motion-energy rule.
"""

from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path

import numpy as np

from imm_model.data.leader import LeaderChoice, actor_by_motion_energy, check_leader_choice
from imm_model.data.loading import LoadResult, load_many
from imm_model.data.sbu import normalized_to_metres
from imm_model.data.sequence import Interaction, check_world_positions
from imm_model.errors import DataFormatError
from imm_model.inputs import read_input, read_input_text

K3HI_CLASSES: tuple[str, ...] = (
    "approaching", "departing", "exchanging", "kicking", "pointing", "punching", "pushing", "shaking",
)
# KINECT15 joint i is K3HI joint K3HI_TO_KINECT15[i]
# (K3HI: 0 head, 1 neck, 2 L-sh, 3 R-sh, 4 L-elb, 5 R-elb, 6 L-hand, 7 R-hand, 8 torso, 9 L-hip,
#  10 R-hip, 11 L-knee, 12 R-knee, 13 L-foot, 14 R-foot).
K3HI_TO_KINECT15 = np.array([0, 1, 8, 2, 4, 6, 3, 5, 7, 9, 11, 13, 10, 12, 14])
MAX_BYTES = 2_000_000  # the dataset's files are under 25 kB
MAX_FRAMES = 100_000
MAX_INFLATED_BYTES = 45 * MAX_FRAMES * 8 + 65_536  # one compressed variable, inflated: curve_B at MAX_FRAMES and headers


def read_mat_skeleton(path: Path) -> np.ndarray:
    """One `skeleton_X.mat` -> (T, 15, 3) positions in normalized units, KINECT15 joint order."""
    from scipy.io import loadmat, whosmat

    try:
        data = read_input(path, "K3HI skeleton file", MAX_BYTES)
        _check_inflated_sizes(path, data)
        declared = dict((name, shape) for name, shape, _ in whosmat(io.BytesIO(data)))  # the headers only, nothing allocated
        if "curve_B" not in declared:
            raise DataFormatError(f"{path}: no 'curve_B' variable (found {sorted(declared)[:10]})")
        shape = declared["curve_B"]
        if len(shape) != 2 or shape[0] != 45 or not 0 < shape[1] <= MAX_FRAMES:
            raise DataFormatError(f"{path}: curve_B has shape {shape}, expected (45, T) with T in 1..{MAX_FRAMES}")
        mat = loadmat(io.BytesIO(data), variable_names=["curve_B"])
    except DataFormatError:
        raise
    except FileNotFoundError:
        raise DataFormatError(f"{path}: file not found") from None
    except Exception as err:  # scipy raises several types for corrupt files
        raise DataFormatError(f"{path}: unreadable .mat file ({type(err).__name__}: {str(err)[:100]})") from None
    arr = np.asarray(mat["curve_B"])
    if arr.ndim != 2 or arr.shape[0] != 45:
        raise DataFormatError(f"{path}: curve_B has shape {arr.shape}, expected (45, T)")
    if not np.issubdtype(arr.dtype, np.number):
        raise DataFormatError(f"{path}: curve_B is not numeric ({arr.dtype})")
    arr = arr.astype(np.float64)
    if arr.shape[1] == 0:
        raise DataFormatError(f"{path}: empty sequence (no frames)")
    if not np.isfinite(arr).all():
        raise DataFormatError(f"{path}: frame {int(np.argwhere(~np.isfinite(arr))[0, 1])}: NaN or infinite value")
    if arr.shape[1] < 2:
        raise DataFormatError(f"{path}: only 1 frame; at least 2 are needed")
    xyz = arr.reshape(3, 15, -1).transpose(2, 1, 0)  # (T, 15, 3)
    check_world_positions(normalized_to_metres(xyz), str(path))
    return xyz[:, K3HI_TO_KINECT15]


def _check_inflated_sizes(path: Path, data: bytes) -> None:
    """Inflate each compressed variable of a MAT v5 file (a 128-byte header, then elements of an 8-byte tag (type,
    size) and data; type 15 is zlib) only as far as MAX_INFLATED_BYTES: scipy would inflate it whole."""
    order = "<" if data[126:128] == b"IM" else ">"
    pos = 128
    while pos + 8 <= len(data):
        kind, size = struct.unpack(order + "II", data[pos : pos + 8])
        if kind == 15:
            inflated = zlib.decompressobj().decompress(data[pos + 8 : pos + 8 + size], MAX_INFLATED_BYTES + 1)
            if len(inflated) > MAX_INFLATED_BYTES:
                raise DataFormatError(f"{path}: a compressed variable inflates past {MAX_INFLATED_BYTES / 1e6:.0f} MB")
        pos += 8 + size


def read_actor_lists(root: Path) -> dict[str, str]:
    """'kicking/12' -> 'A' | 'B' from Train.txt and Test.txt (first file = actor)."""
    actors: dict[str, str] = {}
    for name in ("Train.txt", "Test.txt"):
        path = root / name
        if not path.exists():
            continue
        for line in read_input_text(path, "K3HI actor list", MAX_BYTES).splitlines():
            parts = line.split()
            if len(parts) != 2:
                continue
            first = Path(parts[0])
            actors[f"{first.parts[-3]}/{first.parts[-2]}"] = first.stem.rsplit("_", 1)[-1]
    return actors


def read_k3hi_sequence(folder: Path, leader: LeaderChoice = "actor", actors: dict[str, str] | None = None) -> Interaction:
    check_leader_choice(leader)
    action, number = folder.parts[-2], folder.parts[-1]
    if action not in K3HI_CLASSES:
        raise DataFormatError(f"{folder}: unknown class folder {action!r}")
    a_pos = read_mat_skeleton(folder / "skeleton_A.mat")
    b_pos = read_mat_skeleton(folder / "skeleton_B.mat")
    if len(a_pos) != len(b_pos):
        raise DataFormatError(f"{folder}: skeleton_A has {len(a_pos)} frames but skeleton_B {len(b_pos)}")
    people = normalized_to_metres(np.stack([a_pos, b_pos]))
    sequence_id = f"{action}/{number}"
    if leader in ("left", "right"):
        # K3HI files carry no left/right placement: use the lower mean image-x (metric X is flipped).
        order = np.argsort(-people[:, :, :, 0].mean(axis=(1, 2)))
        a, rule = int(order[0] if leader == "left" else order[1]), leader
    elif actors and sequence_id in actors:
        a, rule = (0 if actors[sequence_id] == "A" else 1), "k3hi_list"
    else:
        a, rule = actor_by_motion_energy(people[0], people[1]), "motion_energy"
    return Interaction(
        sequence_id=sequence_id,
        dataset="k3hi",
        action=action,
        subject_pair="",
        leader=people[a],
        follower=people[1 - a],
        leader_source="AB"[a],
        leader_rule=rule,
        frame_numbers=np.arange(len(a_pos)),
    )


def load_k3hi(root: Path | str, leader: LeaderChoice = "actor", strict: bool = False) -> LoadResult:
    """Load all 312 K3HI sequences (8 classes). Bad folders are skipped and reported unless strict."""
    root = Path(root)
    skeletons = root / "Skeletons"
    if not skeletons.is_dir():
        raise DataFormatError(f"{root}: K3HI folder not found (expected {skeletons})")
    check_leader_choice(leader)
    folders = sorted(
        (p.parent for p in skeletons.glob("*/*/skeleton_A.mat")),
        key=lambda p: (p.parts[-2], int(p.parts[-1]) if p.parts[-1].isdigit() else 10**9, p.parts[-1]),
    )
    if not folders:
        raise DataFormatError(f"{skeletons}: no <class>/<n>/skeleton_A.mat files found")
    actors = read_actor_lists(root)
    return load_many(folders, lambda f: read_k3hi_sequence(f, leader, actors), strict=strict, class_names=K3HI_CLASSES)


# The K3HI classes with an SBU counterpart (in SBU's class order). Approaching and departing are the two SBU classes
# the IMM paper leaves out (no reaction to synthesize: both people walk), and pointing has no SBU counterpart, so
# `imm reproduce` trains and scores K3HI on these five only.
K3HI_SHARED_CLASSES: tuple[str, ...] = ("kicking", "pushing", "shaking", "exchanging", "punching")


def read_split_lists(root: Path) -> dict[str, str]:
    """'kicking/12' -> 'train' | 'test' from Train.txt and Test.txt (InterFormer's split)."""
    split: dict[str, str] = {}
    for name in ("Train", "Test"):
        path = root / f"{name}.txt"
        if not path.exists():
            raise DataFormatError(f"{path}: K3HI split list not found")
        for line in read_input_text(path, "K3HI split list", MAX_BYTES).splitlines():
            parts = line.split()
            if len(parts) == 2:
                first = Path(parts[0])
                split[f"{first.parts[-3]}/{first.parts[-2]}"] = name.lower()
    return split


def k3hi_shared_dataset(root: Path | str):
    """-> (InteractionDataset of the shared classes, train indices, test indices). Train: Train.txt; test: Test.txt
    and the sequences neither list names (48 of 312; never anyone's training data), so each class has a test set."""
    from imm_model.data.dataset import InteractionDataset

    root = Path(root)
    result = load_k3hi(root, strict=True)
    shared = [it for it in result.interactions if it.action in K3HI_SHARED_CLASSES]
    data = InteractionDataset.from_interactions(shared, class_names=K3HI_SHARED_CLASSES,
                                                info={"source": "K3HI via InterFormer, see ../shared/datasets/k3hi/PROVENANCE.md"})
    split = read_split_lists(root)
    train = np.array([i for i, s in enumerate(data.sequence_ids) if split.get(s) == "train"], dtype=np.int64)
    return data, train, np.setdiff1d(np.arange(len(data)), train)
