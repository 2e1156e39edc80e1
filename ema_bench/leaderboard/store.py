"""Append-only JSON-lines store of run records: written as runs finish, resumable.

A run killed mid-write leaves at most one partial last line; :func:`open_store` cuts it off
before appending, so there are neither duplicates nor lost complete rows.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

RUNS_FILE = "runs.jsonl"


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


def _repair(path: Path) -> None:
    """Drop a trailing partial line (an interrupted write)."""
    if not path.exists() or path.stat().st_size == 0:
        return
    with open(path, "rb+") as fh:
        data = fh.read()
        if data.endswith(b"\n"):
            return
        cut = data.rfind(b"\n") + 1
        fh.truncate(cut)


def read_records(path: str | os.PathLike) -> list[dict]:
    """Every complete record in the file (a partial last line is ignored)."""
    path = Path(path)
    if not path.exists():
        return []
    records = []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.endswith("\n"):
                break  # interrupted write
            line = line.strip()
            if not line:
                continue
            try:
                records.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}:{lineno}: broken record ({exc.msg})") from None
    return records


class RunStore:
    """Append records one line at a time, flushed and synced so a crash loses nothing."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        _repair(self.path)
        # identities of the runs recorded: another budget, root seed or model version is
        # another run, recorded beside the old one
        self.done = {run_identity(r) for r in read_records(self.path)}
        self._fh = open(self.path, "a", encoding="utf-8")

    def append(self, record: dict) -> None:
        ident = run_identity(record)
        if ident in self.done:
            return
        self._fh.write(json.dumps(record, sort_keys=True, allow_nan=False) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self.done.add(ident)

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> RunStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
