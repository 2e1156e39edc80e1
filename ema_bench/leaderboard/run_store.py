"""The leaderboard's run records on the sweep store (:mod:`ema_bench.sweep.store`).

A run's identity is its solver, case, track, seed, budget, root seed and model version
(:func:`run_identity`); a run that raised is recorded as an *error record* (``status:
"error"``, see :func:`~ema_bench.leaderboard.tasks.error_record`), scored as a failure and
run again by a resume.  Every line read is type-checked (:data:`RUN_SCHEMA`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from ..sweep.schema import opt, req
from ..sweep.store import Store, identity_version, is_current, is_error, model_version
from ..sweep.store import read_records as _read
from ..sweep.store import unique as _unique

__all__ = ["IDENTITY_FIELDS", "RUNS_FILE", "RUN_SCHEMA", "RunStore", "is_current", "is_error",
           "model_version", "read_records", "run_identity", "unique"]

RUNS_FILE = "runs.jsonl"

#: What identifies a solver run, with the model version: every place that asks "is this run
#: done / the same run?" (the store, the selection of a sweep, ``--check``) uses these.
IDENTITY_FIELDS = ("solver", "case", "track", "seed", "budget", "root_seed")

#: The fields a reader relies on, by type (records carry more; ``validate`` checks the rest).
RUN_SCHEMA = {"solver": req("str"), "case": req("str"), "track": req("str"),
              "seed": req("int"), "budget": req("int"), "root_seed": opt("int"),
              "model_version": opt("str|int"), "status": opt("str"), "key": opt("str"),
              "success": opt("bool"), "evals_to_success": opt("int|null"),
              "evaluations": opt("int"), "fitness": opt("number|null"),
              "wall_s": opt("number|null"), "seed_scheme": opt("int")}
#: Records without a solver (a blind-suite case read by the same readers): key only.
_KEYED = {"key": req("str"), "model_version": opt("str|int")}


def _schema(record: dict) -> dict:
    return RUN_SCHEMA if "solver" in record else _KEYED


def run_identity(record: dict) -> tuple:
    """The one identity of a run record: solver, case, track, seed, budget, root seed and
    model version (records without a solver, e.g. blind-suite cases: key and model version;
    a compatible earlier version counts as this one:
    :func:`~ema_bench.sweep.store.identity_version`)."""
    if "solver" not in record:
        return record["key"], identity_version(record)
    return (*(record.get(f, 0) if f == "root_seed" else record[f] for f in IDENTITY_FIELDS),
            identity_version(record))


def unique(records: Iterable[dict]) -> list[dict]:
    """One record per run (:func:`run_identity`): the first successful record, else the last
    error record."""
    return _unique(records, run_identity)


def read_records(path: str | os.PathLike) -> list[dict]:
    """The run records of the file, one per run (:func:`unique`), type-checked; a partial
    or broken last line is ignored."""
    return _read(path, run_identity, _schema)


def RunStore(path: str | os.PathLike) -> Store:
    """The store of a ``runs.jsonl``: one record per run, errors run again by a resume."""
    return Store(path, run_identity, schema=_schema)
