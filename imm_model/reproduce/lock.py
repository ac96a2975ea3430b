"""One `imm reproduce` at a time per folder: two on the same runs would train the same run directories at once
(interleaved logs, checkpoints from two trainers). An advisory lock (flock) on a file in the folder, released by
the kernel when its holder ends, however it ends, so a killed reproduce never leaves a stale lock behind."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from imm_model.errors import IMMError

LOCK_NAME = ".imm-reproduce.lock"


class FolderLock:
    """`with FolderLock(folder, "--runs"):` holds the folder's lock, or refuses with one line naming the holder."""

    def __init__(self, folder: Path, what: str):
        self.folder, self.what, self._fd = Path(folder), what, -1

    def __enter__(self) -> FolderLock:
        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise IMMError(f"{self.what} {self.folder}: in use by another `imm reproduce` (pid {holder}); wait for it "
                           f"to finish or stop it") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return self

    def __exit__(self, *exc) -> None:
        os.close(self._fd)  # closing the file releases the lock
