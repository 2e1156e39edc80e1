"""Which faults can the tests tell apart: correlations, singular values, weakest directions.

Computed from the noise-whitened Jacobian ``S^-1/2 J`` of the fit (unit box): its singular
values say how many noise standard deviations of output a unit step along each principal
direction moves; the smallest ones are the directions the tests barely see.  A parameter is
*practically non-identifiable* when its interval is wider than :data:`IDENTIFIABLE_WIDTH` of
its range: the tests given cannot pin it down, whatever the solver does.
"""

from __future__ import annotations

import numpy as np

#: Interval width (fraction of the parameter's range) above which a parameter counts as
#: practically non-identifiable from the tests given.
IDENTIFIABLE_WIDTH = 0.05
#: Absolute correlation above which two parameters are reported as confounded.
CONFOUNDED = 0.9


def correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance (NaN where a variance is 0 or infinite)."""
    d = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore", invalid="ignore"):
        c = cov / np.outer(d, d)
    c[~np.isfinite(c)] = np.nan
    np.fill_diagonal(c, 1.0)
    return c


def report(J: np.ndarray, sigma_elem: np.ndarray, cov_unit: np.ndarray,
           width_unit: np.ndarray, names: tuple[str, ...], ranges: np.ndarray,
           units: dict[str, str], n_directions: int = 2) -> dict[str, object]:
    """The identifiability report of a fit.

    Parameters
    ----------
    J : array (n_residuals, dim)
        Jacobian of the outputs in the unit box.
    sigma_elem : array (n_residuals,)
        Noise standard deviation of each residual element.
    cov_unit : array (dim, dim)
        Covariance of the estimate in the unit box.
    width_unit : array (dim,)
        Interval widths in the unit box (fractions of each range).
    names, ranges, units
        Parameter names, their ranges (physical) and units.

    Returns
    -------
    dict
        ``correlation`` (name -> name -> r), ``singular_values`` (output standard deviations
        per unit-box step, descending), ``weakest`` (the ``n_directions`` least-seen
        directions: physical step per parameter along a unit-norm unit-box direction and the
        standard deviation along it), ``confounded`` (pairs with ``|r| > CONFOUNDED``),
        ``non_identifiable`` (interval wider than ``IDENTIFIABLE_WIDTH`` of the range).
    """
    Jw = J / sigma_elem[:, None]
    _, s, vt = np.linalg.svd(Jw, full_matrices=False)
    corr = correlation(cov_unit)
    weakest = []
    for k in range(1, min(n_directions, s.size) + 1):
        v = vt[-k] * np.sign(vt[-k][np.argmax(np.abs(vt[-k]))])
        weakest.append({
            "singular_value": float(s[-k]),
            "std_along": float(1.0 / s[-k]) if s[-k] > 0 else float("inf"),
            "direction": {n: float(v[i]) for i, n in enumerate(names)},
            "physical_step": {n: f"{v[i] * ranges[i]:+.3g} {units.get(n, '')}".strip()
                              for i, n in enumerate(names)},
        })
    pairs = [(names[i], names[j], float(corr[i, j])) for i in range(len(names))
             for j in range(i + 1, len(names))
             if np.isfinite(corr[i, j]) and abs(corr[i, j]) > CONFOUNDED]
    return {
        "correlation": {a: {b: (None if not np.isfinite(corr[i, j]) else float(corr[i, j]))
                            for j, b in enumerate(names)} for i, a in enumerate(names)},
        "singular_values": [float(v) for v in s],
        "weakest": weakest,
        "confounded": [{"pair": [a, b], "correlation": r} for a, b, r in pairs],
        "non_identifiable": [n for n, w in zip(names, width_unit)
                             if not np.isfinite(w) or w > IDENTIFIABLE_WIDTH],
    }
