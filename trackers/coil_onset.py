"""A coil short's onset as a change point in a unit's ``Na`` fits (``fleet-bayes-onset``).

``fleet-bayes`` calls a short present once the fitted shorted share ``s = 1 - Na`` exceeds
three standard deviations, and before that runs the futures as if none had begun: a short
that began a few inspections ago, still within the noise, is for it a future event, and its
growth rate is learned from the inspections after the call only.  Here the onset is a change
point of the whole series of fits (Fearnhead 2006's exact posterior over a single change, on
the campaign's published law):

Hypotheses
    The short began in the interval before inspection ``h`` (``h = 0 .. K``), at one of
    :data:`N_POSITIONS` equally spaced points of the interval's logged duty (a uniform onset
    within the interval, integrated by the midpoint rule; the first inspection's: at it), or
    has not begun (``h = K + 1``); prior from the law's memoryless onset (exponential in
    flights, mean ``na_onset_mean``); the growth rate ``g`` on the fleet-bayes grid, prior
    the fleet's log-normal.
Likelihood
    Before the onset ``s_k ~ N(0, sd_k^2)``.  From it the law itself, as a state-space model:
    the log share ``l = log s`` starts at ``log s_0`` (``s_0`` the law's initial share) and is
    a random walk with drift over the logged duty ``C``, ``l_k = l_{k-1} + g dC_k + w_k``,
    ``var w_k = g^2 dC_k m (1 + 1/k_d) / k_e`` (the flights' gamma growth noise and duty,
    ``m`` the unit's mean duty per flight), observed as ``s_k ~ N(exp(l_k), sd_k^2)``: an
    extended Kalman filter per hypothesis gives the exact sequential likelihood of the
    linearised model.  The growth noise is a random walk, so the fits' deviations from the
    mean curve are correlated: the previous version of this module scored each fit
    independently around the curve (and the onset's spread within its interval as noise of
    every fit), which overweighted early fits and misread a slow stretch of the walk as a
    slower rate.  Each fit is an outlier with probability :data:`OUTLIER` (uniform over the
    fault box's shares, 0-0.2; a fit more likely an outlier than not does not update the
    filter): a fit stuck in a local minimum reports ``1 - Na = 0.005`` with a standard
    deviation of ``1e-4`` (seen on the committed twin campaign), which must not start a short
    on its own.
Futures
    Each path draws a hypothesis ``(h, position, g)`` from the joint posterior: a path whose
    short has begun starts from the filter's log share now (mean and variance), a path whose
    short has not begun starts one at the law's hazard, exactly as
    :class:`~ema_bench.prognostics.laws.ForwardPaths` runs it.
"""

from __future__ import annotations

import numpy as np

#: Probability that a fit is an outlier, and the outlier's density over the shorted share
#: (uniform over the fault box, ``Na`` in 0.8-1).
OUTLIER = 0.05
OUTLIER_DENSITY = 1.0 / 0.2
#: Onset positions within an interval (midpoint rule over its logged duty).
N_POSITIONS = 8


def _mix(log_normal: np.ndarray) -> np.ndarray:
    """Log-likelihood of a fit: its normal log-density mixed with the outlier component."""
    return np.log((1.0 - OUTLIER) * np.exp(log_normal) + OUTLIER * OUTLIER_DENSITY)


def _normal(x: np.ndarray | float, mean: np.ndarray | float, var: np.ndarray) -> np.ndarray:
    return -0.5 * (x - mean) ** 2 / var - 0.5 * np.log(2.0 * np.pi * var)


def onset_posterior(flights: np.ndarray, duty: np.ndarray, s: np.ndarray, sd: np.ndarray,
                    laws: dict, grid: np.ndarray, log_prior: np.ndarray, mean_duty: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint posterior of the onset (interval and position in it) and the growth rate.

    Parameters
    ----------
    flights : (K+1,) inspection flights; duty : (K+1,) logged duty since the previous
        inspection (0 for the first); s, sd : (K+1,) fitted shorted share ``1 - Na`` and its
        standard deviation; laws : the campaign's laws; grid, log_prior : (G,) growth rates
        (per unit duty) and their log prior; mean_duty : the unit's mean duty per flight.

    Returns
    -------
    post : (K+2, N_POSITIONS, G)
        Posterior over (onset interval, position in it, growth rate); row ``K+1``: not begun
        (its mass spread evenly over the positions); ``post.sum(axis=(1, 2))`` is the
        posterior of the onset interval.
    log_share, log_sd : (K+2, N_POSITIONS, G)
        The log shorted share now, its mean and standard deviation, under each begun
        hypothesis (the filter's last state).
    """
    f = np.asarray(flights, dtype=float)
    c = np.cumsum(np.asarray(duty, dtype=float))
    s, sd = np.asarray(s, dtype=float), np.maximum(np.asarray(sd, dtype=float), 1e-6)
    k_all, n_u = f.size, N_POSITIONS
    s0, mean_on = float(laws["na_initial_short"]), float(laws["na_onset_mean"])
    q = grid[None, :] ** 2 * (mean_duty * (1.0 + 1.0 / float(laws["duty_shape"]))
                              / float(laws["na_growth_shape"]))   # walk variance per duty
    g = grid[None, :]
    # prior of each interval: the onset flight's exponential law
    edges = np.concatenate([[0.0], f])
    surv = np.exp(-edges / mean_on)
    p_h = np.concatenate([surv[:-1] - surv[1:], [surv[-1]]])
    # duty from each onset position to the interval's end (the first inspection's: none)
    width = np.diff(c, prepend=c[0])
    left = (1.0 - (np.arange(n_u) + 0.5) / n_u)[:, None]
    shape = (k_all + 1, n_u, grid.size)
    ll, mean, var = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    healthy = _mix(_normal(s, 0.0, sd ** 2))   # per inspection, no short
    keep_above = np.log(OUTLIER * OUTLIER_DENSITY / (1.0 - OUTLIER))
    for h in range(k_all):
        dc = width[h] * left                              # (n_u, 1)
        m, P = np.log(s0) + g * dc, q * dc                # (n_u, G)
        total = np.full(m.shape, healthy[:h].sum())
        for k in range(h, k_all):
            if k > h:
                m, P = m + g * (c[k] - c[k - 1]), P + q * (c[k] - c[k - 1])
            e = np.exp(m)                                 # the share predicted = its slope
            S = e ** 2 * P + sd[k] ** 2
            logn = _normal(s[k], e, S)
            total += _mix(logn)
            keep = logn >= keep_above                     # an outlier does not update
            gain = np.where(keep, P * e / S, 0.0)
            m, P = m + gain * (s[k] - e), P - gain * e * P
        ll[h], mean[h], var[h] = total, m, P
    ll[k_all] = healthy.sum()
    log_p = np.log(np.maximum(p_h, 1e-300) / n_u)
    lp = ll + log_p[:, None, None] + log_prior[None, None, :]
    post = np.exp(lp - lp.max())
    return post / post.sum(), mean, np.sqrt(np.maximum(var, 0.0))


def onset_paths(rng: np.random.Generator, post: np.ndarray, log_share: np.ndarray,
                log_sd: np.ndarray, grid: np.ndarray, n: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` paths drawn from :func:`onset_posterior`: whether each path's short has begun,
    its shorted share now (``0`` where not begun) and its growth rate."""
    flat = rng.choice(post.size, size=n, p=post.ravel())
    h, a, j = np.unravel_index(flat, post.shape)
    begun = h < post.shape[0] - 1
    s_now = np.exp(log_share[h, a, j] + log_sd[h, a, j] * rng.standard_normal(n))
    s_now = np.where(begun, np.clip(s_now, 1e-4, 1.0), 0.0)
    return begun, s_now, grid[j]
