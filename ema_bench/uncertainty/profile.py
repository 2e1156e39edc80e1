"""Profile-likelihood intervals: follow the valley, not the tangent.

For parameter ``j`` the profile is the fitness minimised over the other parameters with
``j`` held at each value of a grid, ``f_p(t) = min f(t, others)``.  For a weighted
least-squares fit the quadratic theory gives ``f_p(t) - f = (t - t_hat)^2 / (A^-1)_jj``
(:mod:`~ema_bench.uncertainty.local`), while the sandwich variance of ``t_hat`` is ``V_jj``;
so the scaled drop ``q(t) = (f_p(t) - f) (A^-1)_jj / V_jj`` is asymptotically chi-square
with one degree of freedom, and the interval is ``{t : q(t) <= chi2_1(level)}``.  Near the
estimate the profile interval is the Laplace interval; farther out it follows the real,
curved valley (the paper's Na/Fst one) and stops at the bounds.

Each side is a safeguarded secant search on ``sqrt(q)`` (linear in ``t`` for a quadratic
valley), started at the Laplace end; every profile point is a local refit of the others,
warm started at the previous point plus the linear prediction of how they follow ``t``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .local import Counter, OutOfEvaluations, refit

#: Most evaluations of one profile point's refit of the others.
POINT_EVALS = 60
#: Most profile points per side of an interval.
POINTS_PER_SIDE = 5
#: Accept an end when ``q`` is within this fraction of the threshold.
Q_TOL = 0.1


@dataclass
class Profile:
    """The profile of one parameter, in the unit box.

    ``t``: grid values, ``q``: scaled drop at each (chi-square scale; 0 at the estimate),
    ``low``/``high``: interval ends, ``better``: the lowest fitness a profile refit found,
    where below the fit's (the fit was not at the optimum)."""

    index: int
    t: list[float] = field(default_factory=list)
    q: list[float] = field(default_factory=list)
    low: float = 0.0
    high: float = 1.0
    better: float | None = None


def profile_interval(counter: Counter, u_hat: np.ndarray, f_hat: float, j: int,
                     A: np.ndarray, V: np.ndarray, threshold: float,
                     max_evals: int) -> Profile:
    """Profile interval of unit-box parameter ``j`` around the fit ``u_hat`` (fitness
    ``f_hat``), with the information ``A`` and sandwich covariance ``V`` of the fit,
    ``threshold = chi2_1(level)``; at most ``max_evals`` evaluations (then the Laplace end
    of an unfinished side is kept)."""
    start = counter.evaluations
    dim = u_hat.size
    others = np.arange(dim) != j
    try:
        ainv = np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        ainv = np.full_like(A, np.nan)
    se = float(np.sqrt(V[j, j])) if np.isfinite(V[j, j]) else np.inf
    scale = ainv[j, j] / V[j, j] if np.isfinite(V[j, j]) and V[j, j] > 0 else np.nan
    # how the others follow t along the valley floor (linear theory)
    follow = -np.linalg.lstsq(A[np.ix_(others, others)], A[others, j], rcond=None)[0] \
        if dim > 1 else np.zeros(0)
    prof = Profile(index=j, t=[float(u_hat[j])], q=[0.0])
    cap = start + max_evals
    z = float(np.sqrt(threshold))
    ends = {}
    for side in (-1.0, 1.0):
        bound = 0.0 if side < 0 else 1.0
        room = abs(bound - u_hat[j])
        laplace = min(z * se, room) if np.isfinite(se) and np.isfinite(scale) else room
        ends[side] = u_hat[j] + side * laplace      # kept if nothing better is found
        if room <= 0.0 or not np.isfinite(scale):
            continue
        inner, outer = 0.0, None                    # distances with q below / above threshold
        d = laplace
        warm = u_hat.copy()
        for _ in range(POINTS_PER_SIDE):
            left = cap - counter.evaluations
            if left < 3 * dim:
                break
            u0 = warm.copy()
            u0[j] = u_hat[j] + side * d
            u0[others] = np.clip(warm[others] + follow * (u0[j] - warm[j]), 0.0, 1.0)
            try:
                u, f = refit(counter, u0, others, max_evals=min(POINT_EVALS, left))
            except OutOfEvaluations:
                break
            q = max(f - f_hat, 0.0) * scale
            if f < f_hat and (prof.better is None or f < prof.better):
                prof.better = float(f)
            prof.t.append(float(u0[j]))
            prof.q.append(float(q))
            warm = u
            if q <= threshold:
                inner = d
                if d >= room * (1 - 1e-12):        # the bound is inside the region
                    ends[side] = bound
                    break
            else:
                outer = d
            ends[side] = u_hat[j] + side * (inner if outer is None else
                                            _crossing(inner, outer, prof, side, u_hat[j],
                                                      threshold))
            if abs(q - threshold) <= Q_TOL * threshold:
                ends[side] = u_hat[j] + side * d
                break
            # secant on sqrt(q), which is linear in d for a quadratic valley
            guess = d * z / np.sqrt(q) if q > 0 else 2.0 * d
            lo_d, hi_d = inner, (room if outer is None else outer)
            if not lo_d < guess < hi_d:
                guess = 0.5 * (lo_d + hi_d) if outer is not None else min(2.0 * d, room)
            d = min(guess, room)
    prof.low, prof.high = float(min(ends[-1.0], u_hat[j])), float(max(ends[1.0], u_hat[j]))
    return prof


def _crossing(inner: float, outer: float, prof: Profile, side: float, t_hat: float,
              threshold: float) -> float:
    """Distance where ``sqrt(q)`` crosses ``sqrt(threshold)``, interpolated linearly between
    the profile points at distances ``inner`` (below) and ``outer`` (above)."""
    def q_at(d: float) -> float:
        if d == 0.0:
            return 0.0
        k = int(np.argmin([abs(t - (t_hat + side * d)) for t in prof.t]))
        return prof.q[k]

    a, b = np.sqrt(q_at(inner)), np.sqrt(q_at(outer))
    if b <= a:
        return outer
    return float(inner + (np.sqrt(threshold) - a) * (outer - inner) / (b - a))
