"""Bayes point and interval of a remaining useful life from weighted samples, and the fleet's
life distribution from its published laws.

What the oracle (:func:`~ema_bench.prognostics.oracle.oracle_predictions`) and the no-sensing
``life-table`` reference tracker share: both weigh samples of the remaining life by the
campaign's cut rule (:func:`~ema_bench.prognostics.campaign.cut_likelihood`) and answer the
point that maximises the probability of lying within ``+-alpha`` of the truth, the headline's
criterion, with the weighted 2.5-97.5 % interval.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache

import numpy as np

from ..seeding import child
from .laws import FleetLaws, unit_history


def _weights(samples: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(samples, dtype=float).ravel()
    w = np.ones(r.size) if weights is None else np.asarray(weights, dtype=float).ravel()
    if r.size == 0 or r.shape != w.shape or np.isnan(r).any() or (w < 0).any() \
            or not np.isfinite(w).all():
        raise ValueError("samples and weights must be non-empty, of one length, not NaN, "
                         "weights finite and >= 0")
    if w.sum() <= 0:
        raise ValueError("weights sum to 0: no sample is compatible with the evidence")
    return r, w / w.sum()


def best_point(samples: np.ndarray, weights: np.ndarray | None = None,
               alpha: float = 0.2) -> float:
    """The RUL ``r`` (flights) maximising ``P((1 - alpha) R <= r <= (1 + alpha) R)`` under the
    weighted samples ``R``.

    A sample ``R`` counts for ``r`` when ``r / (1 + alpha) <= R <= r / (1 - alpha)``; the
    maximum is attained at some ``(1 - alpha) R_i``, which are all tried (ties: the smallest
    ``r``).  Infinite samples count for no finite ``r``; when every sample is infinite the
    answer is ``inf``.
    """
    r, w = _weights(samples, weights)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")
    fin = np.isfinite(r)
    if not fin.any():
        return math.inf
    order = np.argsort(r[fin], kind="stable")
    rs, cw = r[fin][order], np.concatenate([[0.0], np.cumsum(w[fin][order])])
    cand = (1.0 - alpha) * rs
    lo = np.searchsorted(rs, cand / (1.0 + alpha), side="left")
    hi = np.searchsorted(rs, cand / (1.0 - alpha) * (1 + 1e-12), side="right")
    mass = cw[hi] - cw[lo]
    return float(cand[int(np.argmax(mass))])


def weighted_quantile(samples: np.ndarray, weights: np.ndarray | None,
                      q: float | np.ndarray) -> np.ndarray:
    """Quantiles ``q`` of weighted samples (inverse of the weighted CDF, no interpolation:
    the smallest sample whose cumulative weight reaches ``q``); ``inf`` samples allowed."""
    r, w = _weights(samples, weights)
    order = np.argsort(r, kind="stable")
    c = np.cumsum(w[order])
    k = np.searchsorted(c, np.asarray(q, dtype=float) * (1 - 1e-12), side="left")
    return r[order][np.minimum(k, r.size - 1)]


#: Units drawn for the fleet's life distribution (about 3.5 ms each), and their root seed.
FLEET_SAMPLE = 2000
FLEET_SEED = 20260


@lru_cache(maxsize=4)
def _lives(laws_json: str, n: int, seed: int) -> np.ndarray:
    laws = FleetLaws(**{k: tuple(v) if isinstance(v, list) else v
                        for k, v in json.loads(laws_json).items()
                        if k in FleetLaws.__dataclass_fields__})
    root = np.random.SeedSequence(seed)
    eols = [unit_history(child(root, i), laws).eol for i in range(n)]
    return np.array([math.inf if e is None else float(e) for e in eols])


def fleet_lives(laws: dict, n: int = FLEET_SAMPLE, seed: int = FLEET_SEED) -> np.ndarray:
    """End-of-life flights of ``n`` wearing units drawn from the published ``laws`` (a
    manifest's ``laws``): the fleet's life distribution as an operator knows it from the laws
    alone (``inf``: no failure within ``max_flights``).  Cached per process."""
    return _lives(json.dumps(laws, sort_keys=True), int(n), int(seed)).copy()
