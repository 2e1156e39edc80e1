"""Expected hits: score the forecast, not the draw of the futures.

Whether a point RUL lands within +-20 % of the true RUL at the cut depends on the forecast
and on how the unit's future happened to unfold (a backlash jump, a coil short's onset, the
duty of the flights): the realised hit rate of 170 units carries the luck of their 170
futures, shared by every tracker and the oracle.  The *expected* hit of a unit removes that
luck: the probability that the point lies within ``+-alpha`` of the RUL under the unit's
futures drawn from its **true state** at the cut with its **true law parameters** (the
oracle's machinery, :func:`~ema_bench.prognostics.oracle.unit_futures`, weighed by the
published cut rule), averaged over the failing units::

    E_hit(u) = sum_i w_i 1[(1 - alpha) R_i <= point_u <= (1 + alpha) R_i] / sum_i w_i

The tracker's and the oracle's points are judged on the **same** futures (a paired figure),
drawn from a seed of their own (:data:`FUTURES_SEED`), independent of the futures the
oracle chose its point on: judged on those, the oracle's point would score its in-sample
optimum.  A unit without a prediction at its cut scores 0.

What it rewards: a point where the unit's true future is likely to end.  Knowing the realised
RUL is worth nothing more than the oracle's point (a run that writes the true RULs scores
100 % realised, and about what the oracle scores expected: ``tests/test_prognostics_expected.py``).
"""

from __future__ import annotations

import math

import numpy as np

from .oracle import N_PATHS, failing_units, unit_futures

#: Root seed of the futures the points are judged on (the oracle chooses its point on the
#: futures of seed 0, :func:`~ema_bench.prognostics.oracle.oracle_predictions`).
FUTURES_SEED = 1


def hit_probability(point: float, rul: np.ndarray, weights: np.ndarray,
                    alpha: float = 0.2) -> float:
    """Weighted share of futures ``rul`` (flights) for which ``point`` (flights) lies within
    ``[(1 - alpha) R, (1 + alpha) R]``, bounds included; 0 for an infinite or NaN point."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")
    r, w = np.asarray(rul, dtype=float), np.asarray(weights, dtype=float)
    if r.shape != w.shape or not r.size or w.sum() <= 0:
        raise ValueError("futures and weights must be non-empty, of one length, weights > 0")
    if not math.isfinite(point):
        return 0.0
    with np.errstate(invalid="ignore"):
        hit = ((1.0 - alpha) * r <= point) & (point <= (1.0 + alpha) * r)
    return float(np.sum(w * hit) / np.sum(w))


def campaign_futures(truth: dict[str, dict], laws: dict, thresholds: dict[str, float],
                     every: int, cut_rule: dict, n_paths: int = N_PATHS,
                     seed: int = FUTURES_SEED) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every failing unit's futures from its true state at its cut (unit -> (RUL samples,
    cut-rule weights)); unit ``k`` of the sorted truth gets child ``k`` of ``seed``, so a
    unit's futures do not depend on which other units are scored (about 0.3 s per unit at
    4,000 paths)."""
    stop = tuple(cut_rule.get("stop", (0.5, 0.95)))
    return {unit: unit_futures(t, laws, thresholds, every, stop, rng, n_paths)[:2]
            for unit, t, rng in failing_units(truth, seed)}


def expected_hits(rows: list[dict], futures: dict[str, tuple[np.ndarray, np.ndarray]],
                  alpha: float = 0.2) -> np.ndarray:
    """Per row (``unit``, ``rul``: a tracker's or the oracle's point at the cut) its
    expected hit under the unit's futures."""
    return np.array([hit_probability(float(r["rul"]), *futures[r["unit"]], alpha=alpha)
                     for r in rows], dtype=float)


def at_most(p: np.ndarray, k: int) -> float:
    """P(at most ``k`` hits) when unit ``i`` hits with probability ``p[i]`` independently
    (the Poisson-binomial distribution, by exact convolution): how unusual a realised hit
    count is under the units' futures."""
    dist = np.array([1.0])
    for pi in np.asarray(p, dtype=float):
        dist = np.convolve(dist, [1.0 - pi, pi])
    return float(dist[:int(k) + 1].sum())
