"""Append-only JSON-lines store of run records: written as runs finish, resumable, shared.

Several processes may append to one file (two sweeps on one ``--out``, on one machine or
several sharing a disk): every append holds an exclusive ``flock`` on the file and writes one
whole line, so lines never interleave.  A write that fails (a full disk) is undone; a writer
killed mid-line, or a crash, leaves at most one partial or garbage last line, which readers
ignore and the next writer cuts off (under the lock) before appending: there are neither half
records nor lost complete rows.  A broken line before the last is corruption for a person to
look at: reading stops with an error naming its byte offset.

A run that raised is recorded too, as an *error record* (``status: "error"``, see
:func:`~ema_bench.leaderboard.tasks.error_record`).  Readers keep one record per run
identity (:func:`unique`): the first successful one, else the last error.  So a file merged
by hand, or written by two sweeps at once, never counts a run twice, and a retried run that
succeeds supersedes its old error.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

RUNS_FILE = "runs.jsonl"

log = logging.getLogger("ema_bench")


def model_version(record: dict) -> str:
    """The model version a record was run on (records before versions existed: ``"1"``)."""
    return str(record.get("model_version", "1"))


#: What identifies a solver run, with the model version: every place that asks "is this run
#: done / the same run?" (the store, the selection of a sweep, ``--check``) uses these.
IDENTITY_FIELDS = ("solver", "case", "track", "seed", "budget", "root_seed")


def run_identity(record: dict) -> tuple:
    """The one identity of a run record: solver, case, track, seed, budget, root seed and
    model version (records without a solver, e.g. blind-suite cases: key and model version).
    """
    if "solver" not in record:
        return record["key"], model_version(record)
    return (*(record.get(f, 0) if f == "root_seed" else record[f] for f in IDENTITY_FIELDS),
            model_version(record))


def is_current(record: dict) -> bool:
    """Whether a record was run on this installation's models (others are stale: they
    are neither reused on resume nor compared by ``--check``)."""
    from ..trace_cache import MODEL_VERSION

    return model_version(record) == MODEL_VERSION


def is_error(record: dict) -> bool:
    """Whether a record is of a run that raised (or whose worker died) instead of finishing."""
    return record.get("status") == "error"


def unique(records: Iterable[dict]) -> list[dict]:
    """One record per run identity, in order of first appearance: the first successful
    record, else the last error record (a retry's error is the newest news)."""
    kept: dict[tuple, dict] = {}
    for r in records:
        ident = run_identity(r)
        old = kept.get(ident)
        if old is None or is_error(old):
            kept[ident] = r
    return list(kept.values())


def _parse(data: bytes, where: str, offset: int = 0) -> tuple[list[dict], int]:
    """The records in ``data`` and how many bytes of it are intact.

    A last line without its newline (an interrupted write) or one that does not parse (a
    torn or garbage tail) is not intact; a broken line before the last is corruption a
    person must look at: ValueError naming it."""
    records, end = [], 0
    lines = data.split(b"\n")
    for i, line in enumerate(lines[:-1]):   # lines[-1]: the bytes after the last newline
        start = end
        end += len(line) + 1
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            # a broken line followed by complete ones is not a torn tail
            if any(rest.strip() for rest in lines[i + 1:-1]):
                raise ValueError(f"{where}: broken record at byte {offset + start} "
                                 f"({getattr(exc, 'msg', exc)})") from None
            return records, start
    return records, end


def read_records(path: str | os.PathLike) -> list[dict]:
    """The records of the file, one per run identity (:func:`unique`); a partial or broken
    last line is ignored."""
    path = Path(path)
    if not path.exists():
        return []
    return unique(_parse(path.read_bytes(), str(path))[0])


class RunStore:
    """Append records one whole line at a time, under an exclusive lock, flushed and synced.

    ``done`` holds the identities of successful records (what a resume skips; errors are
    retried), ``fresh`` those of every record appended since this store was opened, by
    this process or another (:meth:`refresh` reads them): a run in ``fresh`` is not run
    again by this process.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        self._offset = 0            # bytes of the file read so far: whole, intact lines
        self.done: set[tuple] = set()
        self.fresh: set[tuple] = set()
        with self._locked():
            self._repair()
        self.fresh.clear()          # only what is appended from now on

    @contextmanager
    def _locked(self) -> Iterator[None]:
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(self._fd, fcntl.LOCK_UN)

    def settled(self, identity: tuple) -> bool:
        """Whether this process must not run ``identity`` (again): it succeeded, or it was
        recorded, even as an error, since the store was opened (by a concurrent sweep)."""
        return identity in self.done or identity in self.fresh

    def refresh(self) -> None:
        """Read the records appended since the last read (by any process).  Without the
        lock: a line still being written has no newline yet and is read next time."""
        with open(self.path, "rb") as fh:
            fh.seek(self._offset)
            data = fh.read()
        records, intact = _parse(data, str(self.path), self._offset)
        for r in records:
            ident = run_identity(r)
            self.fresh.add(ident)
            if not is_error(r):
                self.done.add(ident)
        self._offset += intact

    def _repair(self) -> None:
        """Read what is new and cut a partial or broken last line: with the lock held, no
        one is writing it any more (its writer died or hit a full disk)."""
        self.refresh()
        size = os.fstat(self._fd).st_size
        if self._offset < size:
            log.warning("%s: dropping %d bytes of an incomplete last record (an interrupted "
                        "write)", self.path, size - self._offset)
            os.ftruncate(self._fd, self._offset)

    def append(self, record: dict) -> None:
        """Append ``record`` unless a successful record of its run is already there."""
        line = (json.dumps(record, sort_keys=True, allow_nan=False) + "\n").encode()
        with self._locked():
            self._repair()
            if run_identity(record) in self.done:
                return
            size = os.fstat(self._fd).st_size
            try:
                self._write(line)
                os.fsync(self._fd)
            except OSError as exc:
                os.ftruncate(self._fd, size)   # no half record left behind
                raise OSError(exc.errno or errno.EIO, "cannot append a record: "
                              f"{exc.strerror or exc}", str(self.path)) from None
            self.refresh()

    def _write(self, data: bytes) -> None:
        """One ``write`` after another until ``data`` is all written (a write may be short)."""
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> RunStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
