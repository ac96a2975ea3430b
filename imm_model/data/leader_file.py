"""A user's own leader motion from a file: what `imm generate --leader` and the studio's upload read."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.data.sequence import check_world_positions
from imm_model.errors import DataFormatError

MAX_LEADER_BYTES = 16_000_000  # an .npz leader's arrays, uncompressed (about 44,000 frames of 15 joints in float64)


def read_leader_file(path: Path, bvh_map: Path | None = None) -> np.ndarray:
    """A .bvh (any recognisable human skeleton, data/bvh.py), an .npz with a `leader` array ((T, J, 3), or (T, 3J)
    as `check_leader` reads it), or an SBU skeleton_pos.txt (its more active person) -> (T, J, 3) world metres.
    Suffixes in either case; anything else, or beyond the readers' bounds, is a one-line DataFormatError."""
    from imm_model.inputs import check_input

    check_input(path, "leader file")  # a FIFO or a device named as such, never opened
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        from imm_model.data.bvh import read_bvh

        return read_bvh(path, bvh_map)
    if suffix == ".npz":
        from imm_model.data.npz import read_npz

        leader = read_npz(path, ["leader"], MAX_LEADER_BYTES, "leader")["leader"].astype(np.float64)
        if leader.ndim == 2 and leader.shape[1] % 3 == 0 and leader.shape[1] > 0:
            leader = leader.reshape(len(leader), -1, 3)
        if leader.ndim != 3 or leader.shape[2] != 3:
            raise DataFormatError(f"{path}: 'leader' has shape {leader.shape}; expected (frames, joints, 3)")
        return check_world_positions(leader, f"{path}: 'leader'")
    if suffix == ".txt":
        from imm_model.data.leader import actor_by_motion_energy
        from imm_model.data.sbu import normalized_to_metres, parse_skeleton_file

        _, positions = parse_skeleton_file(path)
        metres = normalized_to_metres(positions)
        return metres[actor_by_motion_energy(metres[0], metres[1])]
    raise DataFormatError(f"{path}: unsupported leader file type {path.suffix!r}; give a .bvh, .npz or SBU skeleton_pos.txt")
