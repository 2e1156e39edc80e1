"""Scoring a predictive distribution of the RUL, not only its point.

A tracker may give quantiles of the RUL (``TrackStep.rul_quantiles``: level -> flights, at
the levels of :data:`LEVELS`); the oracle always does.  At each failing unit's cut the board
scores:

- ``interval score`` of the central 50, 80 and 95 % intervals (Gneiting and Raftery 2007,
  eq. 43): ``IS_a(l, u; y) = (u - l) + (2 / a) (l - y)+ + (2 / a) (y - u)+`` with
  ``a = 1 - level`` (flights; lower is better: width plus a penalty for a miss that grows as
  the nominal level does);
- ``coverage`` of each of those intervals;
- ``crps``: the continuous ranked probability score, approximated by the weighted interval
  score of the median and the three central intervals (Bracher et al. 2021, PLoS Comput Biol
  17(2) e1008618): ``WIS = (|y - m| / 2 + sum_k (a_k / 2) IS_{a_k}) / (K + 1/2)``, ``K = 3``
  (flights; it tends to the CRPS as the levels grow dense, and ranks forecasts as it does).

A tracker that gives only its 95 % interval (``rul_low``, ``rul_high``) is scored on what it
gives: its 95 % interval score and coverage; its 50 and 80 % figures and its CRPS are not
scored (``nan``, ``-`` on the board).  Bounds are clipped to ``[0, H]``, the horizon the point
errors use (:data:`~ema_bench.prognostics.scoring.HORIZON_INSPECTIONS`): an interval reaching
past it says "not within the horizon" and costs its width up to ``H``.  A unit without a
prediction at its cut is an infinite miss, as on the rest of the board.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

#: Quantile levels of a predictive distribution: the median and the central 50, 80, 95 %.
LEVELS = (0.025, 0.1, 0.25, 0.5, 0.75, 0.9, 0.975)
#: Central interval levels scored, and the quantile levels of their ends.
INTERVALS = {0.5: (0.25, 0.75), 0.8: (0.1, 0.9), 0.95: (0.025, 0.975)}


def level_key(q: float) -> str:
    """The JSON key of quantile level ``q`` (``0.025`` -> ``"0.025"``)."""
    return f"{float(q):g}"


def check_quantiles(quantiles: Mapping) -> dict[str, float]:
    """``quantiles`` (level -> RUL, flights) as plain floats if sound: levels in (0, 1),
    values not NaN, >= 0 and non-decreasing in the level; ValueError naming the fault."""
    try:
        items = sorted((float(k), float(v)) for k, v in quantiles.items())
    except (TypeError, ValueError):
        raise ValueError(f"RUL quantiles must map levels to numbers, got {quantiles!r}") \
            from None
    if any(not 0.0 < q < 1.0 for q, _ in items):
        raise ValueError(f"RUL quantile levels must lie in (0, 1), got {[q for q, _ in items]}")
    vals = [v for _, v in items]
    if any(math.isnan(v) or v < 0 for v in vals) or any(b < a for a, b in zip(vals, vals[1:])):
        raise ValueError(f"RUL quantiles must be >= 0 and non-decreasing in the level, got "
                         f"{dict(items)}")
    return {level_key(q): v for q, v in items}


def interval_score(low: np.ndarray, high: np.ndarray, true: np.ndarray,
                   level: float) -> np.ndarray:
    """Interval score of central ``level`` intervals (Gneiting and Raftery 2007), flights.

    ``(u - l) + (2 / a) max(l - y, 0) + (2 / a) max(y - u, 0)``, ``a = 1 - level``;
    elementwise, infinite bounds give ``inf``."""
    a = 1.0 - float(level)
    lo, hi, y = (np.asarray(v, dtype=float) for v in (low, high, true))
    with np.errstate(invalid="ignore"):
        return (hi - lo) + 2.0 / a * np.maximum(lo - y, 0.0) + 2.0 / a * np.maximum(y - hi, 0.0)


def weighted_interval_score(median: np.ndarray, bounds: Mapping[float, tuple],
                            true: np.ndarray) -> np.ndarray:
    """The weighted interval score (Bracher et al. 2021) of a median and central intervals
    ``bounds`` (level -> (low, high) arrays), flights: the quantile approximation of the
    CRPS (module docstring)."""
    y = np.asarray(true, dtype=float)
    total = 0.5 * np.abs(np.asarray(median, dtype=float) - y)
    for level, (lo, hi) in bounds.items():
        total = total + (1.0 - level) / 2.0 * interval_score(lo, hi, y, level)
    return total / (len(bounds) + 0.5)


def columns(units: list[dict], horizon: float) -> dict[str, np.ndarray]:
    """Per failing unit the distribution terms the board averages: ``is50``, ``is80``,
    ``is95`` (interval scores), ``cov50``, ``cov80`` (coverage; ``cov95`` is the headline's
    ``covered``) and ``crps``; ``nan`` where the unit's prediction has no such quantiles.

    ``units``: rows with ``true_rul``, ``rul_low``, ``rul_high`` and, when given,
    ``quantiles`` (level key -> flights); a row with ``at_cut`` false is a unit without a
    prediction at its cut (every term infinite, not covered)."""
    n = len(units)
    true = np.array([u["true_rul"] for u in units], dtype=float)
    missing = np.array([not u.get("at_cut", True) for u in units], dtype=bool)

    def q(level: float) -> np.ndarray:
        key = level_key(level)
        return np.array([(u.get("quantiles") or {}).get(key, math.nan) for u in units],
                        dtype=float)

    def clip(v: np.ndarray) -> np.ndarray:
        return np.clip(v, 0.0, horizon)

    bounds = {lev: (clip(q(a)), clip(q(b))) for lev, (a, b) in INTERVALS.items()}
    # the 95 % interval every tracker gives
    bounds[0.95] = (clip(np.array([u["rul_low"] for u in units], dtype=float)),
                    clip(np.array([u["rul_high"] for u in units], dtype=float)))
    out: dict[str, np.ndarray] = {}
    for lev, (lo, hi) in bounds.items():
        pct = int(round(100 * lev))
        out[f"is{pct}"] = interval_score(lo, hi, true, lev)
        if pct != 95:
            cov = ((lo <= true) & (true <= hi)).astype(float)
            out[f"cov{pct}"] = np.where(np.isnan(lo) | np.isnan(hi), math.nan, cov)
    out["crps"] = weighted_interval_score(clip(q(0.5)), bounds, true)
    for k in out:   # a unit without a prediction at its cut: an infinite miss
        out[k] = np.where(missing, 0.0 if k.startswith("cov") else math.inf, out[k]) \
            if n else out[k]
    return out


def reliability(units: list[dict]) -> dict[str, float]:
    """Observed coverage of each central interval level a run gives (level key -> share of
    failing units whose interval holds the true RUL; levels not given are left out): the
    points of a reliability diagram, nominal against observed."""
    true = np.array([u["true_rul"] for u in units], dtype=float)
    out = {}
    for lev, (a, b) in INTERVALS.items():
        if lev == 0.95:
            lo = np.array([u["rul_low"] for u in units], dtype=float)
            hi = np.array([u["rul_high"] for u in units], dtype=float)
        else:
            qs = [u.get("quantiles") or {} for u in units]
            if not units or any(level_key(a) not in q or level_key(b) not in q for q in qs):
                continue
            lo = np.array([q[level_key(a)] for q in qs], dtype=float)
            hi = np.array([q[level_key(b)] for q in qs], dtype=float)
        if units:
            out[level_key(lev)] = float(np.mean((lo <= true) & (true <= hi)))
    return out
