"""Input files the user names. Each is checked before anything opens it: it must be a regular file within a size
bound. Opening a FIFO blocks until a writer comes, and a device such as /dev/zero (or a symlink to one) never
ends, so either would hang a reader or fill memory; here each is a one-line error at once, naming what the path is.
`read_input` also checks the file it opened (a path swapped for a FIFO after the check still cannot block it)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from imm_model.errors import DataFormatError, IMMError

MAX_SETTINGS_BYTES = 1_000_000  # a JSON file of settings (a config, a joint mapping): a few kilobytes in practice

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _refuse_mode(path: Path, mode: int, what: str, error: type[IMMError]) -> None:
    if stat.S_ISREG(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "not a file")
    link = f" (a link to {os.path.realpath(path)})" if path.is_symlink() else ""
    raise error(f"{path}{link}: {kind}, not a regular file ({what} expected)")


def _refuse_size(path: Path, size: int, what: str, max_bytes: int | None, error: type[IMMError]) -> None:
    if max_bytes is not None and size > max_bytes:
        raise error(f"{path}: {size / 1e6:.1f} MB; {what}s up to {max_bytes / 1e6:.0f} MB are read")


def check_input(path: Path | str, what: str, max_bytes: int | None = None,
                error: type[IMMError] = DataFormatError) -> int:
    """Refuse (`error`, one line naming the path and what it is) a path that is missing, is not a regular file, or
    holds more than `max_bytes`; `what` names the kind of file ("leader file", "checkpoint"). -> its size in bytes."""
    path = Path(path)
    try:
        st = path.stat()  # follows symlinks: a link to /dev/zero is judged as /dev/zero
    except FileNotFoundError:
        raise error(f"{path}: {what} not found") from None
    except OSError as err:
        raise error(f"{path}: cannot read ({err.strerror or type(err).__name__})") from None
    _refuse_mode(path, st.st_mode, what, error)
    _refuse_size(path, st.st_size, what, max_bytes, error)
    return st.st_size


def read_input(path: Path | str, what: str, max_bytes: int, error: type[IMMError] = DataFormatError) -> bytes:
    """The bytes of a regular file of at most `max_bytes` (`check_input`'s refusals otherwise)."""
    path = Path(path)
    check_input(path, what, max_bytes, error)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)  # never blocks, whatever the path is by now
        with open(fd, "rb") as f:
            st = os.fstat(fd)
            _refuse_mode(path, st.st_mode, what, error)
            data = f.read(max_bytes + 1)
    except OSError as err:
        raise error(f"{path}: cannot read ({err.strerror or type(err).__name__})") from None
    _refuse_size(path, len(data), what, max_bytes, error)  # it grew since the check
    return data


def read_input_text(path: Path | str, what: str, max_bytes: int, error: type[IMMError] = DataFormatError) -> str:
    """`read_input` decoded as UTF-8 text; anything else is a one-line `error`."""
    data = read_input(path, what, max_bytes, error)
    try:
        return data.decode()
    except UnicodeDecodeError as err:
        raise error(f"{path}: not a text file ({err.reason} at byte {err.start})") from None
