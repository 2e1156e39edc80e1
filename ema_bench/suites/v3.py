"""Suite ``emafdi-v3``: v2's problems, parameter targets the noise allows, a denser ladder.

v3 keeps what makes a v2 problem (:mod:`~ema_bench.suites.v2`): the tiers (4, 7, 12), every
instance (20 a tier, plus the paper cases on tier 4), the conditions, the budgets and the
noise (it does not depend on the case key).  It runs on model version 4
(:data:`V3_MODEL_VERSION`: the monitor locates the commutation transfers version 3 dropped,
docs/landscape-atlas.md), so its fitness and its twin-track data are version 4's and it has
its own best-known table (``suite_targets_v3.json``, :func:`target_keys`).  A v3 case key is
v2's with :data:`PREFIX` (``v3-t12-s06@prior``, ``v3-small@no-prior``).  What changes is
how a run is judged:

- **parameter targets the noise allows.**  In v2 a parameter target is the best-so-far point
  within ``L`` of every judged range; on tier 12 the exact best fit of the noisy data lies
  outside 1 % of range on some parameter on up to half of the noise draws, so a perfect
  optimiser misses the target.  In v3 each judged parameter ``i`` of a case has the target
  scale ``s_i = max(range_i, z sigma_i / FLOOR)`` (:func:`scales`): at the 1 % level the
  tolerance is ``max(1 % of range, z sigma_i)``, and every level of the ladder scales with it.
  ``sigma_i`` is the standard deviation of the best fit under the sensor noise, from the
  noise-whitened Gauss-Newton covariance at the truth (:mod:`ema_bench.uncertainty`), ``z``
  per case and track the smallest for which the joint probability that the best fit lies
  inside every tolerance is at least :data:`COVERAGE` (:func:`joint_probability`: Monte Carlo
  over the Gaussian, centred on the clean-data bias on the reference track).  The table
  ``suite_tolerances_v3.json`` holds ``sigma``, ``z`` and the probability under the old and
  the new rule (``benchmarks/v3_tolerances.py`` writes it; docs/suite-v3.md shows it);
- **a denser fitness ladder**: :data:`FITNESS_PRECISIONS`, 4 per decade from 1e-1 to 1e-6
  (docs/suite-v3.md says why).

A case without a table entry (none computed) keeps v2's rule (scale = range).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from importlib.resources.abc import Traversable

import numpy as np

from . import v2
from .base import CaseBudgets, Instance, Selection, Suite
from .targets import (
    TARGET_ROOT_SEED,
    SuiteError,
    package_file,
    read_targets,
    target_key,
    user_entry,
)

SUITE_ID = "emafdi-v3"
#: Before a v2 case key: a v3 case (``v3-t7-s03@no-prior``).
PREFIX = "v3-"
#: The model version of v3's problems, tables and records (v1 and v2 stay on version 3).
V3_MODEL_VERSION = "4"
#: v3's best-known table (``ema-bench targets --suite emafdi-v3``).
TARGETS_FILE = "suite_targets_v3.json"
#: Noise seeds (0 ..) of the shipped best-known entries: tier 4 with full information (v1's
#: problems) as many as v1's table gives v2's board, every other objective seeds 0 and 1 (the
#: board's two noise seeds).
SHIPPED_SEEDS = {"full-information tier 4": v2.TARGET_SEEDS, "other": 2}
#: The tolerance table (``benchmarks/v3_tolerances.py``).
TOLERANCES_FILE = "suite_tolerances_v3.json"
#: The joint probability, under the noise model, that the exact best fit of the noisy data
#: lies inside every parameter's 1 % tolerance.
COVERAGE = 0.95
#: The finest parameter level at which a tolerance is never below its fraction of range (the
#: success rule's 1 %).
FLOOR = 0.01
#: Fitness targets ``f* + p (f_nominal - f*)``: 4 per decade, 1e-1 .. 1e-6 (21 targets).
FITNESS_PRECISIONS: tuple[float, ...] = tuple(float(f"{10.0 ** (-k / 4):.3g}")
                                              for k in range(4, 25))
#: Draws of the Monte Carlo of :func:`joint_probability`.
MC_DRAWS = 200_000


def case_key(name: str, cond: str) -> str:
    """A v3 case (``v3-t7-s03@no-prior``)."""
    return PREFIX + v2.case_key(name, cond)


def cases(tiers: Sequence[int], conditions: Sequence[str],
          per_tier: int | None = None) -> list[str]:
    """The v3 case keys of ``tiers`` x ``conditions`` (:func:`ema_bench.suites.v2.cases`)."""
    return [PREFIX + c for c in v2.cases(tiers, conditions, per_tier)]


def tolerance_case(inst: Instance) -> str:
    """The case whose tolerance and best-known entries ``inst`` uses: its objective's
    (``no-prior`` shares ``prior``'s data and fitness, :func:`ema_bench.suites.v2.
    target_case`)."""
    return PREFIX + v2.target_case(inst)


def tolerance_key(case: str, track: str) -> str:
    """The key of a tolerance entry (``v3-t7-s03@prior|twin``)."""
    return f"{case}|{track}"


#: Fields of a tolerance entry: per parameter (the instance's ``names`` order) ``sigma``
#: (physical units) and ``bias`` (the Gaussian's centre minus the truth), ``judged``; ``z``;
#: the joint probabilities ``p_old`` (1 % of range) and ``p_new`` (this rule).
ENTRY_FIELDS = ("names", "sigma", "bias", "judged", "z", "p_old", "p_new")


@functools.cache
def shipped_tolerances() -> dict:
    """The shipped tolerance table (empty entries while it is absent); SuiteError for a
    table of another suite or model version."""
    return read_targets(package_file(TOLERANCES_FILE), SUITE_ID,
                        model_version=V3_MODEL_VERSION, remake="(benchmarks/v3_tolerances.py)")


def tolerance(ranges: np.ndarray, sigma: np.ndarray, z: float) -> np.ndarray:
    """The 1 % tolerance of each parameter: ``max(FLOOR x range, z sigma)`` (physical)."""
    return np.maximum(FLOOR * np.asarray(ranges, float), z * np.asarray(sigma, float))


def joint_probability(cov: np.ndarray, bias: np.ndarray, tol: np.ndarray,
                      seed: int | np.random.SeedSequence = 0,
                      draws: int = MC_DRAWS) -> float:
    """Probability that a Gaussian ``N(bias, cov)`` draw lies within ``tol`` of 0 on every
    coordinate (Monte Carlo, ``draws`` draws; an infinite variance counts as outside unless
    its tolerance is infinite)."""
    return float(np.mean(_inside(_draws(cov, bias, seed, draws), tol)))


def _draws(cov: np.ndarray, bias: np.ndarray, seed, draws: int) -> np.ndarray:
    cov = np.asarray(cov, float)
    finite = np.isfinite(np.diag(cov))
    d = np.full((draws, cov.shape[0]), np.inf)
    if finite.any():
        c = cov[np.ix_(finite, finite)]
        w, v = np.linalg.eigh(c)
        root = v * np.sqrt(np.maximum(w, 0.0))
        g = np.random.default_rng(seed).standard_normal((draws, int(finite.sum())))
        d[:, finite] = g @ root.T + np.asarray(bias, float)[finite]
    return d


def _inside(d: np.ndarray, tol: np.ndarray) -> np.ndarray:
    return np.all(np.abs(d) <= tol, axis=1)


def noise_z(cov: np.ndarray, bias: np.ndarray, ranges: np.ndarray,
            coverage: float = COVERAGE, seed: int | np.random.SeedSequence = 0,
            draws: int = MC_DRAWS) -> tuple[float, float, float]:
    """The smallest ``z`` (to 0.01) for which the joint probability of :func:`tolerance`
    reaches ``coverage``, with the probability at 1 % of range (``z = 0``) and at ``z``:
    ``(z, p_old, p_new)``.  The same draws judge every ``z`` (the probability is then
    non-decreasing in it)."""
    d = _draws(cov, bias, seed, draws)
    sigma = np.sqrt(np.diag(np.asarray(cov, float)))

    def p(z: float) -> float:
        return float(np.mean(_inside(d, tolerance(ranges, sigma, z))))

    p_old = p(0.0)
    if p_old >= coverage:
        return 0.0, p_old, p_old
    lo, hi = 0.0, 1.0
    while p(hi) < coverage:
        lo, hi = hi, 2.0 * hi
        if hi > 64:
            raise SuiteError("no finite z reaches the coverage: a parameter the data cannot "
                             "see (infinite variance)")
    while hi - lo > 0.005:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if p(mid) < coverage else (lo, mid)
    z = float(np.ceil(hi * 100.0) / 100.0)
    return z, p_old, p(z)


def scales(inst: Instance, track: str) -> np.ndarray | None:
    """Each searched parameter's target scale on ``track``: ``max(range, z sigma / FLOOR)``
    from the tolerance table, so that level ``L`` of the parameter ladder is a tolerance of
    ``L x scale`` (at 1 %: ``max(1 % of range, z sigma)``); None (the ranges) without an
    entry."""
    entry = shipped_tolerances()["entries"].get(tolerance_key(tolerance_case(inst), track))
    if entry is None:
        return None
    if tuple(entry["names"]) != inst.names:
        raise SuiteError(f"{TOLERANCES_FILE}: entry of {inst.case} names {entry['names']}, "
                         f"the instance searches {list(inst.names)}")
    return tolerance(inst.ranges, np.array(entry["sigma"], float), float(entry["z"])) / FLOOR


def _lookup(name: str, cond: str | None) -> Instance | None:
    """A v3 case is ``v3-<v2 instance>@<condition>``; what v2 refuses, v3 refuses."""
    if cond is None or not name.startswith(PREFIX):
        return None
    base = v2.SUITE.lookup(name[len(PREFIX):], cond)
    if base is None:
        return None
    case = PREFIX + base.case
    return dataclasses.replace(base, case=case, suite=SUITE,
                               paper_case=base.paper_case if base.paper_case != base.case
                               else case)


def _complete_cases(entered, per_tier: int | None) -> list[str]:
    return [PREFIX + c for c in v2.SUITE.complete_cases(entered, per_tier)]


def _sweep_budget(keys: Sequence[str], budget: int | None, per_dim: int | None,
                  quick: bool) -> int | CaseBudgets:
    """v2's budgets of the same problems."""
    b = v2.SUITE.sweep_budget([k[len(PREFIX):] for k in keys], budget, per_dim, quick)
    return b if isinstance(b, int) else CaseBudgets(
        {PREFIX + k: n for k, n in b.budgets.items()}, b.label)


def _env_cases(dim: int | str | None, cond: str | None, name: object = None) -> list[str]:
    """v2's episode cases of the same tier, as v3 keys (instance ``t7-s03`` or
    ``v3-t7-s03``)."""
    if isinstance(name, str) and name.startswith(PREFIX):
        name = name[len(PREFIX):]
    return [PREFIX + c for c in v2.SUITE.tier_cases(dim, cond, name)]


def targets_path() -> Traversable:
    """Where the shipped v3 best-known table is (the package's ``suite_targets_v3.json``)."""
    return package_file(TARGETS_FILE)


@functools.cache
def shipped_targets() -> dict:
    """v3's best-known table shipped with the package (empty entries while it is absent,
    SuiteError when it is labelled for another suite or model version)."""
    return read_targets(targets_path(), SUITE_ID, model_version=V3_MODEL_VERSION)


def target_keys(seeds: int | None = None, tracks: Sequence[str] = ("reference", "twin"),
                tiers: Sequence[int] | None = None, conditions: Sequence[str] | None = None,
                per_tier: int | None = None) -> list[str]:
    """The ``case|track|seed`` keys of v3's best-known table, seed by seed: every objective
    of :func:`ema_bench.suites.v2.target_keys` (as v3 keys) and tier 4 with full
    information (``v3-small@prior``: v2 reads v1's entries there, v3 polishes its own on
    model version 4).  ``seeds``: noise seeds 0 .. seeds-1 of every objective (default the
    shipped ones, :data:`SHIPPED_SEEDS`); the other arguments select a subset as v2's."""
    dims = [v2.tier(d).dim for d in (v2.TIERS if tiers is None else tiers)]
    wanted = {v2.target_condition(v2.condition(n)).name for n in (conditions or v2.CONDITIONS)}
    full = seeds or SHIPPED_SEEDS["full-information tier 4"]
    other = seeds or SHIPPED_SEEDS["other"]
    base = [v2.case_key(n, "prior") for n in v2.instance_names(v2.BASE_TIER)[:per_tier]] \
        if v2.BASE_TIER in dims and "prior" in wanted else []
    keys = []
    for k in range(max(full, other)):
        keys += [target_key(PREFIX + c, tr, k) for c in base for tr in tracks] if k < full \
            else []
        keys += [PREFIX + key for key in v2.target_keys(k + 1, tracks, dims, conditions,
                                                         per_tier)
                 if key.endswith(f"|{k}")] if k < other else []
    return keys


def _target_keys(sel: Selection, seeds: int | None,
                 tracks: Sequence[str] | None) -> list[str]:
    """:func:`target_keys` of the tiers, conditions and instances selected."""
    from ..instances import TRACKS

    return target_keys(seeds, tracks or TRACKS, v2.selected_tiers(sel, SUITE_ID),
                       sel.conditions, sel.per_tier)


def _best_known(inst: Instance, track: str, seed: int, root_seed: int,
                model_version: str | None = None) -> dict | None:
    """The entry of :func:`tolerance_case` in ``suite_targets_v3.json`` (None while it is
    absent or lacks the key; at a root seed other than 0 a user table's)."""
    key = target_key(tolerance_case(inst), track, seed)
    if root_seed != TARGET_ROOT_SEED:
        return user_entry(SUITE_ID, key, root_seed, V3_MODEL_VERSION)
    return shipped_targets()["entries"].get(key)


SUITE = Suite(id=SUITE_ID, lookup=_lookup, best_known=_best_known,
              judged=v2.SUITE.judged, ioh_instance=v2.SUITE.ioh_instance,
              ioh_functions=v2.SUITE.ioh_functions, complete_cases=_complete_cases,
              case_order=lambda: cases(list(v2.TIERS), list(v2.CONDITIONS)),
              sweep_cases=lambda sel: [PREFIX + c for c in v2.sweep_cases(sel, SUITE_ID)],
              sweep_budget=_sweep_budget, target_keys=_target_keys,
              targets_file=targets_path, grouped=True,
              clean_fits=True, target_scales=scales, fitness_precisions=FITNESS_PRECISIONS,
              split_ecdf=True, tier_cases=_env_cases, model_version=V3_MODEL_VERSION)
