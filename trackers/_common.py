"""Helpers shared by the baseline trackers (not part of the tracker API).

Damage units
    Each failing fault is tracked as its *damage*: the distance from nominal towards its
    threshold as a share of the fault's range, ``d = sign (x - nominal) / (upper - lower)``
    with ``sign = +1`` when the threshold lies above nominal (``Fst``, ``BLK``) and ``-1``
    below (``Na``).  The campaigns' thresholds all lie at ``d = 0.75``.  ``Gprop`` has no
    threshold and is never a failing fault, whatever the thresholds say.
Fits
    :class:`Fitter`: the first inspection of a unit is fitted globally (CMA-ES from nominal
    through :func:`ema_bench.registry.run_solver`); each later one locally from the last
    estimate (the trust-region polish of :func:`ema_bench.uncertainty.intervals`, whose
    Laplace intervals come with it), escalating to CMA-ES from the last estimate when the
    residuals say the local fit missed (a backlash jump, a coil-short onset).
Fit cache
    Every baseline fits the same inspections the same way (one :class:`Fitter`, the same seed
    family), so the fits are shared: with ``EMA_BENCH_FIT_CACHE=DIR`` in the environment a
    fit is stored under DIR keyed by everything it depends on (:func:`fit_key`: the traces'
    values, the inspection's index and conditions' effects, the fitter's seed, budgets, solver
    and track, and the previous fit's estimate and misfit) and read back by the next tracker
    instead of being recomputed; the answers are bit for bit those without the cache (a test
    checks it).  Off by default.
RUL
    :func:`first_passage` runs Monte Carlo damage paths forward until each crosses a
    threshold (its life: the first crossing); :func:`summarise` turns the crossing times
    into the median and 95 % interval of the RUL, the failing fault and the probability of
    failing within the replacement horizon; :func:`replace_now` is the replacement rule every
    baseline uses.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ema_bench.faults import FAULT_INDEX, FAULT_NAMES, LOWER, NOMINAL, UPPER
from ema_bench.prognostics.distributions import LEVELS, level_key
from ema_bench.prognostics.tracking import Inspection, TrackStep
from ema_bench.seeding import SEED_SCHEME, child

#: Faults that never fail: a drifting gain is retuned, not replaced.
NEVER_FAILS = frozenset({"Gprop"})
#: Standard-normal quantile of the 95 % intervals.
Z95 = 1.959963984540054
RANGE = UPPER - LOWER

#: Replacement rule: replace when the predicted probability of failing within
#: ``REPLACE_HORIZON`` inspection intervals (the next inspection and one more: the time to
#: schedule the replacement) reaches ``REPLACE_PROB``, or when a failing fault's 95 %
#: interval lies wholly beyond its threshold.
REPLACE_HORIZON = 2.0
REPLACE_PROB = 0.10

#: How each failing fault's damage grows (physics of failure): wear runs at a nearly constant
#: rate with scatter (gamma-process increments, backlash jumps: ``linear``); an inter-turn
#: short spreads as the shorted loop heats its neighbours, so its damage grows
#: ``exponential``-ly once present.  Faults not listed are ``linear``.
GROWTH: dict[str, str] = {"Na": "exponential"}

#: Process noise of each failing fault's growth: level diffusion (per sqrt(flight)) and rate
#: diffusion (per flight per sqrt(flight)), in damage units for ``linear`` growth and in
#: log-damage units (the level is ``log d``, the rate the growth rate) for ``exponential``.
#: Orders of magnitude of fleet-v1's laws (docs/prognostics.md): friction's gamma process
#: about 2.4e-3 / sqrt(flight) at the median rate, backlash's jumps 7e-3 / sqrt(flight), a
#: coil short's log-growth scatter about 0.75 x its growth rate (0.022 per flight).
PROCESS_NOISE: dict[str, tuple[float, float]] = {
    "Fst": (3e-3, 3e-5), "BLK": (6e-3, 3e-5), "Na": (0.02, 2e-4)}
DEFAULT_PROCESS_NOISE = (3e-3, 1e-4)

#: Longest look-ahead of the RUL paths, flights; a path that has not crossed by then counts
#: as never failing (``inf``).
HORIZON_FLIGHTS = 1500.0


# --- damage units ----------------------------------------------------------------------------

def failing_faults(thresholds: Mapping[str, float]) -> list[str]:
    """The faults with a threshold, ``FAULT_NAMES`` order (never ``Gprop``)."""
    return [n for n in FAULT_NAMES if n in thresholds and n not in NEVER_FAILS]


def signs(names: list[str], thresholds: Mapping[str, float]) -> np.ndarray:
    """Direction of damage of each fault: +1 when its threshold lies above nominal."""
    return np.array([1.0 if thresholds[n] >= NOMINAL[FAULT_INDEX[n]] else -1.0 for n in names])


def to_damage(x: np.ndarray, names: list[str], thresholds: Mapping[str, float]) -> np.ndarray:
    """Damage (..., m) of physical fault vectors (..., 4), share of each fault's range."""
    j = [FAULT_INDEX[n] for n in names]
    x = np.asarray(x, dtype=float)
    return signs(names, thresholds) * (x[..., j] - NOMINAL[j]) / RANGE[j]


def from_damage(d: np.ndarray, names: list[str], thresholds: Mapping[str, float]) -> np.ndarray:
    """Physical values (..., m) of damages (..., m)."""
    j = [FAULT_INDEX[n] for n in names]
    return NOMINAL[j] + signs(names, thresholds) * np.asarray(d, dtype=float) * RANGE[j]


def damage_thresholds(names: list[str], thresholds: Mapping[str, float]) -> np.ndarray:
    """Each fault's threshold in damage units (m,)."""
    return to_damage(np.array([thresholds[n] if n in names else NOMINAL[FAULT_INDEX[n]]
                               for n in FAULT_NAMES]), names, thresholds)


def process_noise(names: list[str], scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Level and rate diffusion (m,) of each fault (:data:`PROCESS_NOISE`)."""
    q = np.array([PROCESS_NOISE.get(n, DEFAULT_PROCESS_NOISE) for n in names]) * scale
    return q[:, 0], q[:, 1]


def growth(name: str) -> str:
    """``linear`` or ``exponential`` (:data:`GROWTH`)."""
    return GROWTH.get(name, "linear")


# --- fitting an inspection -------------------------------------------------------------------

@dataclass
class Fit:
    """A fitted inspection: estimate ``x``, 95 % interval ``low``/``high`` and standard
    deviation ``sd`` (physical, (4,)), fitness, residual over sensor noise (worst signal),
    model runs spent, how it was found (``global``, ``local``, ``local+global``) and the
    correlation matrix (4, 4) of the Laplace covariance (identity where it is undefined)."""

    x: np.ndarray
    low: np.ndarray
    high: np.ndarray
    sd: np.ndarray
    fitness: float
    misfit: float
    evaluations: int
    how: str
    corr: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(len(FAULT_NAMES)))

    @property
    def cov(self) -> np.ndarray:
        """Covariance (4, 4), physical units: the interval's standard deviations with the
        Laplace correlations."""
        return self.corr * np.outer(self.sd, self.sd)


#: Environment variable naming the folder of the shared fit cache (module docstring).
FIT_CACHE_ENV = "EMA_BENCH_FIT_CACHE"


def fit_key(fitter: Fitter, insp: Inspection) -> str:
    """SHA-256 of everything :meth:`Fitter.__call__` depends on for ``insp``."""
    h = hashlib.sha256()
    for name in sorted(insp.traces.data):
        h.update(name.encode())
        h.update(np.ascontiguousarray(insp.traces.data[name], dtype=float).tobytes())
    e = fitter.effects(insp)
    last = fitter.last
    parts = (insp.index, float(insp.traces.dt), fitter.track, fitter.first_budget,
             fitter.global_budget, fitter.solver, fitter.seed_scheme, repr(fitter.seed.entropy),
             tuple(fitter.seed.spawn_key), None if e is None else np.asarray(e).tobytes(),
             None if last is None else (last.x.tobytes(), float(last.misfit)))
    h.update(repr(parts).encode())
    return h.hexdigest()


#: Residual over sensor noise above which a local fit is doubted (absolute floor, and
#: growth over the last accepted fit's: on the reference track the model-form error alone
#: lifts the ratio above 1).
MISFIT_FLOOR = 1.2
MISFIT_GROWTH = 1.15
#: Interval half-width when the Laplace interval cannot be computed, share of range.
FALLBACK_SD = 0.05


class Fitter:
    """Fit a unit's inspections in turn, each warm-started at the last estimate.

    Parameters
    ----------
    track : str
        The campaign's track (``twin`` or ``reference``): picks the intervals' model-form
        allowance.
    seed : SeedSequence
        The unit's seed; inspection ``i``'s solver run gets child ``i``.
    first_budget, global_budget : int
        CMA-ES evaluations for the first inspection (from nominal) and for an escalation
        (from the last estimate).
    solver : str
        The registered solver of the global fits.
    seed_scheme : int
        How a global fit's solver seed derives from the inspection's child of ``seed``
        (:func:`ema_bench.seeding.solver_seed`): this version's one-way hash, or scheme 1 for
        the committed runs tracked under it (``campaign_info["seed_scheme"]``), which replay
        only so.
    """

    def __init__(self, track: str, seed: np.random.SeedSequence, first_budget: int = 1500,
                 global_budget: int = 1000, solver: str = "cmaes",
                 effects: Callable[[Inspection], np.ndarray | None] | None = None,
                 seed_scheme: int = SEED_SCHEME) -> None:
        self.track = track if track in ("twin", "reference") else "measured"
        self.seed = seed
        self.effects = effects or (lambda insp: None)
        self.first_budget = int(first_budget)
        self.global_budget = int(global_budget)
        self.solver = solver
        self.seed_scheme = int(seed_scheme)
        self.last: Fit | None = None

    def __call__(self, insp: Inspection) -> Fit:
        folder = os.environ.get(FIT_CACHE_ENV)
        if not folder:
            return self._fit(insp)
        path = os.path.join(folder, fit_key(self, insp) + ".pkl")
        try:
            with open(path, "rb") as fh:
                fit = pickle.load(fh)
        except (OSError, pickle.UnpicklingError, EOFError):
            fit = self._fit(insp)
            os.makedirs(folder, exist_ok=True)
            tmp = f"{path}.{os.getpid()}.tmp"
            with open(tmp, "wb") as fh:
                pickle.dump(fit, fh)
            os.replace(tmp, path)   # atomic: a parallel reader sees all or nothing
        self.last = fit
        return fit

    def _fit(self, insp: Inspection) -> Fit:
        if self.last is None:
            fit = self._global(insp, None, self.first_budget, "global")
        else:
            fit = self._local(insp, self.last.x)
            if fit.misfit > max(MISFIT_FLOOR, MISFIT_GROWTH * self.last.misfit):
                other = self._global(insp, self.last.x, self.global_budget, "local+global")
                other.evaluations += fit.evaluations
                fit = other if other.fitness < fit.fitness else dataclasses.replace(
                    fit, evaluations=other.evaluations, how="local+global")
        self.last = fit
        return fit

    def _global(self, insp: Inspection, start: np.ndarray | None, budget: int,
                how: str) -> Fit:
        from ema_bench.registry import run_solver

        problem = insp.problem(start=start, budget=budget, effects=self.effects(insp))
        res = run_solver(self.solver, problem, seed=child(self.seed, insp.index),
                         seed_scheme=self.seed_scheme)
        fit = self._intervals(problem, res.x, polish=True)
        fit.evaluations += res.evaluations
        fit.how = how
        return fit

    def _local(self, insp: Inspection, start: np.ndarray) -> Fit:
        problem = insp.problem(start=start, budget=1, effects=self.effects(insp))
        fit = self._intervals(problem, start, polish=True)
        fit.how = "local"
        return fit

    def _intervals(self, problem, x: np.ndarray, polish: bool) -> Fit:
        """Laplace intervals at ``x`` after a local polish (which may move ``x``)."""
        from ema_bench.uncertainty import intervals
        from ema_bench.uncertainty.local import UncertaintyError

        try:
            iv = intervals(problem.objective, x, method="laplace", track=self.track,
                           polish=polish)
        except UncertaintyError:
            sd = FALLBACK_SD * RANGE
            return Fit(np.asarray(x, float), np.maximum(x - Z95 * sd, LOWER),
                       np.minimum(x + Z95 * sd, UPPER), sd, float("inf"), float("inf"), 0,
                       "fallback")
        n = len(FAULT_NAMES)
        est = iv.estimate[:n]
        half = np.maximum(iv.high - est, est - iv.low)[:n]
        cov = iv.cov[:n, :n]
        corr = np.eye(n)
        if np.isfinite(cov).all() and (np.diag(cov) > 0).all():
            corr = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
        return Fit(est, iv.low[:n], iv.high[:n], np.maximum(half / Z95, 1e-6 * RANGE),
                   float(iv.fitness), float(max(iv.noise_ratio.values())),
                   int(iv.evaluations), "", corr)


def condition_effects(campaign_info: Mapping) -> Callable[[Inspection], np.ndarray | None]:
    """The monitor effects of an inspection's logged conditions: the winding's resistance
    rise (copper) and the cold grease's viscous friction (the campaign's documented law and
    its ``viscous_ref``), :func:`ema_bench.prognostics.laws.confounders`.  An inspection
    without logged temperatures gets none."""
    from ema_bench.prognostics.laws import confounders

    c_ref = float(campaign_info.get("laws", {}).get("viscous_ref", 0.0))

    def effects(insp: Inspection) -> np.ndarray | None:
        c = insp.conditions
        if "ambient_temp_C" not in c or "winding_temp_C" not in c:
            return None
        return confounders(float(c["ambient_temp_C"]), float(c["winding_temp_C"]), c_ref)
    return effects


@dataclass
class UnitSetup:
    """What every baseline derives from the campaign and the unit's seed: the thresholds,
    the inspection spacing (flights), the failing faults and their thresholds in damage
    units, the inspection fitter (its seed family) and the Monte Carlo seed family."""

    thresholds: Mapping[str, float]
    every: float
    names: list[str]
    d_thr: np.ndarray
    fitter: Fitter
    mc_seed: np.random.SeedSequence
    effects: Callable[[Inspection], np.ndarray | None]


def unit_setup(campaign_info: Mapping, seed: np.random.SeedSequence, first_budget: int,
               global_budget: int, conditions: bool = True) -> UnitSetup:
    """A baseline's start on one unit (``conditions``: switch the logged conditions'
    confounders on in the monitor, :func:`condition_effects`)."""
    thresholds = campaign_info["thresholds"]
    names = failing_faults(thresholds)
    fit_seed, mc_seed = split_seed(seed)
    effects = condition_effects(campaign_info) if conditions else (lambda insp: None)
    fitter = Fitter(campaign_info.get("track", "measured"), fit_seed, first_budget,
                    global_budget, effects=effects,
                    seed_scheme=campaign_info.get("seed_scheme", SEED_SCHEME))
    return UnitSetup(thresholds, float(campaign_info["inspection_every"]), names,
                     damage_thresholds(names, thresholds), fitter, mc_seed, effects)


# --- remaining useful life -------------------------------------------------------------------

Advance = Callable[[float], np.ndarray]


def first_passage(d0: np.ndarray, advance: Advance, d_thr: np.ndarray, step: float,
                  horizon: float = HORIZON_FLIGHTS) -> np.ndarray:
    """Flights from now until each Monte Carlo path crosses each threshold.

    Parameters
    ----------
    d0 : array (n, m)
        Damage of every path now.
    advance : callable
        ``advance(dt)`` moves every path ``dt`` flights on and returns its damage (n, m).
    d_thr : array (m,)
        Thresholds, damage units.
    step, horizon : float
        Time step and look-ahead, flights.

    Returns
    -------
    array (n, m)
        Crossing time of each path and fault, flights (linear between steps; 0 for a path
        already past its threshold; ``inf`` when not crossed within ``horizon``), up to the
        step in which every path has crossed some threshold: a path's life is its first
        crossing, so the paths are not run on until their other faults cross too (a fault
        crossing after the last path's first one stays ``inf``).  Each row's minimum and
        its argmin are those of running every fault to its crossing: the steps before the
        stop are the same, and a fault first crossing in a later step crosses later.
    """
    prev = np.asarray(d0, dtype=float)
    t = np.where(prev >= d_thr, 0.0, np.inf)
    now = 0.0
    # until every path has a life (its first crossing), not every fault of every path:
    # a short not yet begun on most paths would otherwise run them all to the horizon
    while now < horizon and t.shape[1] and np.isinf(t).all(axis=1).any():
        cur = advance(step)
        hit = np.isinf(t) & (cur >= d_thr)
        if hit.any():
            frac = (d_thr - prev) / np.where(cur - prev > 0, cur - prev, 1.0)
            t[hit] = now + step * np.clip(frac, 0.0, 1.0)[hit]
        prev, now = cur, now + step
    return t


@dataclass
class RulSummary:
    """Median and 95 % interval of the RUL (flights), failing fault and probability of
    failing within the replacement horizon."""

    rul: float
    low: float
    high: float
    failing_fault: str | None
    p_fail: float
    quantiles: dict[str, float] = field(default_factory=dict)


def _rank(sorted_t: np.ndarray, q: float) -> float:
    """Nearest-rank quantile (no interpolation between ``inf`` and a number)."""
    k = min(max(int(np.ceil(q * sorted_t.size)) - 1, 0), sorted_t.size - 1)
    return float(sorted_t[k])


def summarise(cross: np.ndarray, names: list[str], horizon: float) -> RulSummary:
    """The RUL distribution of crossing times ``cross`` (n, m): each path fails with its
    first fault to cross; the failing fault is the one that fails most paths."""
    if cross.shape[1] == 0:
        return RulSummary(np.inf, np.inf, np.inf, None, 0.0)
    t = cross.min(axis=1)
    s = np.sort(t)
    first = np.argmin(cross, axis=1)[np.isfinite(t)]
    failing = names[int(np.bincount(first, minlength=len(names)).argmax())] \
        if first.size else None
    return RulSummary(_rank(s, 0.5), _rank(s, 0.025), _rank(s, 0.975), failing,
                      float(np.mean(t <= horizon)),
                      {level_key(q): _rank(s, q) for q in LEVELS})


def replace_now(summary: RulSummary, low: np.ndarray, high: np.ndarray,
                names: list[str], thresholds: Mapping[str, float],
                prob: float = REPLACE_PROB) -> bool:
    """The replacement rule (:data:`REPLACE_PROB` within :data:`REPLACE_HORIZON`
    intervals, or an interval wholly beyond a threshold); ``Gprop`` never counts."""
    if summary.p_fail >= prob:
        return True
    for n in names:
        j = FAULT_INDEX[n]
        thr = thresholds[n]
        beyond = low[j] > thr if thr >= NOMINAL[j] else high[j] < thr
        if beyond:
            return True
    return False


def make_step(insp: Inspection, x: np.ndarray, low: np.ndarray, high: np.ndarray,
              summary: RulSummary, replace: bool, evaluations: int,
              profile_rul: float | None = None, **extra) -> TrackStep:
    """The :class:`TrackStep` of physical estimate and interval vectors (4,)
    (``profile_rul``: the unconditioned RUL when ``summary``'s is conditioned on the cut)."""
    d = {n: float(v) for n, v in zip(FAULT_NAMES, x)}
    return TrackStep(flight=insp.flight, estimate=d,
                     low={n: float(min(v, d[n])) for n, v in zip(FAULT_NAMES, low)},
                     high={n: float(max(v, d[n])) for n, v in zip(FAULT_NAMES, high)},
                     rul=summary.rul, rul_low=summary.low, rul_high=summary.high,
                     failing_fault=summary.failing_fault, replace=bool(replace),
                     evaluations=int(evaluations), extra=extra,
                     rul_quantiles=dict(summary.quantiles), profile_rul=profile_rul)


def split_seed(seed: np.random.SeedSequence) -> tuple[np.random.SeedSequence,
                                                      np.random.SeedSequence]:
    """A unit's seed split in two disjoint families: the fits' (:class:`Fitter`) and the
    Monte Carlo's (:func:`rng_of`)."""
    return child(seed, 0), child(seed, 1)


def rng_of(seed: np.random.SeedSequence, index: int) -> np.random.Generator:
    """The generator of inspection ``index`` from the Monte Carlo family of
    :func:`split_seed`."""
    return np.random.default_rng(child(seed, index))
