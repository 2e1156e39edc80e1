"""What every suite version shares: target levels, the best-known table's keys and file.

A suite's fixed targets rest on its best-known table (``ema-bench targets``' JSON):
``{"suite", "model_version", "entries": {"case|track|seed": {"f_star", "f_nominal",
"x_star", ..}}}``.  The fitness targets are the ladder ``f* + p (f_nominal - f*)``
(:data:`FITNESS_PRECISIONS`), the parameter targets the best-so-far point within a fraction
of every judged parameter's range (:data:`PARAMETER_TARGETS`).
"""

from __future__ import annotations

import functools
import json
import math
import os
from collections.abc import Sequence
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path

from ..sweep.schema import check, opt, req
from ..trace_cache import MODEL_VERSION

#: The model version the shipped targets of suites emafdi-v1 and v2 were computed on (a suite
#: on another version says so: :attr:`~ema_bench.suites.base.Suite.model_version`).
SUITE_MODEL_VERSION = "3"
#: Fitness targets: ``f* + p (f_nominal - f*)`` for each precision ``p``.
FITNESS_PRECISIONS: tuple[float, ...] = (1e-1, 1e-2, 1e-3, 1e-4)
#: Parameter targets: the best-so-far point within this fraction of every judged range.
PARAMETER_TARGETS: tuple[float, ...] = (0.1, 0.03, 0.01)
#: Checkpoints of the fixed-budget view (evaluations), up to the run's budget.
BUDGET_CHECKPOINTS: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000,
                                       20000, 50000, 100000)
#: The root seed of the runs whose ``f*`` the suites ship.
TARGET_ROOT_SEED = 0


class SuiteError(ValueError):
    """A suite instance, version or target file that cannot be used."""


def check_model_version(suite: str, version: str = SUITE_MODEL_VERSION) -> None:
    """The suite's targets hold only on the models they were computed on: model ``version``
    must be one this installation runs (:data:`~ema_bench.params.MODEL_PARAMS`), and the
    default version's suites must be on the installed default."""
    from ..params import MODEL_PARAMS

    if MODEL_VERSION != SUITE_MODEL_VERSION or str(version) not in MODEL_PARAMS:
        raise SuiteError(f"suite {suite} was built on model version {version}, the installed "
                         f"models are versions {sorted(MODEL_PARAMS)} (default "
                         f"{MODEL_VERSION}): bump the suite")


def target_key(case: str, track: str, seed: int) -> str:
    """The key of a best-known entry (``small|twin|3``)."""
    return f"{case}|{track}|{seed}"


def package_file(name: str) -> Traversable:
    """A data file shipped in the package (``ema_bench/<name>``)."""
    return resources.files("ema_bench").joinpath(name)


#: A best-known table file (``ema-bench targets``' JSON, what ``--targets`` reads), by JSON
#: type; each entry: :data:`ema_bench.suites.best_known.ENTRY_SCHEMA`'s fields;
#: ``superseded``: entries of earlier compatible model versions that differ from this one's
#: (``{version: {key: entry}}``, what records of that version are judged on).
TABLE_SCHEMA = {"suite": req("str"), "model_version": req("str"), "method": opt("dict"),
                "entries": req("dict"), "superseded": opt("dict")}


def read_targets(path: Traversable, suite: str, missing_ok: bool = True,
                 model_version: str = SUITE_MODEL_VERSION,
                 remake: str = "with 'ema-bench targets'") -> dict:
    """A best-known table of ``suite`` on its ``model_version`` (or another table of a suite
    labelled so: v3's tolerances); an empty ``entries`` when the file is missing and
    ``missing_ok`` (a checkout before ``ema-bench targets``), else :class:`SuiteError`;
    SuiteError when it is labelled for another suite or model version (the message says how
    to regenerate it: ``remake``)."""
    name = getattr(path, "name", str(path))
    if not path.is_file():
        if missing_ok:
            return {"suite": suite, "model_version": model_version, "entries": {}}
        raise SuiteError(f"{name}: no best-known table of suite {suite} there; compute it "
                         "with 'ema-bench targets'")
    data = check(json.loads(path.read_text()), TABLE_SCHEMA, name)
    if data.get("suite") != suite or data.get("model_version") != model_version:
        raise SuiteError(f"{name} is for suite {data.get('suite')!r} on model version "
                         f"{data.get('model_version')!r}, not {suite} on "
                         f"{model_version}: regenerate it {remake}")
    return data


def fitness_targets(f_star: float, f_nominal: float,
                    precisions: Sequence[float] = FITNESS_PRECISIONS) -> list[float]:
    """The ladder ``f* + p (f_nominal - f*)`` for ``precisions`` (default
    :data:`FITNESS_PRECISIONS`; a suite's own: ``Instance.fitness_precisions``)."""
    gap = f_nominal - f_star
    if not (math.isfinite(gap) and gap > 0):
        raise SuiteError(f"no fitness targets: f_nominal {f_nominal!r} is not above "
                         f"f* {f_star!r}")
    return [f_star + p * gap for p in precisions]


def precision_key(p: float) -> str:
    """The JSON key of a target level (``1e-3``, ``0.03``)."""
    return f"{p:g}"


#: Best-known tables of other root seeds (``ema-bench targets --root-seed R``): their paths,
#: separated by ``os.pathsep``; the commands' ``--targets FILE`` sets it (worker processes
#: inherit it).
TARGETS_ENV = "EMA_BENCH_TARGETS"


def table_root_seed(data: dict) -> int:
    """The root seed a best-known table was computed at (``method.root_seed``; tables
    written before it was recorded are of :data:`TARGET_ROOT_SEED`)."""
    return int((data.get("method") or {}).get("root_seed", TARGET_ROOT_SEED))


@functools.lru_cache(maxsize=8)
def _user_tables(paths: str) -> tuple[dict, ...]:
    tables = []
    for p in filter(None, paths.split(os.pathsep)):
        path = Path(p)
        if not path.is_file():
            raise SuiteError(f"{TARGETS_ENV}: {p}: no such best-known table (make one with "
                             "'ema-bench targets --root-seed R --out FILE')")
        data = check(json.loads(path.read_text()), TABLE_SCHEMA, p)
        if table_root_seed(data) == TARGET_ROOT_SEED:
            # the shipped table is the one of root seed 0: a second would rank the same runs
            # on other targets than everyone else's
            raise SuiteError(f"{p} is a table of root seed {TARGET_ROOT_SEED}, whose f* the "
                             "package ships; --targets takes tables of other root seeds")
        # read on its own label; user_entry checks it against its suite's model version
        tables.append(read_targets(path, data["suite"], model_version=data["model_version"]))
    return tuple(tables)


def user_targets() -> tuple[dict, ...]:
    """The best-known tables named in :data:`TARGETS_ENV` (each checked by
    :func:`read_targets`: a suite and its model version), in order."""
    return _user_tables(os.environ.get(TARGETS_ENV, ""))


def user_entry(suite: str, key: str, root_seed: int,
               model_version: str = SUITE_MODEL_VERSION) -> dict | None:
    """The entry ``key`` of ``suite`` at ``root_seed`` in the first user table
    (:func:`user_targets`) that has it, or None; :class:`SuiteError` for a table of the
    suite labelled with another model version than the suite's ``model_version``."""
    for data in user_targets():
        if data["suite"] == suite and table_root_seed(data) == root_seed:
            if data["model_version"] != model_version:
                raise SuiteError(f"a --targets table is for suite {suite} on model version "
                                 f"{data['model_version']!r}, not {model_version}: "
                                 "regenerate it with 'ema-bench targets'")
            entry = data["entries"].get(key)
            if entry is not None:
                return entry
    return None


def targets_note(root_seeds: Sequence[int], with_f_star: int, runs: int) -> str:
    """Which targets a board or export ranks on, in one sentence: fitness and parameter
    targets where every run has a best-known ``f*``; else how many lack it and how to
    compute the table of their root seed."""
    if runs and with_f_star == runs:
        return "Targets: fitness (best-known f*) and parameter targets."
    roots = [r for r in root_seeds if r != TARGET_ROOT_SEED] or list(root_seeds)
    r = roots[0] if roots else TARGET_ROOT_SEED
    what = ("parameter targets only" if with_f_star == 0 else
            f"fitness targets on {with_f_star} of {runs} runs, parameter targets on all")
    return (f"Targets: {what}: no best-known f* for {runs - with_f_star} runs (root seed "
            f"{', '.join(map(str, root_seeds))}); compute it with 'ema-bench targets "
            f"--root-seed {r} --out T.json' and pass --targets T.json.")
