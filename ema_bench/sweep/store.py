"""Append-only JSON-lines store of records: written as tasks finish, resumable, shared.

Several processes may append to one file (two sweeps on one folder, on one machine or
several sharing a disk): every append holds an exclusive ``flock`` on the file and writes
whole lines (all the records of one task in one write), so lines never interleave and a task
is never half recorded.  A write that fails (a full disk) is undone; a writer killed
mid-line, or a crash, leaves at most one partial or garbage last line, which readers ignore
and the next writer cuts off (under the lock) before appending.  A broken line before the
last is corruption for a person to look at: reading stops with an error naming its byte
offset.  With a schema (:mod:`.schema`) every line read is type-checked: a wrong field stops
the reading with one line naming the file, the line and the field.

Each record has an *identity* (what makes two lines the same record) and belongs to a
*task* (what a sweep runs; a task may write several records, e.g. one tracking step per
inspection).  Readers keep one record per identity (:func:`unique`): the first successful
one, else the last error (``status: "error"``).  So a file merged by hand, or written by two
sweeps at once, never counts a record twice, and a retried task that succeeds supersedes
its old error.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from .schema import SchemaLike, check

log = logging.getLogger("ema_bench")

Identity = Callable[[dict], Hashable]


def model_version(record: dict) -> str:
    """The model version a record was made with (records before versions existed: ``"1"``)."""
    return str(record.get("model_version", "1"))


def current_version(record: dict) -> str:
    """The model version a record of its case is made on now: its suite's (emafdi-v3: 4;
    a record without a suite case: the installation's default)."""
    from ..suites import suite_of

    return suite_of(record.get("case")).model_version


def is_current(record: dict) -> bool:
    """Whether a record was made with the models its case runs on now
    (:func:`current_version`) or a compatible version (:data:`~ema_bench.trace_cache.
    COMPATIBLE_VERSIONS`; others are stale: they are neither reused on resume nor
    compared)."""
    from ..trace_cache import is_comparable

    return is_comparable(model_version(record), current_version(record))


def is_error(record: dict) -> bool:
    """Whether a record is of a task that raised instead of finishing."""
    return record.get("status") == "error"


def identity_version(record: dict) -> str:
    """The model version in a record's identity: this installation's for a record of a
    compatible version (:data:`~ema_bench.trace_cache.COMPATIBLE_VERSIONS`: the same run,
    reused on resume, a duplicate beside a current one), else the record's own."""
    from ..trace_cache import is_comparable

    version, current = model_version(record), current_version(record)
    return current if is_comparable(version, current) else version


def key_identity(record: dict) -> tuple:
    """The identity of a record named by its ``key``: key and model version
    (:func:`identity_version`)."""
    return record["key"], identity_version(record)


def _keep(kept: dict[Hashable, dict], ident: Hashable, record: dict) -> None:
    """Keep ``record`` as ``kept[ident]`` unless a successful record is there already."""
    old = kept.get(ident)
    if old is None or is_error(old):
        kept[ident] = record


def unique(records: Iterable[dict], identity: Identity = key_identity) -> list[dict]:
    """One record per identity, in order of first appearance: the first successful
    record, else the last error record (a retry's error is the newest news)."""
    kept: dict[Hashable, dict] = {}
    for r in records:
        _keep(kept, identity(r), r)
    return list(kept.values())


def _parse(data: bytes, where: str, offset: int = 0, line: int = 1,
           schema: SchemaLike | None = None) -> tuple[list[dict], int, int]:
    """The records in ``data``, how many bytes and lines of it are intact.

    A last line without its newline (an interrupted write) or one that does not parse (a
    torn or garbage tail) is not intact; a broken line before the last is corruption a
    person must look at: ValueError naming it.  ``line``: the file's line number of the
    first line of ``data`` (for the schema's messages)."""
    records, end = [], 0
    lines = data.split(b"\n")
    for i, raw in enumerate(lines[:-1]):   # lines[-1]: the bytes after the last newline
        start = end
        end += len(raw) + 1
        if not raw.strip():
            continue
        try:
            rec = json.loads(raw)
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            # a broken line followed by complete ones is not a torn tail
            if any(rest.strip() for rest in lines[i + 1:-1]):
                raise ValueError(f"{where}: broken record at byte {offset + start} "
                                 f"({getattr(exc, 'msg', exc)})") from None
            return records, start, line + i
        if schema is not None:
            check(rec, schema, f"{where}, line {line + i}")
        records.append(rec)
    return records, end, line + len(lines) - 1


def read_records(path: str | os.PathLike, identity: Identity = key_identity,
                 schema: SchemaLike | None = None) -> list[dict]:
    """The records of the file, one per identity (:func:`unique`); a partial or broken
    last line is ignored; with ``schema`` every line is type-checked."""
    path = Path(path)
    if not path.exists():
        return []
    return unique(_parse(path.read_bytes(), str(path), schema=schema)[0], identity)


def read_lines(path: str | os.PathLike, schema: SchemaLike | None = None
               ) -> tuple[list[dict], bool, int]:
    """Every record line of the file, in order (nothing deduplicated, type-checked with
    ``schema``), whether its last line is complete, and the number of the line after the last
    intact one: for readers that refuse a torn file rather than read it short."""
    data = Path(path).read_bytes()
    records, end, line = _parse(data, str(path), schema=schema)
    return records, end == len(data), line


class Store:
    """Append records whole lines at a time, under an exclusive lock, flushed and synced.

    Parameters
    ----------
    path : path
        The JSON-lines file (created with its folder).
    identity : callable
        record -> what makes two lines the same record (:func:`key_identity`).
    task_of : callable, optional
        record -> the identity of the task it completes, or ``None`` for a record that
        completes none (default: ``identity``).
    schema : optional
        Type check of every line read (:mod:`.schema`).
    retry_errors : bool
        Whether a task recorded as an error is run again by a resume (the leaderboard: the
        error may have been transient) or is done (a tracker's own failure is its result).

    ``done`` holds the tasks a resume skips, ``fresh`` every task recorded since this store
    was opened, by this process or another (:meth:`refresh` reads them): a task in
    ``fresh`` is not run again by this process.  ``records`` is :func:`unique` of the file.
    """

    def __init__(self, path: str | os.PathLike, identity: Identity = key_identity,
                 task_of: Identity | None = None, schema: SchemaLike | None = None,
                 retry_errors: bool = True) -> None:
        self.path = Path(path)
        self.identity, self.task_of = identity, task_of or identity
        self.schema, self.retry_errors = schema, retry_errors
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        self._offset, self._line = 0, 1   # bytes and lines read so far: whole, intact lines
        self._records: dict[Hashable, dict] = {}
        self.done: set = set()
        self.fresh: set = set()
        with self._locked():
            self._repair()
        self.fresh.clear()          # only what is appended from now on

    @property
    def records(self) -> list[dict]:
        """One record per identity (:func:`unique`), in order of first appearance."""
        return list(self._records.values())

    @contextmanager
    def _locked(self) -> Iterator[None]:
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(self._fd, fcntl.LOCK_UN)

    def settled(self, task: Hashable) -> bool:
        """Whether this process must not run ``task`` (again): it is done, or it was
        recorded, even as an error, since the store was opened (by a concurrent sweep)."""
        return task in self.done or task in self.fresh

    def refresh(self) -> None:
        """Read the records appended since the last read (by any process).  Without the
        lock: a line still being written has no newline yet and is read next time."""
        with open(self.path, "rb") as fh:
            fh.seek(self._offset)
            data = fh.read()
        records, intact, self._line = _parse(data, str(self.path), self._offset, self._line,
                                             self.schema)
        for r in records:
            _keep(self._records, self.identity(r), r)
            task = self.task_of(r)
            if task is None:
                continue
            self.fresh.add(task)
            if not (is_error(r) and self.retry_errors):
                self.done.add(task)
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

    def _known(self, record: dict) -> bool:
        old = self._records.get(self.identity(record))
        return old is not None and not is_error(old)

    def append(self, records: dict | Sequence[dict]) -> int:
        """Append ``records`` (one task's: written in one piece) but those whose identity
        has a successful record already; returns how many were written."""
        batch = [records] if isinstance(records, dict) else list(records)
        with self._locked():
            self._repair()
            new = [r for r in batch if not self._known(r)]
            if not new:
                return 0
            data = "".join(json.dumps(r, sort_keys=True, allow_nan=False) + "\n"
                           for r in new).encode()
            size = os.fstat(self._fd).st_size
            try:
                self._write(data)
                os.fsync(self._fd)
            except OSError as exc:
                os.ftruncate(self._fd, size)   # no half record left behind
                raise OSError(exc.errno or errno.EIO, "cannot append a record: "
                              f"{exc.strerror or exc}", str(self.path)) from None
            self.refresh()
        return len(new)

    def _write(self, data: bytes) -> None:
        """One ``write`` after another until ``data`` is all written (a write may be short)."""
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
