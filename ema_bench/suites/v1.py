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
from collections.abc import Sequence

import numpy as np

from ..faults import CASES, FAULT_NAMES, LOWER, UPPER, FaultError, faults_to_dict
from .base import Instance, Selection, Suite
from .targets import (
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    SUITE_MODEL_VERSION,
    TARGET_ROOT_SEED,
    SuiteError,
    package_file,
    read_targets,
    target_key,
    user_entry,
)

SUITE_ID = "emafdi-v1"
#: Root of the draw of the seeded instances (never changes within a suite version).
SUITE_SEED = 20261123
N_SEEDED = 20
#: The paper's cases, first; ``nominal`` is the sanity row, outside the aggregate scores.
PAPER_CASES: tuple[str, ...] = tuple(CASES)
SANITY_CASES: tuple[str, ...] = ("nominal",)
#: Noise seeds (leaderboard rows, root seed 0) whose ``f*`` the suite ships.
TARGET_SEEDS = 10
#: The board's budget (evaluations per run), and the quick (CI) preset's.
BUDGET = 5000
QUICK_BUDGET = 400
#: IOH tools store instance ids as unsigned 16-bit integers (iohinspector: ``UInt16``).
MAX_IOH_INSTANCE = 2**16 - 1
TARGETS_FILE = "suite_targets.json"
#: Names of instance groups (:func:`instance_names`).
GROUPS = ("all", "paper", "lhs", "quick")


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


@functools.lru_cache(maxsize=1)
def shipped_targets() -> dict:
    """The best-known optima shipped with the package (``ema_bench/suite_targets.json``,
    :func:`read_targets`)."""
    return read_targets(package_file(TARGETS_FILE), SUITE_ID)


def best_known(case: str, track: str, seed: int, root_seed: int = 0) -> dict | None:
    """``{"f_star", "f_nominal", "x_star"}`` of an instance, or None where no fixed target
    is known: at :data:`TARGET_ROOT_SEED` the shipped table's (none for a seed beyond
    :data:`TARGET_SEEDS`, the sanity case, a custom case), at another root seed a user
    table's (:func:`user_entry`; none without one)."""
    key = target_key(case, track, seed)
    if root_seed != TARGET_ROOT_SEED:
        return user_entry(SUITE_ID, key, root_seed)
    return shipped_targets()["entries"].get(key)


def describe() -> dict[str, object]:
    """The suite as JSON: id, model version, instances with their truths, targets."""
    return {"suite": SUITE_ID, "model_version": SUITE_MODEL_VERSION, "suite_seed": SUITE_SEED,
            "instances": {n: faults_to_dict(instance_faults(n)) for n in instance_names()},
            "sanity": list(SANITY_CASES), "fitness_precisions": list(FITNESS_PRECISIONS),
            "parameter_targets": list(PARAMETER_TARGETS), "target_seeds": TARGET_SEEDS,
            "targets_shipped": len(shipped_targets()["entries"])}


# --- the Suite value ------------------------------------------------------------------------
def _lookup(name: str, cond: str | None) -> Instance | None:
    """A v1 case is an instance's bare name (no condition)."""
    if cond is not None or not (name in CASES or name in seeded_instances()):
        return None
    return Instance(case=name, name=name, suite=SUITE, names=FAULT_NAMES,
                    truth=instance_faults(name), lower=LOWER, upper=UPPER, budget=BUDGET,
                    ranked=name not in SANITY_CASES, paper_case=name, ioh_function=name)


def _ioh_instance(inst: Instance, seed: int) -> int:
    """The run seed (the root seed is a run attribute)."""
    if seed > MAX_IOH_INSTANCE:
        raise ValueError(f"seed {seed} is beyond IOH's 16-bit instance ids (at most "
                         f"{MAX_IOH_INSTANCE})")
    return seed


def _no_tiers(sel: Selection) -> None:
    if sel.tiers or sel.conditions or sel.per_tier:
        raise SuiteError(f"{SUITE_ID} has no tiers or conditions: --tiers, --conditions and "
                         "--per-tier belong to a suite with tiers (--suite emafdi-v2)")


def _sweep_cases(sel: Selection) -> list[str]:
    """The cases and groups named (default: every instance; quick: the quick group)."""
    _no_tiers(sel)
    return expand_cases(sel.cases or ["quick" if sel.quick else "all"])


def _sweep_budget(cases: Sequence[str], budget: int | None, per_dim: int | None,
                  quick: bool) -> int:
    if per_dim:
        raise SuiteError(f"{SUITE_ID} has one budget for every case: --budget, not "
                         "--budget-per-dim")
    return budget or (QUICK_BUDGET if quick else BUDGET)


def _target_keys(sel: Selection, seeds: int | None,
                 tracks: Sequence[str] | None) -> list[str] | None:
    """Keys of the cases named (none named: every key of the table)."""
    from ..instances import TRACKS

    _no_tiers(sel)
    if not (sel.cases or seeds or tracks):
        return None
    cases = [c for c in expand_cases(sel.cases or ["all"]) if c not in SANITY_CASES]
    return [target_key(c, t, k) for k in range(seeds or TARGET_SEEDS)
            for c in cases for t in (tracks or TRACKS)]


SUITE = Suite(
    id=SUITE_ID, lookup=_lookup,
    # v1's entries hold for every compatible model version (its problems have no trigonometry)
    best_known=lambda inst, track, seed, root, _version: best_known(inst.name, track, seed, root),
    judged=lambda inst, track: None,   # every fault (v1's clean-data fits exclude none)
    ioh_instance=_ioh_instance, ioh_functions=lambda: instance_names(),
    complete_cases=lambda entered, per_tier: [c for c in instance_names()
                                              if c not in SANITY_CASES],
    case_order=lambda: instance_names(), sweep_cases=_sweep_cases,
    sweep_budget=_sweep_budget, target_keys=_target_keys,
    targets_file=lambda: package_file(TARGETS_FILE))
