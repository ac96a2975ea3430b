"""Reader for the SBU Kinect Interaction dataset v2.0 (raw `skeleton_pos.txt` files).

Row format (dataset README): frame number, then persons PA (left) and PB (right), 15 joints each,
xyz interleaved: 91 comma-separated values. x, y are normalized to [0, 1] and z to [0, 7.8125];
the README's formulas turn them into millimetres: X = 1280 - 2560 x, Y = 960 - 1920 y,
Z = 10000 z / 7.8125. We expose metres (Y up) and keep the normalized units reachable through
`metres_to_normalized`, because the paper reports AFD in them.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np

from imm_model.data.leader import LeaderChoice, actor_by_motion_energy, check_leader_choice
from imm_model.data.loading import LoadResult, load_many
from imm_model.data.sequence import Interaction, check_world_positions
from imm_model.errors import DataFormatError
from imm_model.inputs import read_input, read_input_text

SBU_CLASSES: dict[str, str] = {
    "01": "approaching",
    "02": "departing",
    "03": "kicking",
    "04": "pushing",
    "05": "shaking_hands",
    "06": "hugging",
    "07": "exchanging_objects",
    "08": "punching",
}
# The six classes the IMM paper uses (197 sequences).
PAPER_CLASSES: tuple[str, ...] = ("kicking", "pushing", "shaking_hands", "hugging", "exchanging_objects", "punching")
ALL_CLASSES: tuple[str, ...] = tuple(SBU_CLASSES.values())
NUM_JOINTS = 15
NUM_COLUMNS = 1 + 2 * NUM_JOINTS * 3
MAX_BYTES = 10_000_000  # about 11,000 frames (the dataset's files are under 40 kB)
MAX_LINE_CHARS = 40 * NUM_COLUMNS
ACTOR_CSV = "interformer_actor_assignment.csv"
_PATH_RE = re.compile(r"^s\d\ds\d\d$")

_SCALE = np.array([-2.56, -1.92, 10.0 / 7.8125])  # metres per normalized unit, per axis
_OFFSET = np.array([1.28, 0.96, 0.0])  # metres


def normalized_to_metres(xyz: np.ndarray) -> np.ndarray:
    """(..., 3) dataset units -> metres (README formulas divided by 1000)."""
    return xyz * _SCALE + _OFFSET


def metres_to_normalized(xyz: np.ndarray) -> np.ndarray:
    """(..., 3) metres -> the dataset's normalized units (exact inverse of `normalized_to_metres`)."""
    return (xyz - _OFFSET) / _SCALE


def parse_skeleton_file(path: Path | str) -> tuple[np.ndarray, np.ndarray]:
    """One `skeleton_pos.txt` -> (frame numbers (T,), positions (2, T, 15, 3) normalized units).

    Raises DataFormatError naming the file and line for every malformed case.
    """
    path = Path(path)
    try:
        text = read_input(path, "skeleton file", MAX_BYTES).decode("ascii")
    except UnicodeDecodeError as err:
        raise DataFormatError(f"{path}: not a text file ({err.reason} at byte {err.start})") from None
    lines = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip()]
    if not lines:
        raise DataFormatError(f"{path}: empty file (no frames)")
    rows = []
    for lineno, line in lines:
        if len(line) > MAX_LINE_CHARS:  # refused before it is split into far more values than a row has
            raise DataFormatError(f"{path}:{lineno}: a line of {len(line)} characters; rows of {NUM_COLUMNS} values are expected")
        fields = line.rstrip(",").split(",")
        if len(fields) != NUM_COLUMNS:
            raise DataFormatError(f"{path}:{lineno}: expected {NUM_COLUMNS} comma-separated values, found {len(fields)}")
        try:
            rows.append([float(v) for v in fields])
        except ValueError:
            bad = next(v for v in fields if not _is_float(v))
            raise DataFormatError(f"{path}:{lineno}: non-numeric value {bad.strip()!r}") from None
    data = np.asarray(rows, dtype=np.float64)
    finite = np.isfinite(data)
    if not finite.all():
        row = int(np.argwhere(~finite)[0, 0])
        raise DataFormatError(f"{path}:{lines[row][0]}: NaN or infinite value")
    if len(data) < 2:
        raise DataFormatError(f"{path}: only {len(data)} frame; at least 2 are needed")
    if np.abs(data[:, 0]).max() > 2**53:
        raise DataFormatError(f"{path}: frame numbers beyond 2^53")
    positions = data[:, 1:].reshape(len(data), 2, NUM_JOINTS, 3).transpose(1, 0, 2, 3)
    check_world_positions(normalized_to_metres(positions), str(path))
    return data[:, 0].astype(np.int64), positions


def _is_float(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def read_actor_assignment(root: Path) -> dict[str, str]:
    """sequence id ('s01s02/03/001') -> 'PA' | 'PB' from InterFormer's labelling (may be absent)."""
    path = root / ACTOR_CSV
    if not path.exists():
        return {}
    text = read_input_text(path, "actor assignment", MAX_BYTES)
    return {row["sbu_sequence"]: row["actor_in_raw_file"] for row in csv.DictReader(io.StringIO(text, newline=""))}


def sbu_sequence_files(root: Path) -> list[Path]:
    """All `sXXsYY/CC/NNN/skeleton_pos.txt` files below `root`, sorted."""
    return sorted(p for p in root.glob("*/*/*/skeleton_pos.txt") if _PATH_RE.match(p.parts[-4]))


def read_sbu_sequence(
    path: Path, leader: LeaderChoice = "actor", actors: dict[str, str] | None = None
) -> Interaction:
    """Read one raw file into an `Interaction` in world metres with the chosen leader first."""
    check_leader_choice(leader)
    pair, class_code, number = path.parts[-4], path.parts[-3], path.parts[-2]
    if class_code not in SBU_CLASSES:
        raise DataFormatError(f"{path}: unknown class folder {class_code!r} (expected 01-08)")
    sequence_id = f"{pair}/{class_code}/{number}"
    frames, positions = parse_skeleton_file(path)
    metres = normalized_to_metres(positions)  # (2, T, 15, 3)
    if leader == "left":
        a, rule = 0, "left"
    elif leader == "right":
        a, rule = 1, "right"
    elif actors and sequence_id in actors:
        a, rule = (0 if actors[sequence_id] == "PA" else 1), "interformer"
    else:
        a, rule = actor_by_motion_energy(metres[0], metres[1]), "motion_energy"
    return Interaction(
        sequence_id=sequence_id,
        dataset="sbu",
        action=SBU_CLASSES[class_code],
        subject_pair=pair,
        leader=metres[a],
        follower=metres[1 - a],
        leader_source=("PA", "PB")[a],
        leader_rule=rule,
        frame_numbers=frames,
    )


def load_sbu(
    root: Path | str,
    classes: str | tuple[str, ...] = "paper",
    leader: LeaderChoice = "actor",
    strict: bool = False,
) -> LoadResult:
    """Load the raw SBU folder. `classes`: "paper" (6 classes, 197 sequences), "all" (8, 282) or names.

    Malformed files are skipped and listed in `result.skipped` unless `strict`, which raises on the first.
    """
    root = Path(root)
    if not root.is_dir():
        raise DataFormatError(f"{root}: SBU data folder not found")
    check_leader_choice(leader)
    wanted = PAPER_CLASSES if classes == "paper" else ALL_CLASSES if classes == "all" else tuple(classes)
    unknown = [c for c in wanted if c not in ALL_CLASSES]
    if unknown:
        raise ValueError(f"unknown SBU classes {unknown}; known: {list(ALL_CLASSES)}")
    files = sbu_sequence_files(root)
    if not files:
        raise DataFormatError(f"{root}: no sXXsYY/CC/NNN/skeleton_pos.txt files found")
    # Files under an unknown class folder are still read (and reported) so a typo is not silent.
    files = [p for p in files if SBU_CLASSES.get(p.parts[-3]) in wanted or p.parts[-3] not in SBU_CLASSES]
    actors = read_actor_assignment(root)
    return load_many(files, lambda p: read_sbu_sequence(p, leader, actors), strict=strict, class_names=wanted)
