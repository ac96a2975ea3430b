"""Reading .npz files within a memory budget and without unpickling.

`np.load` trusts what a file says about itself: a few hundred kilobytes of zeros can declare gigabytes of frames,
and a file that is not a zip is offered to the unpickler (whose refusal advises `allow_pickle`). Here the zip's
directory (each member's declared uncompressed size) and each array's .npy header (shape, dtype) are checked
against the budget and against each other before any array is allocated; zipfile never inflates a member past
its declared size, so the budget holds for what is read.
"""

from __future__ import annotations

import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from imm_model.errors import DataFormatError
from imm_model.inputs import check_input

NUMERIC_KINDS = "biuf"  # bool, signed and unsigned integers, floats


def read_npz(path: Path, names: Iterable[str], max_bytes: int, what: str) -> dict[str, np.ndarray]:
    """The arrays `names` of the .npz at `path`, each required; a one-line DataFormatError when one is missing or
    not numeric, or when the file or the arrays' declared sizes exceed `max_bytes` (`what` names the kind of file
    in that message: "leader", "interaction bundle")."""
    path = Path(path)
    try:
        check_input(path, f"{what} file", max_bytes)
        if not zipfile.is_zipfile(path):
            raise DataFormatError(f"{path}: unreadable .npz (not a zip of .npy arrays)")
        with zipfile.ZipFile(path) as zf:
            members = {info.filename.removesuffix(".npy"): info for info in zf.infolist() if info.filename.endswith(".npy")}
            names = list(dict.fromkeys(names))
            missing = [n for n in names if n not in members]
            if missing:
                raise DataFormatError(f"{path}: no {missing[0]!r} array (found {', '.join(list(members)[:10]) or 'none'})")
            declared = sum(members[n].file_size for n in names)
            if declared > max_bytes:
                raise DataFormatError(f"{path}: its arrays declare {declared / 1e6:.0f} MB uncompressed; "
                                      f"{what} files up to {max_bytes / 1e6:.0f} MB are read")
            return {n: _read_member(zf, members[n], path) for n in names}
    except DataFormatError:
        raise
    except OSError as err:
        raise DataFormatError(f"{path}: cannot read ({err.strerror or type(err).__name__})") from None
    except Exception as err:  # zipfile, zlib and numpy raise several types for corrupt members
        raise DataFormatError(f"{path}: unreadable .npz ({type(err).__name__}: {str(err)[:100]})") from None


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path) -> np.ndarray:
    name = info.filename.removesuffix(".npy")
    with zf.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version not in ((1, 0), (2, 0)):
            raise DataFormatError(f"{path}: array {name!r} is in .npy format {version}; 1.0 and 2.0 are read")
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(f)
        if dtype.kind not in NUMERIC_KINDS or dtype.hasobject:
            raise DataFormatError(f"{path}: array {name!r} has dtype {dtype}; numbers are expected")
        nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
        if nbytes > info.file_size:
            raise DataFormatError(f"{path}: array {name!r} declares shape {shape} ({nbytes / 1e6:.0f} MB) "
                                  f"in a {info.file_size / 1e6:.1f} MB member")
    with zf.open(info) as f:
        return np.lib.format.read_array(f, allow_pickle=False)
