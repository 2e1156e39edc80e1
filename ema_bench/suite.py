"""The versioned benchmark suite: its id, its instances and its fixed targets.

A suite version fixes everything a published score depends on: the models
(:data:`~ema_bench.trace_cache.MODEL_VERSION`), the instances (the four paper cases and
:data:`N_SEEDED` instances drawn once from :data:`SUITE_SEED`) and the best-known fitness
``f*`` of every (instance, track, seed) from which the fitness targets are built
(``suite_targets.json``, written by ``ema-bench targets``).  A change to any of them is a new
suite version (and a new Gymnasium id); ``--check`` refuses to compare across versions.

Version history (the Gymnasium id in brackets):

- ``emafdi-v1`` [``EMAFault/Identify-v1``]: model version 2 (analog hysteresis reference,
  monitor without discretisation bias); paper cases + 20 Latin-hypercube instances ``s00`` ..
  ``s19`` over the whole fault box; fitness targets at precisions 1e-1 .. 1e-4 of the
  ``f*``-to-nominal gap; parameter targets at 10, 3 and 1 % of range.
- (unversioned) [``EMAFault/Identify-v0``]: model version 1, the four paper cases, success
  = final vector within 1 % of range.
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

import numpy as np

from .faults import CASES, FAULT_NAMES, LOWER, UPPER, FaultError, faults_to_dict
from .sweep.schema import check, opt, req
from .trace_cache import MODEL_VERSION

SUITE_ID = "emafdi-v1"
#: The model version the suite's targets were computed on.
SUITE_MODEL_VERSION = "2"
#: Root of the draw of the seeded instances (never changes within a suite version).
SUITE_SEED = 20261123
N_SEEDED = 20
#: The paper's cases, first; ``nominal`` is the sanity row, outside the aggregate scores.
PAPER_CASES: tuple[str, ...] = tuple(CASES)
SANITY_CASES: tuple[str, ...] = ("nominal",)
#: Noise seeds (leaderboard rows, root seed 0) whose ``f*`` the suite ships.
TARGET_SEEDS = 10
TARGET_ROOT_SEED = 0
#: Fitness targets: ``f* + p (f_nominal - f*)`` for each precision ``p``.
FITNESS_PRECISIONS: tuple[float, ...] = (1e-1, 1e-2, 1e-3, 1e-4)
#: Parameter targets: the best-so-far point within this fraction of every fault's range.
PARAMETER_TARGETS: tuple[float, ...] = (0.1, 0.03, 0.01)
#: Checkpoints of the fixed-budget view (evaluations), up to the run's budget.
BUDGET_CHECKPOINTS: tuple[int, ...] = (10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000,
                                       20000, 50000, 100000)
TARGETS_FILE = "suite_targets.json"
#: Best-known tables of other root seeds (``ema-bench targets --root-seed R``): their paths,
#: separated by ``os.pathsep``; the commands' ``--targets FILE`` sets it (worker processes
#: inherit it).
TARGETS_ENV = "EMA_BENCH_TARGETS"
#: Names of instance groups (:func:`instance_names`).
GROUPS = ("all", "paper", "lhs", "quick")


class SuiteError(ValueError):
    """A suite instance, version or target file that cannot be used."""


@functools.lru_cache(maxsize=1)
def seeded_instances() -> dict[str, np.ndarray]:
    """The suite's seeded instances ``s00`` ..: a Latin hypercube over the whole fault box
    (each fault's range cut in :data:`N_SEEDED` strata, one instance per stratum), so high
    friction, heavy coil shorts and both gain drifts are all represented."""
    # scipy.stats is imported here, not with the module: it costs 0.5 s of every start-up
    from scipy.stats import qmc

    lhs = qmc.LatinHypercube(d=len(FAULT_NAMES), rng=np.random.default_rng(SUITE_SEED))
    x = qmc.scale(lhs.random(N_SEEDED), LOWER, UPPER)
    return {f"s{i:02d}": row for i, row in enumerate(x)}


def instance_names(which: str = "all") -> tuple[str, ...]:
    """Instance names: ``all`` (paper cases then seeded), ``paper``, ``lhs`` (the seeded
    instances ``s00`` ..) or ``quick`` (the paper cases and the first four seeded instances:
    the CI baseline).  (``seeded`` is not a group: it is the case of a random instance drawn
    from each run's seed.)"""
    seeded = tuple(seeded_instances())
    groups = {"all": PAPER_CASES + seeded, "paper": PAPER_CASES, "lhs": seeded,
              "quick": PAPER_CASES + seeded[:4]}
    if which not in groups:
        raise SuiteError(f"unknown instance group {which!r}; known: {list(groups)}")
    return groups[which]


def expand_cases(names: Sequence[str]) -> list[str]:
    """Case names with groups (``all``, ``paper``, ``lhs``, ``quick``) expanded, checked, in
    order and without repeats (``seeded``, a random instance per run, passes through)."""
    out = [c for n in names for c in (instance_names(n) if n in GROUPS else (n,))]
    for c in out:
        if c != "seeded":
            instance_faults(c)   # unknown names fail here, before any work
    return list(dict.fromkeys(out))


def instance_faults(name: str) -> np.ndarray:
    """The true fault vector of a suite instance (paper case or seeded)."""
    if name in CASES:
        return CASES[name].x
    seeded = seeded_instances()
    if name in seeded:
        return seeded[name].copy()
    raise FaultError(f"unknown case {name!r}; known: {list(CASES)}, the suite's "
                     f"{N_SEEDED} seeded instances s00..s{N_SEEDED - 1:02d}, or 'seeded'")


def is_instance(name: object) -> bool:
    return isinstance(name, str) and (name in CASES or name in seeded_instances())


def check_model_version() -> None:
    """The suite's targets hold only on the models they were computed on."""
    if MODEL_VERSION != SUITE_MODEL_VERSION:
        raise SuiteError(f"suite {SUITE_ID} was built on model version {SUITE_MODEL_VERSION}, "
                         f"the installed models are version {MODEL_VERSION}: bump the suite")


# --- fixed targets -------------------------------------------------------------------------
def target_key(case: str, track: str, seed: int) -> str:
    return f"{case}|{track}|{seed}"


#: A best-known table file (``ema-bench targets``' JSON, what ``--targets`` reads), by JSON
#: type; each entry: :data:`ema_bench.best_known.ENTRY_SCHEMA`'s fields.
TABLE_SCHEMA = {"suite": req("str"), "model_version": req("str"), "method": opt("dict"),
                "entries": req("dict")}


def read_targets(path: Traversable, suite: str, missing_ok: bool = True) -> dict:
    """A best-known table (``ema-bench targets``' JSON) of ``suite`` on the installed model
    version: ``{"suite", "model_version", "entries": {key: {"f_star", "f_nominal",
    "x_star", ..}}}``; an empty ``entries`` when the file is missing and ``missing_ok`` (a
    checkout before ``ema-bench targets``), else :class:`SuiteError`; SuiteError when it is
    labelled for another suite or model version."""
    name = getattr(path, "name", str(path))
    if not path.is_file():
        if missing_ok:
            return {"suite": suite, "model_version": SUITE_MODEL_VERSION, "entries": {}}
        raise SuiteError(f"{name}: no best-known table of suite {suite} there; compute it "
                         "with 'ema-bench targets'")
    data = check(json.loads(path.read_text()), TABLE_SCHEMA, name)
    if data.get("suite") != suite or data.get("model_version") != SUITE_MODEL_VERSION:
        raise SuiteError(f"{name} is for suite {data.get('suite')!r} on model version "
                         f"{data.get('model_version')!r}, not {suite} on "
                         f"{SUITE_MODEL_VERSION}: regenerate it with 'ema-bench targets'")
    return data


@functools.lru_cache(maxsize=1)
def shipped_targets() -> dict:
    """The best-known optima shipped with the package (``ema_bench/suite_targets.json``,
    :func:`read_targets`)."""
    return read_targets(resources.files("ema_bench").joinpath(TARGETS_FILE), SUITE_ID)


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
        tables.append(read_targets(path, data["suite"]))   # and its model version
    return tuple(tables)


def user_targets() -> tuple[dict, ...]:
    """The best-known tables named in :data:`TARGETS_ENV` (each checked by
    :func:`read_targets`: a suite and the installed model version), in order."""
    return _user_tables(os.environ.get(TARGETS_ENV, ""))


def user_entry(suite: str, key: str, root_seed: int) -> dict | None:
    """The entry ``key`` of ``suite`` at ``root_seed`` in the first user table
    (:func:`user_targets`) that has it, or None."""
    for data in user_targets():
        if data["suite"] == suite and table_root_seed(data) == root_seed:
            entry = data["entries"].get(key)
            if entry is not None:
                return entry
    return None


def best_known(case: str, track: str, seed: int, root_seed: int = 0) -> dict | None:
    """``{"f_star", "f_nominal", "x_star"}`` of an instance, or None where no fixed target
    is known: at :data:`TARGET_ROOT_SEED` the shipped table's (none for a seed beyond
    :data:`TARGET_SEEDS`, the sanity case, a custom case), at another root seed a user
    table's (:func:`user_entry`; none without one)."""
    key = target_key(case, track, seed)
    if root_seed != TARGET_ROOT_SEED:
        return user_entry(SUITE_ID, key, root_seed)
    return shipped_targets()["entries"].get(key)


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


def fitness_targets(f_star: float, f_nominal: float) -> list[float]:
    """The ladder ``f* + p (f_nominal - f*)`` for :data:`FITNESS_PRECISIONS`."""
    gap = f_nominal - f_star
    if not (math.isfinite(gap) and gap > 0):
        raise SuiteError(f"no fitness targets: f_nominal {f_nominal!r} is not above "
                         f"f* {f_star!r}")
    return [f_star + p * gap for p in FITNESS_PRECISIONS]


def precision_key(p: float) -> str:
    """The JSON key of a target level (``1e-3``, ``0.03``)."""
    return f"{p:g}"


def describe() -> dict[str, object]:
    """The suite as JSON: id, model version, instances with their truths, targets."""
    return {"suite": SUITE_ID, "model_version": SUITE_MODEL_VERSION, "suite_seed": SUITE_SEED,
            "instances": {n: faults_to_dict(instance_faults(n)) for n in instance_names()},
            "sanity": list(SANITY_CASES), "fitness_precisions": list(FITNESS_PRECISIONS),
            "parameter_targets": list(PARAMETER_TARGETS), "target_seeds": TARGET_SEEDS,
            "targets_shipped": len(shipped_targets()["entries"])}
