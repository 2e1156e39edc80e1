"""A coil short's onset as a change point in a unit's ``Na`` fits (``fleet-bayes-onset``).

``fleet-bayes`` calls a short present once the fitted shorted share ``s = 1 - Na`` exceeds
three standard deviations, and before that runs the futures as if none had begun: a short
that began a few inspections ago, still within the noise, is for it a future event, and its
growth rate is learned from the inspections after the call only.  Here the onset is a change
point of the whole series of fits (Fearnhead 2006's exact posterior over a single change, on
the campaign's published law):

Hypotheses
    The short began in the interval before inspection ``h`` (``h = 0 .. K``, onset at the
    middle of the interval's logged duty), or has not begun (``h = K + 1``); prior from the
    law's memoryless onset (exponential in flights, mean ``na_onset_mean``); the growth rate
    ``g`` on the fleet-bayes grid, prior the fleet's log-normal.
Likelihood
    Before the onset ``s_k ~ N(0, sd_k^2)``; from it ``s_k ~ N(mu_k, sd_k^2 + mu_k^2 v_k)``,
    ``mu_k = s_0 exp(g (C_k - C_on))`` (``s_0`` the law's initial share, ``C`` the logged duty),
    ``v_k`` the law's growth noise over that duty plus the onset's spread within its interval
    (uniform: ``(g dC / 2)^2 / 3``); each fit is an outlier with probability
    :data:`OUTLIER` (uniform over the fault box's shares, 0-0.2): a fit stuck in a local
    minimum reports ``1 - Na = 0.005`` with a standard deviation of ``1e-4`` (seen on the
    committed twin campaign), which must not start a short on its own.
Futures
    Each path draws ``(h, g)`` from the joint posterior: a path whose short has begun starts
    from its share now (the model's ``mu_K`` and the last fit combined by their precisions),
    a path whose short has not begun starts one at the law's hazard, exactly as
    :class:`~ema_bench.prognostics.laws.ForwardPaths` runs it.
"""

from __future__ import annotations

import numpy as np

#: Probability that a fit is an outlier, and the outlier's density over the shorted share
#: (uniform over the fault box, ``Na`` in 0.8-1).
OUTLIER = 0.05
OUTLIER_DENSITY = 1.0 / 0.2


def _loglik(s: np.ndarray, mu: np.ndarray | float, var: np.ndarray) -> np.ndarray:
    """Log-likelihood of fits ``s`` under ``N(mu, var)`` mixed with the outlier component."""
    normal = np.exp(-0.5 * (s - mu) ** 2 / var) / np.sqrt(2.0 * np.pi * var)
    return np.log((1.0 - OUTLIER) * normal + OUTLIER * OUTLIER_DENSITY)


def onset_posterior(flights: np.ndarray, duty: np.ndarray, s: np.ndarray, sd: np.ndarray,
                    laws: dict, grid: np.ndarray, log_prior: np.ndarray, mean_duty: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint posterior of the onset interval and the growth rate.

    Parameters
    ----------
    flights : (K+1,) inspection flights; duty : (K+1,) logged duty since the previous
        inspection (0 for the first); s, sd : (K+1,) fitted shorted share ``1 - Na`` and its
        standard deviation; laws : the campaign's laws; grid, log_prior : (G,) growth rates
        (per unit duty) and their log prior; mean_duty : the unit's mean duty per flight.

    Returns
    -------
    post : (K+2, G)
        Posterior over (onset hypothesis, growth rate); row ``K+1``: not begun.
    share, share_sd : (K+2, G)
        The shorted share now and its standard deviation under each begun hypothesis.
    """
    f = np.asarray(flights, dtype=float)
    c = np.cumsum(np.asarray(duty, dtype=float))
    s, sd = np.asarray(s, dtype=float), np.maximum(np.asarray(sd, dtype=float), 1e-6)
    k_all = f.size
    s0, mean_on = float(laws["na_initial_short"]), float(laws["na_onset_mean"])
    noise = mean_duty * (1.0 + 1.0 / float(laws["duty_shape"])) / float(laws["na_growth_shape"])
    # prior of each hypothesis: the onset flight's exponential law
    edges = np.concatenate([[0.0], f])
    surv = np.exp(-edges / mean_on)
    p_h = np.concatenate([surv[:-1] - surv[1:], [surv[-1]]])
    # onset duty: the middle of its interval (the first inspection's: there)
    c_prev = np.concatenate([[c[0]], c[:-1]])
    c_on, c_width = 0.5 * (c_prev + c), c - c_prev
    g = grid[None, :]
    ll = np.zeros((k_all + 1, grid.size))
    share = np.zeros((k_all + 1, grid.size))
    share_sd = np.zeros((k_all + 1, grid.size))
    healthy = _loglik(s, 0.0, sd ** 2)   # per inspection, no short
    for h in range(k_all):
        dc = np.maximum(c[h:] - c_on[h], 0.0)[:, None]
        mu = s0 * np.exp(g * dc)
        v = g ** 2 * dc * noise + (g * c_width[h] / 2.0) ** 2 / 3.0
        var = sd[h:, None] ** 2 + mu ** 2 * np.expm1(np.minimum(v, 5.0))
        ll[h] = healthy[:h].sum() + np.sum(_loglik(s[h:, None], mu, var), axis=0)
        # the share now: the model's and the last fit's, by their precisions
        m_now, v_now = mu[-1], var[-1] - sd[-1] ** 2 + 1e-12
        w_fit = v_now / (v_now + sd[-1] ** 2)
        share[h] = w_fit * s[-1] + (1.0 - w_fit) * m_now
        share_sd[h] = np.sqrt(v_now * sd[-1] ** 2 / (v_now + sd[-1] ** 2))
    ll[k_all] = healthy.sum()
    lp = ll + np.log(np.maximum(p_h, 1e-300))[:, None] + log_prior[None, :]
    post = np.exp(lp - lp.max())
    return post / post.sum(), share, share_sd


def onset_paths(rng: np.random.Generator, post: np.ndarray, share: np.ndarray,
                share_sd: np.ndarray, grid: np.ndarray, n: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` paths drawn from :func:`onset_posterior`: whether each path's short has begun,
    its shorted share now (``0`` where not begun) and its growth rate."""
    flat = rng.choice(post.size, size=n, p=post.ravel())
    h, j = np.unravel_index(flat, post.shape)
    begun = h < post.shape[0] - 1
    s_now = share[h, j] + share_sd[h, j] * rng.standard_normal(n)
    s_now = np.where(begun, np.clip(s_now, 1e-4, 1.0), 0.0)
    return begun, s_now, grid[j]
