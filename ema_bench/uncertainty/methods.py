"""One entry point for the uncertainty of a fit: :func:`intervals`.

Methods (a registry, :data:`METHODS`):

* ``laplace`` (default) -- the Gauss-Newton sandwich covariance at the (polished) fit, with
  the noise level estimated from the residuals per signal; ``t_hat +- z se``.  Cheap (one
  batched Jacobian, ``2 dim + 1`` evaluations, plus the polish).
* ``profile`` -- profile-likelihood intervals (:mod:`~ema_bench.uncertainty.profile`),
  which follow curved valleys and stop at bounds.
* ``bootstrap`` -- parametric bootstrap refits (:mod:`~ema_bench.uncertainty.bootstrap`).

Model-form error (``model_form``): on the reference track and on measured data the monitor
did not make the data, so noise alone under-states the error.  ``"discrepancy"`` widens every
fault interval by the monitor's calibrated model-form allowance
(:mod:`~ema_bench.uncertainty.model_form`); ``"none"`` does not.  The default ``"auto"`` uses
``"none"`` on the twin track (the monitor made the data) and ``"discrepancy"`` otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..objective import N_FAULTS, Objective
from ..seeding import SeedLike, as_seed_sequence
from ..traces import SIGNALS
from . import model_form as mf
from .bootstrap import N_BOOT, bootstrap_estimates, normal_interval
from .conformal import calibration_factor, calibration_kind
from .identifiability import report
from .local import Counter, UncertaintyError, jacobian, refit, sandwich
from .noise import estimated_sigma, known_sigma, weighed
from .profile import Profile, profile_interval

#: Evaluations a local polish of the fit may take before the intervals are computed.
POLISH_EVALS = 400
#: Default cap on an interval computation's evaluations, polish included.
MAX_EVALS = 3000
NOISE_MODES = ("estimated", "known")
#: Residual over sensor noise above which a fit is flagged (the twin track's fits at the
#: optimum stay below 1.06 over 200 instances, the reference track's below 1.12 over 100).
MISFIT_RATIO = 1.2
MODEL_FORM_MODES = ("auto", "none", "discrepancy")


@dataclass
class Intervals:
    """Intervals of a fit, physical units, in the search space's ``names`` order.

    ``estimate``: the (polished) fit the intervals are centred on; ``low``/``high``: interval
    ends; ``noise_low``/``noise_high``: the method's ends from the noise alone; ``cov``:
    Laplace sandwich covariance; ``noise_ratio``: estimated over known noise per signal;
    ``allowance``: model-form half-width combined in quadrature (0 when none); ``factor``:
    the calibration factor each half-width was multiplied by (1: none), from the
    ``calibration`` set (``twin``, ``reference`` or ``none``);
    ``evaluations``: the model runs the polish and the method took (not counted against any
    problem's budget); ``profiles`` (profile method): per parameter, grid values and chi-square
    drops; ``replicates`` (bootstrap): refit estimates."""

    method: str
    level: float
    names: tuple[str, ...]
    units: dict[str, str]
    lower: np.ndarray
    upper: np.ndarray
    estimate: np.ndarray
    fitness: float
    low: np.ndarray
    high: np.ndarray
    cov: np.ndarray
    noise_low: np.ndarray
    noise_high: np.ndarray
    noise_ratio: dict[str, float]
    allowance: np.ndarray
    model_form: str
    noise: str
    factor: np.ndarray
    calibration: str
    evaluations: int
    identifiability: dict[str, object]
    profiles: list[dict[str, list[float]] | None] = field(default_factory=list)
    replicates: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def ranges(self) -> np.ndarray:
        return self.upper - self.lower

    def uncalibrated(self) -> tuple[np.ndarray, np.ndarray]:
        """The interval ends before calibration: the method's noise half-widths combined in
        quadrature with the model-form allowance (what calibration scores are taken on)."""
        u = self.estimate
        return (u - np.hypot(u - self.noise_low, self.allowance),
                u + np.hypot(self.noise_high - u, self.allowance))

    def width_percent(self) -> np.ndarray:
        """Interval widths in % of each parameter's range."""
        return 100.0 * (self.high - self.low) / self.ranges

    def contains(self, x: np.ndarray) -> np.ndarray:
        """Per parameter, whether ``x`` lies in its interval."""
        x = np.asarray(x, dtype=float)[:len(self.names)]
        return (self.low <= x) & (x <= self.high)

    def as_dict(self) -> dict[str, object]:
        """The JSON form: ``intervals`` (name -> [low, high]), ``interval_method`` and the
        rest of the report."""
        n = self.names
        return {
            "intervals": {k: [float(a), float(b)] for k, a, b in zip(n, self.low, self.high)},
            "interval_method": self.method,
            "interval_level": self.level,
            "interval_estimate": {k: float(v) for k, v in zip(n, self.estimate)},
            "interval_width_percent": {k: float(v) for k, v in zip(n, self.width_percent())},
            "interval_noise_only": {k: [float(a), float(b)] for k, a, b in
                                    zip(n, self.noise_low, self.noise_high)},
            "model_form": self.model_form,
            "calibration": self.calibration,
            "calibration_factor": {k: float(v) for k, v in zip(n, self.factor)},
            "model_form_allowance": {k: float(v) for k, v in zip(n, self.allowance)},
            "noise": self.noise,
            "noise_ratio": self.noise_ratio,
            "interval_evaluations": self.evaluations,
            "identifiability": self.identifiability,
            "interval_warnings": self.warnings,
        }


@dataclass
class _Fit:
    """What every method starts from: the counted objective, the polished fit in the unit
    box, its outputs, Jacobian, noise, covariance and information."""

    counter: Counter
    u: np.ndarray
    f: float
    y: np.ndarray
    J: np.ndarray
    sigma: np.ndarray
    cov: np.ndarray
    A: np.ndarray


Method = Callable[[_Fit, float, int, SeedLike, int, np.ndarray],
                  tuple[np.ndarray, np.ndarray, dict]]


def _chi2_1(level: float) -> float:
    """Chi-square quantile, one degree of freedom (scipy.stats is imported here, not with
    the module: it costs 0.5 s of every command's start-up)."""
    from scipy.stats import chi2

    return float(chi2.ppf(level, 1))


def _laplace(fit: _Fit, level: float, max_evals: int, seed: SeedLike,
             n_boot: int, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    z = float(np.sqrt(_chi2_1(level)))
    half = z * np.sqrt(np.diag(fit.cov))
    return fit.u - half, fit.u + half, {}


def _profile(fit: _Fit, level: float, max_evals: int, seed: SeedLike,
             n_boot: int, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    threshold = _chi2_1(level)
    lo, hi, _ = _laplace(fit, level, max_evals, seed, n_boot, which)
    profiles: list[dict | None] = [None] * fit.u.size
    start = fit.counter.evaluations
    todo = list(np.flatnonzero(which))
    for k, j in enumerate(todo):
        # an even share of what is left for each remaining parameter
        left = max_evals - (fit.counter.evaluations - start)
        p: Profile = profile_interval(fit.counter, fit.u, fit.f, j, fit.A, fit.cov,
                                      threshold, left // (len(todo) - k))
        lo[j], hi[j] = p.low, p.high
        order = np.argsort(p.t)
        profiles[j] = {"t": [p.t[i] for i in order], "q": [p.q[i] for i in order],
                       "better": p.better}
    return lo, hi, {"profiles": profiles}


def _bootstrap(fit: _Fit, level: float, max_evals: int, seed: SeedLike,
               n_boot: int, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    boot = bootstrap_estimates(fit.counter, fit.u, fit.y, fit.sigma, n_boot, seed, max_evals)
    if boot.shape[0] < 10:
        raise UncertaintyError(f"only {boot.shape[0]} bootstrap refits fit in {max_evals} "
                               "evaluations; give a larger max_evals or fewer replicates")
    lo, hi = normal_interval(fit.u, boot, level)
    return lo, hi, {"replicates": boot}


#: name -> method (unit-box intervals from a polished fit)
METHODS: dict[str, Method] = {"laplace": _laplace, "profile": _profile,
                              "bootstrap": _bootstrap}


def intervals(objective: Objective, x: np.ndarray, *, method: str = "laplace",
              level: float = 0.95, track: str | None = None, model_form: str = "auto",
              noise: str = "estimated", noise_scale: float = 1.0, calibrate: bool = True,
              polish: bool = True, params: Sequence[str] | None = None,
              max_evals: int = MAX_EVALS, n_boot: int = N_BOOT,
              seed: SeedLike = 0) -> Intervals:
    """Intervals for the fit ``x`` of ``objective`` (a problem's ``objective``).

    Parameters
    ----------
    objective : Objective
        What was minimised (``problem.objective``).
    x : array (dim,)
        The fit, physical units (``names`` order).
    method : {"laplace", "profile", "bootstrap"}
        See the module docstring.
    level : float
        Coverage level in (0, 1).
    track : str, optional
        Where the data come from (``twin``, ``reference``, ``measured``); picks the
        model-form default.
    model_form : {"auto", "none", "discrepancy"}
        Model-form allowance (see the module docstring).
    noise : {"estimated", "known"}
        Noise level from the residuals (default) or from the sensors' datasheet.
    noise_scale : float
        Multiplies the noise level (a sensitivity study; 1 is the honest value).
    calibrate : bool
        Multiply each fault's half-width by its shipped calibration factor
        (:mod:`~ema_bench.uncertainty.conformal`: split-conformal, from coverage runs on
        instances disjoint from those coverage is reported on).
    params : sequence of str, optional
        The parameters the profile method profiles (default all; the others get their
        Laplace intervals).
    polish : bool
        Refine ``x`` by a local least-squares refit first (at most ``POLISH_EVALS``
        evaluations); the intervals assume the gradient vanishes at their centre.
    max_evals : int
        Cap on the evaluations of the whole computation (polish and Jacobian included); the
        profile and bootstrap methods stop there (a profile side then keeps its Laplace
        end, a bootstrap its replicates so far).
    n_boot : int
        Bootstrap replicates.
    seed : int or SeedSequence
        Randomness of the bootstrap (a run passes its node's ``intervals`` stream).

    Raises
    ------
    UncertaintyError
        Unknown method or mode, bad level, or a fit the model cannot simulate.
    """
    if method not in METHODS:
        raise UncertaintyError(f"unknown interval method {method!r}; known: {list(METHODS)}")
    if model_form not in MODEL_FORM_MODES:
        raise UncertaintyError(f"model_form must be one of {list(MODEL_FORM_MODES)}, got "
                               f"{model_form!r}")
    if noise not in NOISE_MODES:
        raise UncertaintyError(f"noise must be one of {list(NOISE_MODES)}, got {noise!r}")
    if not 0.0 < float(level) < 1.0:
        raise UncertaintyError(f"level must lie in (0, 1), got {level!r}")
    if not (np.isfinite(noise_scale) and noise_scale > 0):
        raise UncertaintyError(f"noise_scale must be a positive number, got {noise_scale!r}")
    if int(max_evals) < 1 or int(n_boot) < 1:
        raise UncertaintyError("max_evals and n_boot must be positive")
    space = objective.space
    unknown = [n for n in (params or ()) if n not in space.names]
    if unknown:
        raise UncertaintyError(f"unknown parameter(s) {unknown}; known: {list(space.names)}")
    which = np.array([params is None or n in params for n in space.names])
    u0 = space.to_unit(space.check(np.asarray(x, dtype=float)[None, :])[0])
    counter = Counter(objective)
    if polish:   # the best point the refit saw, its start included
        u, f = refit(counter, u0, max_evals=POLISH_EVALS)
    else:
        _, f0 = counter.outputs(u0[None, :])
        u, f = u0, float(f0[0])
    if not np.isfinite(f):
        raise UncertaintyError("the monitor model fails at the fit: no interval")
    y, J = jacobian(counter, u)
    resid = counter.residual(y)
    est = estimated_sigma(objective, resid, u.size)
    sigma = (est if noise == "estimated" else known_sigma()) * float(noise_scale)
    cov, A = sandwich(objective, J, sigma)
    fit = _Fit(counter, u, float(f), y, J, sigma, cov, A)
    # max_evals caps everything the intervals cost, the polish and the Jacobian included
    lo, hi, extra = METHODS[method](fit, float(level),
                                    max(int(max_evals) - counter.evaluations, 0),
                                    as_seed_sequence(seed), int(n_boot), which)
    ranges = space.upper - space.lower
    mode = model_form if model_form != "auto" else ("none" if track == "twin" else
                                                     "discrepancy")
    allowance = np.zeros(u.size)
    if mode == "discrepancy":
        allowance[:N_FAULTS] = mf.allowance(level)
    factor = np.ones(u.size)
    fac = calibration_factor(calibration_kind(track), method, mode, level) \
        if calibrate else None
    if fac is not None:
        factor[:N_FAULTS] = fac
    low = np.clip(u - factor * np.hypot(u - lo, allowance), 0.0, 1.0)
    high = np.clip(u + factor * np.hypot(hi - u, allowance), 0.0, 1.0)
    # an output the fitness does not weigh tells nothing: infinite noise on its elements
    ident = report(J, np.where(weighed(objective), sigma[objective.signal_index], np.inf),
                   cov, high - low, space.names, ranges, space.units)
    profiles = [None if p is None else
                {"value": list(space.lower[j] + np.array(p["t"]) * ranges[j]), "q": p["q"],
                 "better": None if p["better"] is None else float(p["better"])}
                for j, p in enumerate(extra.get("profiles", []))]
    rep = extra.get("replicates")
    ratio = est / known_sigma()
    loud = [f"{SIGNALS[k]} {ratio[k]:.2f}x" for k in np.flatnonzero(ratio > MISFIT_RATIO)]
    warnings = [f"the residuals exceed the sensor noise ({', '.join(loud)}): the fit is not "
                "at the optimum or the model misses physics (the intervals widen with the "
                "residuals)"] if loud else []
    better = [p["better"] for p in profiles if p is not None and p["better"] is not None]
    if better and min(better) < f - 1e-9 * abs(f):
        warnings.append(f"a profile refit found a lower fitness ({min(better):.6g} < {f:.6g}):"
                        " the fit was not at the optimum")
    return Intervals(
        method=method, level=float(level), names=space.names, units=dict(space.units),
        lower=np.array(space.lower), upper=np.array(space.upper),
        estimate=space.from_unit(u), fitness=float(f),
        low=space.from_unit(low), high=space.from_unit(high),
        noise_low=space.from_unit(np.clip(lo, 0.0, 1.0)),
        noise_high=space.from_unit(np.clip(hi, 0.0, 1.0)),
        cov=cov * np.outer(ranges, ranges),
        noise_ratio={s: float(v) for s, v in zip(SIGNALS, ratio)},
        allowance=allowance * ranges, model_form=mode, noise=noise,
        factor=factor, calibration="none" if fac is None else calibration_kind(track),
        evaluations=counter.evaluations, identifiability=ident, profiles=profiles,
        replicates=None if rep is None else space.from_unit(rep), warnings=warnings)
