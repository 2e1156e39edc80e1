"""``refit-trend``: fit every inspection, then extrapolate each fault's recent trend.

Model
    Each inspection is identified on its own (:class:`~._common.Fitter`: CMA-ES from nominal
    on the first, a local refit from the last estimate afterwards, CMA-ES again when the
    residuals say the local refit missed), with the confounders of the logged operating
    conditions switched on in the monitor (:func:`~._common.condition_effects`), and given
    Laplace 95 % intervals.  Each failing fault's damage (share of range towards its
    threshold) is taken to grow with independent increments (wear: a gamma process, Poisson
    jumps, a random walk with drift): between two inspections ``dt`` flights apart,
    ``d_i - d_{i-1} = rate dt + noise``, the noise of variance ``sigma^2 dt`` plus the two
    estimates' variances (from their intervals).
Trend
    Weighted least squares on the increment rates ``(d_i - d_{i-1}) / dt`` over the last
    ``window`` (12) estimates.  Rate laws: *linear* (a constant rate), *exponential* (``rate
    = b0 + g d``: a coil short that spreads; fitted on the increments that start from damage
    already present, :data:`DETECT_SD` standard deviations above zero, so an onset jump is
    not taken for growth) and *quadratic* (the rate grows linearly in flights).  Linear
    unless a richer law beats it by :data:`MARGIN` in AICc on the same increments, and still
    does without the latest one (a single jump is not a trend); exponential is tried first.
    ``sigma^2`` is estimated from the rate residuals by moments, shrunk towards
    :data:`PRIOR_NOISE` squared with the weight of two increments (so two inspections give a
    usable trend).
RUL distribution
    Monte Carlo: 2,000 paths start at the current estimate (drawn within its interval), with
    trend coefficients drawn from their least-squares covariance, and run forward with the
    trend plus the increments' noise (a random walk of variance ``sigma^2`` per flight), in
    half-interval steps, up to 1,500 flights.  A path fails with its first fault to cross
    its threshold; the RUL is the median and 2.5-97.5 % quantiles of the failure times
    (``inf`` where more than that share never fails).  With one inspection only there is no
    trend yet: the RUL is ``[0, inf]`` with an infinite median.
Replacement
    :func:`~._common.replace_now`: probability of failing within two inspection intervals
    at least 10 %, or a failing fault's interval wholly past its threshold.  ``Gprop`` is
    fitted and reported but never tracked for failure.
Assumptions
    The fault trends are independent of each other; a coil short's onset is not predicted
    (a healthy coil has no trend); the confounders follow the campaign's documented laws
    (``conditions=False`` leaves them out, and they land in the estimates as bias).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ema_bench.faults import FAULT_INDEX
from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker

from ._common import (
    RANGE,
    REPLACE_HORIZON,
    REPLACE_PROB,
    RulSummary,
    first_passage,
    make_step,
    replace_now,
    rng_of,
    summarise,
    to_damage,
    unit_setup,
)

WINDOW = 12
#: AICc gain a richer rate law needs over the linear one (beyond its own penalty).
MARGIN = 2.0
#: Damage counts as present at an estimate this many standard deviations above zero.
DETECT_SD = 3.0
#: Damage of a path that cannot fail (a fault without a trend yet).
NEVER = -1e9
N_PATHS = 2000
#: Prior of the increments' noise, damage units per sqrt(flight), and its weight in
#: increments (friction's gamma process at fleet-v1's median rate is about 2.4e-3).
PRIOR_NOISE = 3e-3
PRIOR_INCREMENTS = 2.0
#: Rate laws: the columns of ``(1, 2 h, d)`` each uses (``rate = b0 + 2 b1 h + bd d``).
LAWS = {"linear": (0,), "quadratic": (0, 1), "exponential": (0, 2)}


@dataclass
class Trend:
    """A fault's rate law: ``rate(h, d) = b0 + 2 b1 h + bd d`` (``h``: flights from now,
    ``d``: damage), coefficient mean and covariance over ``(b0, b1, bd)``, and the
    increments' noise variance per flight, damage units."""

    law: str
    mean: np.ndarray
    cov: np.ndarray
    sigma2: float
    aicc: float


@dataclass
class _Increments:
    """Rate observations between consecutive estimates: rate, span (flights), measurement
    variance of the increment, midpoint (flights from now) and mean damage."""

    rate: np.ndarray
    dt: np.ndarray
    meas: np.ndarray
    tau: np.ndarray
    dbar: np.ndarray

    def take(self, keep: np.ndarray) -> _Increments:
        return _Increments(*(a[keep] for a in (self.rate, self.dt, self.meas, self.tau,
                                               self.dbar)))


def _wls(law: str, inc: _Increments, q_level: float) -> Trend | None:
    """Weighted least squares of one rate law: the noise variance per flight and the
    coefficients by alternation (moments: ``E[(res dt)^2] = sigma^2 dt + meas``), the noise
    shrunk towards ``q_level^2`` with the weight of :data:`PRIOR_INCREMENTS` increments."""
    X = np.stack([np.ones_like(inc.tau), 2.0 * inc.tau, inc.dbar], axis=1)
    used = np.array(LAWS[law])
    Xu, n, dt = X[:, used], inc.rate.size, inc.dt
    dof = n - used.size
    sigma2 = q_level ** 2
    for _ in range(3):
        v = (sigma2 * dt + inc.meas) / dt ** 2
        try:
            cov_u = np.linalg.inv(Xu.T @ (Xu / v[:, None]))
        except np.linalg.LinAlgError:
            return None
        beta = cov_u @ (Xu.T @ (inc.rate / v))
        res = inc.rate - Xu @ beta
        moment = max(float(np.sum(res ** 2 * dt ** 2 - inc.meas)), 0.0) / float(dt.sum())
        moment *= n / dof if dof > 0 else 0.0
        sigma2 = (max(dof, 0) * moment + PRIOR_INCREMENTS * q_level ** 2) / (
            max(dof, 0) + PRIOR_INCREMENTS)
    v = (sigma2 * dt + inc.meas) / dt ** 2
    nll = float(np.sum(np.log(2 * np.pi * v) + res ** 2 / v))
    p = used.size + 1
    aicc = nll + 2 * p + (2 * p * (p + 1) / (n - p - 1) if n > p + 1 else np.inf)
    mean, cov = np.zeros(3), np.zeros((3, 3))
    mean[used] = beta
    cov[np.ix_(used, used)] = cov_u
    return Trend(law, mean, cov, sigma2, aicc)


def _beats_linear(law: str, inc: _Increments, q_level: float) -> Trend | None:
    """The ``law`` fit if it beats the linear one on ``inc`` by :data:`MARGIN`, and still
    does without the latest increment (one jump is not a trend); else None."""
    for data in (inc, inc.take(np.arange(inc.rate.size - 1))):
        if data.rate.size < 5:                    # AICc of 3 parameters needs n >= 5
            return None
        rich, lin = _wls(law, data, q_level), _wls("linear", data, q_level)
        if rich is None or lin is None or not rich.aicc + MARGIN < lin.aicc:
            return None
    return _wls(law, inc, q_level)


def fit_trend(t: np.ndarray, d: np.ndarray, s: np.ndarray, q_level: float) -> Trend | None:
    """The rate law of one fault from estimates ``d`` (damage) at flights ``t`` with standard
    deviations ``s``; None with fewer than two estimates.

    Linear on every increment unless a richer law beats it (:func:`_beats_linear`): the
    exponential one, on the increments that start from damage already present
    (:data:`DETECT_SD`), first; then the quadratic one."""
    if t.size < 2:
        return None
    dt = np.diff(t).astype(float)
    inc = _Increments(np.diff(d) / dt, dt, s[1:] ** 2 + s[:-1] ** 2,
                      0.5 * (t[1:] + t[:-1]) - t[-1], 0.5 * (d[1:] + d[:-1]))
    present = d[:-1] > DETECT_SD * s[:-1]
    # growth with the damage is only seen once there is damage (a coil short's onset jump
    # from zero is not a growth rate)
    k = int(np.argmin(present[::-1])) if not present.all() else present.size
    exp = _beats_linear("exponential", inc.take(np.arange(inc.rate.size - k,
                                                          inc.rate.size)), q_level)
    if exp is not None:
        return exp
    return _beats_linear("quadratic", inc, q_level) or _wls("linear", inc, q_level)


def predict(trends: list[Trend | None], d_now: np.ndarray, s_now: np.ndarray,
            d_thr: np.ndarray, rng: np.random.Generator, n_paths: int, step: float
            ) -> np.ndarray:
    """Crossing times (n_paths, m) of Monte Carlo paths of the trends (``inf`` for a fault
    without a trend)."""
    m = d_now.size
    d0 = d_now + s_now * rng.standard_normal((n_paths, m))
    B = np.zeros((n_paths, m, 3))
    sig = np.zeros(m)
    for j, tr in enumerate(trends):
        if tr is None:
            d0[:, j] = NEVER    # no trend: the path stays put, far below any threshold
        else:
            B[:, j] = rng.multivariate_normal(tr.mean, tr.cov, size=n_paths,
                                              check_valid="ignore", method="eigh")
            sig[j] = np.sqrt(tr.sigma2)
    state = {"d": d0, "h": 0.0}

    def advance(dt: float) -> np.ndarray:
        d, h = state["d"], state["h"]
        rate = B[..., 0] + B[..., 1] * (2 * h + dt) + B[..., 2] * d
        state["d"] = d + rate * dt + sig * np.sqrt(dt) * rng.standard_normal(d.shape)
        state["h"] = h + dt
        return state["d"]

    return first_passage(d0, advance, d_thr, step)


@register_tracker("refit-trend", description="refit every inspection (Laplace intervals), "
                  "extrapolate each fault's recent trend (linear/quadratic/exponential rate "
                  "by AICc) to its threshold by Monte Carlo")
def factory(campaign_info: dict, seed: np.random.SeedSequence, *, window: int = WINDOW,
            n_paths: int = N_PATHS, first_budget: int = 1500, global_budget: int = 1000,
            replace_prob: float = REPLACE_PROB, conditions: bool = True):
    u = unit_setup(campaign_info, seed, first_budget, global_budget, conditions)
    thresholds, every, names, d_thr, fitter, mc_seed = (u.thresholds, u.every, u.names, u.d_thr,
                                                        u.fitter, u.mc_seed)
    j = [FAULT_INDEX[n] for n in names]
    t_hist: list[float] = []
    d_hist: list[np.ndarray] = []
    s_hist: list[np.ndarray] = []

    def step(insp: Inspection) -> TrackStep:
        fit = fitter(insp)
        t_hist.append(float(insp.flight))
        d_hist.append(to_damage(fit.x, names, thresholds))
        s_hist.append(fit.sd[j] / RANGE[j])
        t = np.array(t_hist[-window:])
        D, S = np.array(d_hist[-window:]), np.array(s_hist[-window:])
        trends = [fit_trend(t, D[:, k], S[:, k], PRIOR_NOISE) for k in range(len(names))]
        if any(tr is not None for tr in trends):
            cross = predict(trends, D[-1], S[-1], d_thr, rng_of(mc_seed, insp.index),
                            n_paths, every / 2)
            summary = summarise(cross, names, REPLACE_HORIZON * every)
        else:
            summary = RulSummary(np.inf, 0.0, np.inf, None, 0.0)
        replace = replace_now(summary, fit.low, fit.high, names, thresholds, replace_prob)
        return make_step(insp, fit.x, fit.low, fit.high, summary, replace, fit.evaluations,
                         fit=fit.how, misfit=round(fit.misfit, 4), p_fail=summary.p_fail,
                         laws={n: tr.law for n, tr in zip(names, trends) if tr is not None})

    return step
