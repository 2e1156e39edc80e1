"""The benchmark's suite versions and the one registry of their cases.

Every suite version is one module building one :class:`~.base.Suite` value (:mod:`.v1`:
the paper's four-fault problem, :mod:`.v2`: tiers of dimension and conditions, :mod:`.v3`:
v2's problems judged on the targets the noise allows).  A run's
case key (``small``, ``t7-s03@no-prior``) is parsed here and nowhere else:
:func:`instance` returns the :class:`~.base.Instance` that every consumer asks (truth,
ranges, judged parameters, best-known entry, IOH ids, budget, the problem's settings);
:func:`suite_of` the suite version a record of a case is scored under.  Adding a version is
one module and one entry in :data:`SUITES`.  The problem of a case:
:func:`~ema_bench.suites.problem.make_problem`.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

from . import v1, v2, v3
from .base import Instance, Suite
from .targets import SuiteError

#: Every suite version, oldest first: the first is the default (a case drawn from the seed,
#: custom faults).
SUITES: dict[str, Suite] = {s.id: s for s in (v1.SUITE, v2.SUITE, v3.SUITE)}
DEFAULT = v1.SUITE
#: Between an instance and its condition in a case key.
CASE_SEP = "@"

__all__ = ["CASE_SEP", "DEFAULT", "SUITES", "Instance", "Suite", "SuiteError", "board_suite",
           "case_order", "episode_cases", "find", "instance", "is_case", "suite_of"]


@functools.cache
def find(case: object) -> Instance | None:
    """The instance a case key names, None where it names none (``seeded``, custom faults);
    SuiteError for a key a suite refuses (an unknown condition)."""
    if not isinstance(case, str):
        return None
    name, sep, cond = case.partition(CASE_SEP)
    for suite in SUITES.values():
        found = suite.lookup(name, cond if sep else None)
        if found is not None:
            return found
    return None


def instance(case: object) -> Instance:
    """The instance a case key names; SuiteError naming the suites otherwise."""
    found = find(case)
    if found is None:
        raise SuiteError(f"unknown case {case!r}: not an instance of suite "
                         f"{' or '.join(SUITES)} (v1: small, full, random, nominal, s00 .. "
                         f"s{v1.N_SEEDED - 1:02d}; v2: instance{CASE_SEP}condition, e.g. "
                         f"t7-s03{CASE_SEP}no-prior; v3: {v3.PREFIX}t7-s03{CASE_SEP}no-prior)")
    return found


def is_case(case: object) -> bool:
    """Whether ``case`` is a key of some suite's instance."""
    try:
        return find(case) is not None
    except SuiteError:
        return False


def suite_of(case: object) -> Suite:
    """The suite a record of ``case`` is scored under (cases outside every suite: the
    default suite's, as before versions)."""
    try:
        found = find(case)
    except SuiteError:
        found = None
    return DEFAULT if found is None else found.suite


def board_suite(records: Iterable[dict]) -> Suite:
    """The suite of a board's records: a suite scored by group where any record is of one
    (its board's tables are per group), else the default."""
    suites = [suite_of(r["case"]) for r in records]
    return next((s for s in suites if s.grouped), DEFAULT)


def episode_cases(case: object = "small", tier: int | str | None = None,
                  condition: str | None = None, suite: str = v2.SUITE_ID) -> list:
    """The cases an environment's episodes draw from (episode ``k``: case ``k mod n``):
    ``[case]`` (any case key, ``seeded``, true faults), or with ``tier`` or ``condition``
    the keys of that tier of ``suite`` under that condition (default the faults-only tier
    and ``prior``), only the one of instance ``case`` where it is given; SuiteError for a
    suite without tiers, or a tier, condition or instance the suite does not have."""
    if tier is None and condition is None:
        return [case]
    found = SUITES.get(suite)
    if found is None or found.tier_cases is None:
        raise SuiteError(f"suite {suite!r} has no tiers; suites with tiers: "
                         f"{[s.id for s in SUITES.values() if s.tier_cases is not None]}")
    return found.tier_cases(tier, condition, case)


def case_order() -> dict[str, int]:
    """Every suite's cases -> their position in the suite tables' order."""
    names = [c for s in SUITES.values() for c in s.case_order()]
    return {c: i for i, c in enumerate(dict.fromkeys(names))}
