"""Parametric bootstrap: refit the model to its own outputs plus resampled noise.

Each replicate adds fresh white noise of the estimated per-signal level to the fitted
model's outputs and refits all parameters locally from the fit (warm start: the replicate
optimum lies within a few standard errors of it).  The spread of the refits includes what the
Laplace approximation leaves out (curvature, bounds, the kinks of dry friction); the intervals
are the normal ones, ``t_hat +- z sd`` (:func:`normal_interval`).
"""

from __future__ import annotations

import numpy as np

from ..seeding import SeedLike, as_seed_sequence
from .local import Counter, OutOfEvaluations, refit

#: Default number of replicates.
N_BOOT = 50
#: Most evaluations of one replicate's refit.
REFIT_EVALS = 80


def bootstrap_estimates(counter: Counter, u_hat: np.ndarray, y_hat: np.ndarray,
                        sigma: np.ndarray, n_boot: int, seed: SeedLike,
                        max_evals: int) -> np.ndarray:
    """Refit estimates (n_done, dim) in the unit box of up to ``n_boot`` replicates; stops
    early (fewer rows) when ``max_evals`` evaluations are spent."""
    rng = np.random.default_rng(as_seed_sequence(seed))
    s = sigma[counter.objective.signal_index]
    cap = counter.evaluations + max_evals
    out = []
    base_data = counter.data
    try:
        for _ in range(n_boot):
            left = cap - counter.evaluations
            if left < 3 * u_hat.size:
                break
            counter.data = y_hat + rng.normal(0.0, 1.0, y_hat.size) * s
            try:
                u, _ = refit(counter, u_hat, max_evals=min(REFIT_EVALS, left))
            except OutOfEvaluations:
                break
            out.append(u)
    finally:
        counter.data = base_data
    return np.array(out).reshape(-1, u_hat.size)


def normal_interval(u_hat: np.ndarray, boot: np.ndarray, level: float) -> tuple[np.ndarray,
                                                                                 np.ndarray]:
    """Normal bootstrap interval in the unit box, ``t_hat +- z sd``, with ``sd`` the spread
    of the refits around their mean (with tens of replicates the 2.5 % quantiles themselves
    would rest on one or two refits)."""
    from scipy.stats import norm

    half = norm.ppf(0.5 + 0.5 * level) * boot.std(axis=0, ddof=1)
    return u_hat - half, u_hat + half
