"""Output files. A command first plans every file it will write (`plan_outputs`: refused, before anything is
written, if one exists without --force, is one of the command's inputs, or is named twice), then writes each
atomically (`write_atomic`: a temporary file in the same folder, renamed over the target), so an interrupted or
failed write never leaves half a file, and never writes numbers that are not finite."""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imm_model.errors import IMMError

NAME_MAX = 255  # bytes in one file name, on every common file system
CHECKPOINT_SUFFIX = ".safetensors"  # a NAME.json beside NAME.safetensors is that checkpoint's sidecar


@dataclass(frozen=True)
class Output:
    path: Path
    what: str = "--out"  # how the user named it, for the one-line errors: "--json", "--out's leader copy"
    source: str = ""  # in a batch, the item it is written for (a leader file, a sequence id)


def _identity(path: Path) -> tuple:
    """Two names of one file compare equal: symlinks resolved, hard links by inode."""
    try:
        st = path.stat()
        return ("inode", st.st_dev, st.st_ino)
    except OSError:
        return ("path", str(path.resolve()))


def _writable_parent(out: Output) -> None:
    """The nearest existing folder above the file must be a writable folder (missing ones are created)."""
    parent = out.path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise IMMError(f"{out.what} {out.path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise IMMError(f"{out.what} {out.path}: {parent} is not a writable folder")


def plan_outputs(outputs: Sequence[Output], inputs: Iterable[Path | None] = (), force: bool = False,
                 force_option: str = "--force") -> None:
    """Refuse (one-line IMMError) the whole plan if any output is a folder, cannot be created, is named twice, is an
    input of the command (never, even with `force`), is the sidecar of a checkpoint the plan does not rewrite, or
    exists without `force`. Call it with every file the command will write before writing any."""
    sources = {_identity(Path(p)): Path(p) for p in inputs if p is not None}  # also those the command makes first
    planned: dict[tuple, Output] = {}
    for out in outputs:
        if out.path.is_dir():
            raise IMMError(f"{out.what} {out.path}: is a folder; give a file name")
        size = len(os.fsencode(out.path.name))
        if size > NAME_MAX:
            item = f" (for {out.source})" if out.source else ""
            raise IMMError(f"{out.what} {out.path.name[:40]}...{item}: a file name of {size} bytes; names up to {NAME_MAX} "
                           f"bytes can be written")
        _writable_parent(out)
        key = _identity(out.path)
        if key in planned:
            first = planned[key]
            if first.source and out.source:
                raise IMMError(f"{out.what} {out.path} would be written twice (for {first.source} and for {out.source}): "
                               f"give each item its own name")
            raise IMMError(f"{first.what} and {out.what} are the same file ({out.path}): give each output its own name")
        planned[key] = out
        if key in sources:
            raise IMMError(f"{out.what} {out.path}: that is an input of this command ({sources[key]}); choose another file")
    # planned files by name too: one that another writer creates meanwhile changes its identity, not its name
    planned_paths = {out.path for out in planned.values()}
    for out in planned.values():
        checkpoint = out.path.with_suffix(CHECKPOINT_SUFFIX)
        if (out.path.suffix.lower() == ".json" and checkpoint.exists() and checkpoint not in planned_paths
                and _identity(checkpoint) not in planned):
            raise IMMError(f"{out.what} {out.path}: that is the sidecar of the checkpoint {checkpoint}; choose another file")
        if out.path.exists() and not force:
            raise IMMError(f"{out.what} {out.path}: the file exists; pass {force_option} to replace it")


def _temporary(path: Path) -> Path:
    """A hidden name beside `path` (same folder, so the rename is atomic) that no other writer uses."""
    head = os.fsencode(path.name)[:200].decode(errors="ignore")  # within NAME_MAX (255 bytes), whole characters
    return path.with_name(f".{head}.{os.getpid()}-{secrets.token_hex(4)}.tmp")


def _failed(path: Path, err: OSError) -> IMMError:
    return IMMError(f"{path}: could not write it ({err.strerror or type(err).__name__})")


def write_atomic(path: Path | str, data: bytes | str | Callable[[Path], None], replace: bool = True,
                 force_option: str = "--force") -> None:
    """Write bytes, text, or whatever `data(temporary_path)` writes, under `path` in one rename (`write_files`)."""
    write_files([(Path(path), data)], replace, force_option)


def write_files(files: Sequence[tuple[Path, bytes | str | Callable[[Path], None]]], replace: bool = True,
                force_option: str = "--force") -> None:
    """Write each (path, bytes, text or `writer(temporary_path)`) to a temporary file beside its path, then rename
    them all into place: a failure while writing (a full disk, a refused permission: one-line IMMError) leaves every
    path as it was and no temporary file behind. Without `replace`, no file that exists by then is replaced, even one
    another process created after `plan_outputs` checked (each is linked into place, which fails on an existing name):
    the first such file is refused (one line naming `force_option`) and the files this call had put in place are
    removed again."""
    temporaries = [(_temporary(Path(path)), Path(path), data) for path, data in files]
    placed: list[Path] = []
    current = Path()
    try:
        for tmp, path, data in temporaries:
            current = path
            path.parent.mkdir(parents=True, exist_ok=True)
            if callable(data):
                data(tmp)
            else:
                tmp.write_bytes(data.encode() if isinstance(data, str) else data)
        for tmp, path, _ in temporaries:
            current = path
            if replace:
                os.replace(tmp, path)
            else:
                os.link(tmp, path)  # atomic, and never onto an existing name
            placed.append(path)
    except FileExistsError:
        for path in placed:
            path.unlink(missing_ok=True)
        raise IMMError(f"{current}: the file exists (another command wrote it meanwhile?); pass {force_option} to "
                       f"replace it") from None
    except OSError as err:
        raise _failed(current, err) from None
    finally:
        for tmp, _, _ in temporaries:
            tmp.unlink(missing_ok=True)


def write_new(path: Path | str, data: bytes) -> Path:
    """Write `data` under `path`, or under NAME-2.EXT, NAME-3.EXT, ... if that exists: never replaces a file, even
    one another process creates meanwhile (the temporary file is hard-linked to the free name) -> the name used."""
    path = Path(path)
    tmp = _temporary(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        for n in range(1, 10_000):
            target = path if n == 1 else path.with_name(f"{path.stem}-{n}{path.suffix}")
            try:
                os.link(tmp, target)
                return target
            except FileExistsError:
                continue
        raise IMMError(f"{path}: 10000 files of that name exist already; clear the folder")
    except OSError as err:
        raise _failed(path, err) from None
    finally:
        tmp.unlink(missing_ok=True)


def check_finite(values: np.ndarray, what: str) -> np.ndarray:
    """Pass finite arrays through; anything else is a one-line IMMError naming `what`."""
    arr = np.asarray(values)
    if not np.isfinite(arr).all():
        raise IMMError(f"{what} is not finite (NaN or infinity): refusing to write or report it")
    return arr


# One writer at a time per run folder: two trainers in one folder (two `imm train`, two `imm reproduce`, or one of
# each) would interleave their logs and checkpoints. An advisory lock (flock) on a file in the folder, released by the
# kernel when its holder ends, however it ends, so a killed command never leaves a stale lock behind.
LOCK_NAME = ".imm.lock"


class FolderLock:
    """`with FolderLock(folder, "--runs", "imm reproduce"):` holds the folder's lock, or refuses with one line naming
    the command and pid that hold it."""

    def __init__(self, folder: Path, what: str, command: str = "imm reproduce"):
        self.folder, self.what, self.command, self._fd = Path(folder), what, command, -1

    def __enter__(self) -> FolderLock:
        import fcntl

        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid, _, command = os.read(fd, 200).decode(errors="replace").strip().partition(" ")
            os.close(fd)
            raise IMMError(f"{self.what} {self.folder}: in use by another `{command or 'imm command'}` (pid {pid or '?'}); "
                           f"wait for it to finish or stop it") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()} {self.command}\n".encode())
        self._fd = fd
        return self

    def __exit__(self, *exc) -> None:
        os.close(self._fd)  # closing the file releases the lock
