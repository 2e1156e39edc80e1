"""Anytime scores of run records: fixed-target ERT, ECDF area, fixed-budget quantiles.

Targets (:mod:`~ema_bench.suites.targets`) of a run on a suite instance: four fitness targets
``f* + p (f_nominal - f*)``, ``p`` = 1e-1 .. 1e-4, and three parameter targets (the best-so-far
point within 10, 3, 1 % of every fault's range of the truth).  A record's ``targets`` field
holds the evaluation at which each was first reached.

- **ECDF area** (the ranking score): a run reaching a target at evaluation ``h`` of its budget
  ``B`` is credited ``(ln B - ln h) / ln B`` (its share of the empirical cumulative
  distribution of hitting times on a log axis from 1 to ``B``), a miss 0; a run's area is its
  mean credit over its targets, a solver's area the mean over its runs: the area under the ECDF
  over (instance, target) pairs, in [0, 1], higher is better.  95 % confidence intervals by
  bootstrap over runs (``scipy.stats.bootstrap``'s percentile method, seeded; replicated
  draw for draw without its per-call overhead).
- **ERT** per target (Hansen et al., COCO): evaluations summed over runs (a run that reached
  the target counted until it did, the others at their budget) over the number of runs that
  reached it; its interval is the bootstrap interval of the hit rate per evaluation, inverted.
- **Fixed budget**: quantiles over runs of the best-so-far precision
  ``(f - f*) / (f_nominal - f*)`` at budget checkpoints.

Every hit, ``f*`` and best-so-far value comes from the record's re-derivation
(:func:`.derive.derived`), never from its ``targets`` or ``best_at`` claims (legacy records:
the latest hit their evidence allows, see :mod:`.derive`).

The sanity case (``nominal``: does the solver stay at a healthy actuator?) is scored apart and
left out of every aggregate.  A run that failed with an error reached no target (it counts,
at its budget).
"""

from __future__ import annotations

import functools
import hashlib
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..suites.targets import (
    BUDGET_CHECKPOINTS,
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    precision_key,
)
from ..suites.v1 import SANITY_CASES
from .derive import derived, precision
from .run_store import is_error

CONFIDENCE = 0.95
N_RESAMPLES = 2000
BOOTSTRAP_SEED = 20261123   # the intervals are reproducible: same records, same interval
FITNESS_TARGETS = tuple(f"f{precision_key(p)}" for p in FITNESS_PRECISIONS)
PARAMETER_TARGET_KEYS = tuple(f"p{precision_key(p)}" for p in PARAMETER_TARGETS)


def hits(record: dict) -> dict[str, int | None]:
    """Target name (``f1e-2``, ``p0.01``) -> evaluation of the first hit (None: missed), over
    the targets defined for the record's instance (no fitness targets without an ``f*``); a
    run that failed with an error missed every target.  Re-derived, never the claims."""
    if is_error(record):
        return dict.fromkeys(FITNESS_TARGETS + PARAMETER_TARGET_KEYS)
    d = derived(record)
    out: dict[str, int | None] = {}
    if d.fitness_hits is not None:
        out.update({f"f{k}": v for k, v in d.fitness_hits.items()})
    out.update({f"p{k}": v for k, v in d.parameter_hits.items()})
    return out


def credit(hit: int | None, budget: int) -> float:
    """A target's share of the ECDF area: ``(ln B - ln h) / ln B``, 0 for a miss."""
    if hit is None or hit > budget:
        return 0.0
    if budget <= 1:
        return 1.0
    return (math.log(budget) - math.log(max(hit, 1))) / math.log(budget)


def run_area(record: dict, kinds: str = "fp") -> float:
    """Mean credit of a run over its targets (``kinds``: ``f`` fitness, ``p`` parameter)."""
    h = {k: v for k, v in hits(record).items() if k[0] in kinds}
    if not h:
        return math.nan
    return float(np.mean([credit(v, record["budget"]) for v in h.values()]))


def group_seed(*identity: object) -> int:
    """The bootstrap seed of a group (track, solver, cases, target): fixed by what the group
    is, not by where its records sit in ``runs.jsonl`` nor by which other groups exist."""
    digest = hashlib.sha256("|".join(map(str, identity)).encode()).digest()
    return BOOTSTRAP_SEED ^ int.from_bytes(digest[:8], "little")


def _mean(values: Sequence[float]) -> float:
    """The mean, exactly rounded (``math.fsum``): the same for the values in any order."""
    return math.fsum(values) / len(values) if len(values) else math.nan


@functools.lru_cache(maxsize=64)
def _resamples(n: int, seed: int) -> np.ndarray:
    """The indices of ``N_RESAMPLES`` bootstrap resamples of ``n`` observations: the draw
    ``scipy.stats.bootstrap`` makes with ``rng=np.random.default_rng(seed)``.  Cached
    (read-only): a board asks for the same ``n`` tens of thousands of times, and scipy's
    per-call validation was over half of the v3 tables' CPU."""
    i = np.random.default_rng(seed).integers(0, n, (N_RESAMPLES, n))
    i.flags.writeable = False
    return i


def _percentile_interval(theta: np.ndarray) -> tuple[float, float]:
    """The 95 % percentile interval of a bootstrap distribution, computed as
    ``scipy.stats.bootstrap(..., method="percentile")`` does (``scipy.stats.quantile``,
    linear interpolation, Hyndman and Fan's type 7) to the last bit:
    ``tests/test_anytime.py`` holds the two equal."""
    y = np.sort(theta)
    a = (1.0 - CONFIDENCE) / 2.0
    p = np.array([a, 1.0 - np.float64(a)])
    n = float(y.size)
    jg = p * n + (1.0 - p)
    jp1 = jg // 1
    j = jp1 - 1
    g = jg % 1
    g[j < 0] = 0.0
    lo_i = np.clip(j, 0.0, n - 1).astype(np.int64)
    hi_i = np.clip(jp1, 0.0, n - 1).astype(np.int64)
    q = (1.0 - g) * y[lo_i] + g * y[hi_i]
    return float(q[0]), float(q[1])


def mean_ci(values: Sequence[float], seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """Mean and its bootstrap 95 % interval (nan bounds for fewer than two values); the
    values are sorted first, so the interval does not depend on their order."""
    v = np.sort(np.asarray([x for x in values if not math.isnan(x)], dtype=float))
    if v.size == 0:
        return math.nan, math.nan, math.nan
    m = _mean(v.tolist())
    if v.size < 2 or np.all(v == v[0]):
        return m, (m if v.size > 1 else math.nan), (m if v.size > 1 else math.nan)
    lo, hi = _percentile_interval(np.mean(v[_resamples(v.size, seed)], axis=-1))
    return m, lo, hi


def ert(hit_list: Sequence[int | None], budgets: Sequence[int]) -> float:
    """COCO's expected running time: summed costs over the number of hits (inf without)."""
    k = sum(h is not None for h in hit_list)
    cost = sum(h if h is not None else b for h, b in zip(hit_list, budgets))
    return cost / k if k else math.inf


def ert_ci(hit_list: Sequence[int | None], budgets: Sequence[int],
           seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """ERT and a 95 % interval: the bootstrap interval (over runs) of the hit rate per
    evaluation ``hits / cost``, inverted (an upper bound of inf: the data allow no hit).  The
    runs are resampled as (hit, cost) pairs, sorted first (the interval does not depend on
    their order)."""
    e = ert(hit_list, budgets)
    pairs = sorted((float(h is not None), float(h if h is not None else b))
                   for h, b in zip(hit_list, budgets))
    succ = np.array([p[0] for p in pairs], dtype=float)
    cost = np.array([p[1] for p in pairs], dtype=float)
    if succ.size < 2 or np.all(succ == succ[0]) and np.all(cost == cost[0]):
        return e, (e if succ.size > 1 else math.nan), (e if succ.size > 1 else math.nan)
    i = _resamples(succ.size, seed)
    lo, hi = _percentile_interval(succ[i].sum(-1) / cost[i].sum(-1))
    return e, (float(1.0 / hi) if hi > 0 else math.inf), (float(1.0 / lo) if lo > 0
                                                          else math.inf)


def precision_at(record: dict, budget: int) -> float:
    """Best-so-far precision ``(f - f*) / (f_nominal - f*)`` after ``budget`` evaluations:
    from the re-derived ``best_at`` checkpoints (the last one at or before ``budget``), or the
    final fitness once the run has stopped; nan without ``f*``, for an error record, before
    the first checkpoint or beyond the run's budget.  Below 0: the run beat ``f*``."""
    if is_error(record) or budget > record["budget"]:
        return math.nan
    return precision(derived(record), budget, record.get("evaluations", math.inf))


@dataclass(frozen=True)
class AnytimeScore:
    """A solver's anytime scores on one track over a set of instances."""

    track: str
    solver: str
    cases: str                        # "all" (non-sanity instances) or one instance
    runs: int
    errors: int
    area: tuple[float, float, float]  # ECDF area over every target: mean, 95 % CI
    fitness_area: float               # over fitness targets only (nan without f*)
    parameter_area: float             # over parameter targets only
    ert: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    hit_rate: dict[str, float] = field(default_factory=dict)
    precision: dict[int, tuple[float, float, float]] = field(default_factory=dict)

    def row(self) -> dict[str, object]:
        """A flat row for CSV."""
        d: dict[str, object] = {"track": self.track, "solver": self.solver,
                                "cases": self.cases, "runs": self.runs, "errors": self.errors,
                                "ecdf_area": self.area[0], "ecdf_area_lo": self.area[1],
                                "ecdf_area_hi": self.area[2],
                                "fitness_area": self.fitness_area,
                                "parameter_area": self.parameter_area}
        for k, (e, lo, hi) in self.ert.items():
            d[f"ert_{k}"], d[f"ert_{k}_lo"], d[f"ert_{k}_hi"] = e, lo, hi
        for k, v in self.hit_rate.items():
            d[f"hits_{k}"] = v
        for b, (q10, q50, q90) in self.precision.items():
            d[f"precision_q10_at_{b}"], d[f"precision_median_at_{b}"], \
                d[f"precision_q90_at_{b}"] = q10, q50, q90
        return d


def budget_points(budget: int) -> tuple[int, ...]:
    """The fixed budgets reported: the last checkpoint within a tenth of the budget (the
    records hold the best-so-far there) and the whole budget."""
    early = [c for c in BUDGET_CHECKPOINTS if c <= budget / 10]
    return (early[-1], budget) if early else (budget,)


def anytime_score(track: str, solver: str, cases: str, records: list[dict]) -> AnytimeScore:
    h = [hits(r) for r in records]
    budgets = [r["budget"] for r in records]
    keys = list(dict.fromkeys(k for x in h for k in x))
    ert_d, rate = {}, {}
    for k in keys:
        hk = [x.get(k) for x in h if k in x]
        bk = [b for x, b in zip(h, budgets) if k in x]
        ert_d[k] = ert_ci(hk, bk, group_seed(track, solver, cases, k))
        rate[k] = sum(v is not None for v in hk) / len(hk)
    prec = {}
    for b in budget_points(min(budgets)):
        p = [v for v in (precision_at(r, b) for r in records) if not math.isnan(v)]
        prec[b] = tuple(float(q) for q in np.quantile(p, [0.1, 0.5, 0.9])) if p \
            else (math.nan,) * 3
    fit = [run_area(r, "f") for r in records]
    fit = [v for v in fit if not math.isnan(v)]
    return AnytimeScore(
        track=track, solver=solver, cases=cases, runs=len(records),
        errors=sum(map(is_error, records)),
        area=mean_ci([run_area(r) for r in records], group_seed(track, solver, cases)),
        fitness_area=_mean(fit),
        parameter_area=_mean([run_area(r, "p") for r in records]),
        ert=ert_d, hit_rate=rate, precision=prec)


def anytime_scores(records: list[dict], per_case: bool = False) -> list[AnytimeScore]:
    """Per (track, solver) over the non-sanity instances (``cases="all"``), ranked by ECDF
    area within each track; with ``per_case`` also per instance (sanity included)."""
    groups: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
    for r in records:
        if r["case"] not in SANITY_CASES:
            groups[(r["track"], "all", r["solver"])].append(r)
        if per_case:
            groups[(r["track"], r["case"], r["solver"])].append(r)
    scores = [anytime_score(t, s, c, rs) for (t, c, s), rs in groups.items()]
    return sorted(scores, key=lambda s: (s.track, s.cases != "all", s.cases,
                                         -np.nan_to_num(s.area[0], nan=-1.0), s.solver))


@dataclass(frozen=True)
class SanityScore:
    """On the healthy actuator: how many runs ended at (within 1 % of) the nominal vector."""

    track: str
    solver: str
    runs: int
    stayed: int
    median_max_range_error: float


def sanity_scores(records: list[dict]) -> list[SanityScore]:
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in records:
        if r["case"] in SANITY_CASES:
            groups[(r["track"], r["solver"])].append(r)
    out = []
    for (track, solver), rs in sorted(groups.items()):
        err = [max(derived(r).range_error.values()) for r in rs if not is_error(r)]
        out.append(SanityScore(track, solver, len(rs), sum(derived(r).success for r in rs),
                               float(np.median(err)) if err else math.nan))
    return out


def ecdf_curve(records: list[dict], grid: np.ndarray, kinds: str = "fp") -> np.ndarray:
    """Fraction of (run, target) pairs reached by each evaluation count of ``grid`` (the
    runs' non-sanity targets of ``kinds``: ``f`` fitness, ``p`` parameter)."""
    hit_times = [v if v is not None else math.inf for r in records
                 if r["case"] not in SANITY_CASES for k, v in hits(r).items()
                 if k[0] in kinds]
    if not hit_times:
        return np.full(grid.shape, math.nan)
    t = np.sort(np.asarray(hit_times, float))
    return np.searchsorted(t, grid, side="right") / t.size
