"""``kalman``: a local-linear-trend Kalman filter per fault over the fitted estimates.

Model
    Each inspection is identified as in ``refit-trend`` (:class:`~._common.Fitter`, with the
    logged operating conditions' confounders switched on in the monitor) with Laplace 95 %
    intervals.  Each failing fault has its own two-state filter, flights as time::

        y(t + dt)    = y(t) + rate(t) dt + w_y,   w_y ~ N(0, q_y^2 dt)     (scatter)
        rate(t + dt) = rate(t) + w_r,             w_r ~ N(0, q_r^2 dt)     (rate drift)

    (the exact discretisation of a random walk on the rate, integrated into the level).  For a
    fault that wears at a nearly constant rate (``linear`` growth, :data:`~._common.GROWTH`:
    friction, backlash) ``y`` is the damage ``d`` (share of range towards the threshold); for
    one that spreads (``exponential``: a coil short) ``y = log d``, so the rate is the growth
    rate and the filter starts only once the damage is present (its estimate
    :data:`DETECT_SD` standard deviations above zero).  ``q_y`` and ``q_r``:
    :data:`~._common.PROCESS_NOISE`.  The measurement is the fitted damage (or its log) with
    the variance of its interval (``half-width / 1.96``, through the log's derivative).
Initialisation
    ``y`` = the measurement; rate ``N(0, RATE0^2)``: ``5e-3`` per flight for linear growth (a
    fault crossing three quarters of its range in 150 flights is one standard deviation
    away), ``0.05`` per flight for exponential growth (an e-folding in 20 flights).
Adaptive process noise
    Gamma-process increments and backlash jumps are heavier-tailed than a Gaussian: a fault's
    process noise is multiplied by the mean of its last :data:`NIS_WINDOW` normalised
    innovations squared, between 1 and :data:`MAX_SCALE`.
RUL distribution
    Monte Carlo: 2,000 states drawn from each filter's distribution, propagated by the same
    model in half-interval steps up to 1,500 flights; a path fails with its first fault to
    cross its threshold; median and 2.5-97.5 % quantiles of the failure times.  A fault
    whose exponential filter has not started cannot fail (its onset is not predicted).
Estimates reported
    Failing faults: the filtered damage and its 95 % interval (the fit's before a filter
    starts); ``Gprop``: the fit.
Replacement
    :func:`~._common.replace_now` (failure within two inspection intervals with probability
    at least 10 %, or a fault's interval wholly past its threshold); ``Gprop`` never counts.
"""

from __future__ import annotations

import numpy as np

from ema_bench.faults import FAULT_INDEX
from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker

from ._common import (
    RANGE,
    REPLACE_HORIZON,
    REPLACE_PROB,
    Z95,
    Advance,
    first_passage,
    from_damage,
    growth,
    make_step,
    process_noise,
    replace_now,
    rng_of,
    summarise,
    to_damage,
    unit_setup,
)

RATE0 = {"linear": 5e-3, "exponential": 0.05}
DETECT_SD = 3.0
N_PATHS = 2000
NIS_WINDOW = 4
MAX_SCALE = 25.0


def transition(dt: float, q_y: float, q_r: float) -> tuple[np.ndarray, np.ndarray]:
    """State transition ``F`` and process noise ``Q`` (2, 2) over ``dt`` flights."""
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q_r ** 2 * np.array([[dt ** 3 / 3.0, dt ** 2 / 2.0], [dt ** 2 / 2.0, dt]])
    Q[0, 0] += q_y ** 2 * dt
    return F, Q


class TrendFilter:
    """One fault's local-linear-trend filter on ``y`` (damage, or its log)."""

    def __init__(self, law: str, q_y: float, q_r: float) -> None:
        self.law, self.q_y, self.q_r = law, q_y, q_r
        self.x: np.ndarray | None = None
        self.P = np.zeros((2, 2))
        self.t = 0.0
        self.nis: list[float] = []
        self.scale = 1.0

    @property
    def started(self) -> bool:
        return self.x is not None

    def measure(self, d: float, sd: float) -> tuple[float, float] | None:
        """``(y, variance)`` of a damage measurement, or None where the log of an absent
        damage is undefined (before an exponential filter starts)."""
        if self.law == "linear":
            return d, sd ** 2
        if not self.started and d <= DETECT_SD * sd:
            return None
        d = max(d, sd)                 # a started filter takes a dip to zero as 'small'
        return float(np.log(d)), (sd / d) ** 2

    def update(self, t: float, d: float, sd: float) -> float:
        """Predict to flight ``t`` and update with damage ``d`` of standard deviation ``sd``;
        returns the normalised innovation squared (0 at the start, NaN when not started)."""
        m = self.measure(d, sd)
        if m is None:
            return float("nan")
        z, r = m
        if not self.started:
            self.x = np.array([z, 0.0])
            self.P = np.diag([r, RATE0[self.law] ** 2])
            self.t = t
            return 0.0
        F, Q = transition(t - self.t, self.q_y * np.sqrt(self.scale),
                          self.q_r * np.sqrt(self.scale))
        x, P = F @ self.x, F @ self.P @ F.T + Q
        S = P[0, 0] + r
        nu = z - x[0]
        K = P[:, 0] / S
        self.x, self.P, self.t = x + K * nu, P - np.outer(K, P[0]), t
        nis = float(nu ** 2 / S)
        self.nis = (self.nis + [nis])[-NIS_WINDOW:]
        self.scale = float(np.clip(np.mean(self.nis), 1.0, MAX_SCALE))
        return nis

    def damage(self) -> tuple[float, float, float]:
        """Filtered damage and its 95 % interval ends."""
        y, sd = self.x[0], np.sqrt(self.P[0, 0])
        ends = (y, y - Z95 * sd, y + Z95 * sd)
        return tuple(float(np.exp(v)) for v in ends) if self.law == "exponential" else ends

    def paths(self, rng: np.random.Generator, n: int) -> tuple[np.ndarray, Advance]:
        """Damage of ``n`` Monte Carlo states now and the ``advance(dt)`` that moves them."""
        X = self.x + rng.standard_normal((n, 2)) @ np.linalg.cholesky(
            self.P + 1e-18 * np.eye(2)).T
        q_y, q_r = self.q_y * np.sqrt(self.scale), self.q_r * np.sqrt(self.scale)
        out = np.exp if self.law == "exponential" else (lambda y: y)

        def advance(dt: float) -> np.ndarray:
            F, Q = transition(dt, q_y, q_r)
            X[:] = X @ F.T + rng.standard_normal(X.shape) @ np.linalg.cholesky(Q).T
            return out(X[:, :1]).copy()

        return out(X[:, :1]).copy(), advance


def crossing_times(filters: list[TrendFilter], d_thr: np.ndarray, rng: np.random.Generator,
                   n: int, step: float) -> np.ndarray:
    """Crossing times (n, m) of every fault's Monte Carlo paths (``inf`` before a filter
    starts)."""
    cross = np.full((n, len(filters)), np.inf)
    for k, f in enumerate(filters):
        if f.started:
            d0, advance = f.paths(rng, n)
            cross[:, k] = first_passage(d0, advance, d_thr[k:k + 1], step)[:, 0]
    return cross


@register_tracker("kalman", description="local-linear-trend Kalman filter per fault over the "
                  "fitted estimates (interval variances; log-damage for a spreading coil "
                  "short), adaptive process noise; RUL by Monte Carlo paths to the thresholds")
def factory(campaign_info: dict, seed: np.random.SeedSequence, *, n_paths: int = N_PATHS,
            first_budget: int = 1500, global_budget: int = 1000,
            replace_prob: float = REPLACE_PROB, conditions: bool = True,
            noise_scale: float = 1.0):
    u = unit_setup(campaign_info, seed, first_budget, global_budget, conditions)
    thresholds, every, names, d_thr, fitter, mc_seed = (u.thresholds, u.every, u.names, u.d_thr,
                                                        u.fitter, u.mc_seed)
    j = [FAULT_INDEX[n] for n in names]
    q_y, q_r = process_noise(names, noise_scale)
    filters = [TrendFilter(growth(n), q_y[k], q_r[k]) for k, n in enumerate(names)]

    def step(insp: Inspection) -> TrackStep:
        fit = fitter(insp)
        d_fit = to_damage(fit.x, names, thresholds)
        s_fit = fit.sd[j] / RANGE[j]
        nis = [f.update(float(insp.flight), float(d), float(s))
               for f, d, s in zip(filters, d_fit, s_fit)]
        cross = crossing_times(filters, d_thr, rng_of(mc_seed, insp.index), n_paths,
                               every / 2)
        summary = summarise(cross, names, REPLACE_HORIZON * every)
        x, low, high = fit.x.copy(), fit.low.copy(), fit.high.copy()
        for k, f in enumerate(filters):
            if f.started:
                d, lo, hi = f.damage()
                v = from_damage(np.array([[d], [lo], [hi]]), [names[k]], thresholds)[:, 0]
                x[j[k]], low[j[k]], high[j[k]] = v[0], v[1:].min(), v[1:].max()
        replace = replace_now(summary, low, high, names, thresholds, replace_prob)
        return make_step(insp, x, low, high, summary, replace, fit.evaluations,
                         fit=fit.how, misfit=round(fit.misfit, 4), p_fail=summary.p_fail,
                         rate={n: float(f.x[1]) for n, f in zip(names, filters) if f.started},
                         nis={n: round(v, 3) for n, v in zip(names, nis) if np.isfinite(v)})

    return step
