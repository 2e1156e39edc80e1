"""Claims: which process runs which task, so sweeps sharing one ``--out`` never run a task
twice.

A claim is an exclusive ``flock`` on ``OUT/.claims/<hash of the run identity>.claim``, taken
by the sweep's parent process (which alone writes the store, whatever the executor) just
before it hands the task to a worker and released once the task's record is appended.  The
kernel drops a lock when its holder dies, however it dies (SIGKILL included), so a claim is
never stale and needs no pid bookkeeping; the file names its holder (``pid@host``) for
people.  Locks taken by the parent are not inherited by its spawned workers.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import socket
from pathlib import Path

CLAIMS_DIR = ".claims"


class Claim:
    """A held claim; :meth:`release` it when the task's record is on disk."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path, self._fd = path, fd

    def release(self) -> None:
        """Remove the claim file, then drop the lock (a process that opened the file before
        the removal notices, see :func:`try_claim`)."""
        if self._fd < 0:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self._fd)
            self._fd = -1


def claim_path(folder: str | os.PathLike, identity: tuple) -> Path:
    """Where the claim of the run ``identity`` lives under the output ``folder``."""
    digest = hashlib.sha1(repr(identity).encode()).hexdigest()[:24]
    return Path(folder) / CLAIMS_DIR / f"{digest}.claim"


def try_claim(folder: str | os.PathLike, identity: tuple, label: str = "") -> Claim | None:
    """Claim the run ``identity`` now, or ``None`` when another process holds it."""
    path = claim_path(folder, identity)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        # the holder may have released (removed) the file between our open and our lock:
        # then we hold a lock on a file no one else will see; open the path again
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            try:   # the note is for people: the lock is the claim (a full disk refuses it)
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}@{socket.gethostname()} {label}\n".encode())
            except OSError:
                pass
            return Claim(path, fd)
        os.close(fd)


def holder(folder: str | os.PathLike, identity: tuple) -> str:
    """Who holds the claim of ``identity`` (``pid@host``), as its file says, or ``""``."""
    try:
        return claim_path(folder, identity).read_text().split(" ", 1)[0].strip()
    except OSError:
        return ""
