"""Prognostics metrics: pure functions of predictions and the truth.

Time is in flights; remaining useful life (RUL) in flights; a prediction error is
``d = predicted - true`` (late, optimistic predictions have ``d > 0``).  Every function checks
its inputs and raises ``ValueError`` with a one-line reason (empty, NaN, mismatched lengths).

Sources:

- PHM08 score: Saxena, Goebel, Simon, Eklund, "Damage propagation modeling for aircraft engine
  run-to-failure simulation", PHM 2008 (the C-MAPSS challenge's scoring function).
- alpha-lambda accuracy and prognostic horizon: Saxena, Celaya, Saha, Saha, Goebel, "Metrics
  for offline evaluation of prognostic performance", IJPHM 1 (2010).
- monotonicity: Coble and Hines, "Identifying optimal prognostic parameters from data: a
  genetic algorithms approach", PHM 2009.

NASA's progpy (``progpy.metrics``, 1.9; the optional extra ``prognostics``, never a
dependency) implements alpha-lambda, prognostic horizon and monotonicity on a
``ToEPredictionProfile`` (one ``UncertainData`` distribution of the time of event per
prediction time).  Ours work on the median RUL and its 95 % interval per inspection, which is
what a tracker reports.  Where they differ:

- alpha-lambda: progpy asks that a share ``beta`` of the distribution lie *strictly* inside
  the cone; ours that the median lie inside it, bounds included (the interval is judged on its
  own by :func:`coverage`).  For point predictions off the bounds the two agree
  (``tests/test_prognostics_metrics.py`` checks it when progpy is importable).  progpy takes
  ``t_lambda`` as an absolute time; ours is ``lambda`` of the way from the first prediction
  to EOL (:func:`lambda_flight`), as in Saxena et al.
- prognostic horizon: :func:`prognostic_horizon` counts from the *first* prediction inside the
  bounds, as Saxena et al. and progpy; :func:`prognostic_horizon_strict` from the first after
  which every prediction stays inside (so one lucky early prediction cannot earn a long
  horizon).  The two agree on profiles that never leave the bounds once inside.
- monotonicity: progpy's is of the mean time-to-event, ours of whatever series is given (the
  scoring passes the median RUL, and separately the failing fault's estimate); same formula.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

ArrayLike = Sequence[float] | np.ndarray

#: Which prediction alpha-lambda judges: the first at or after ``t_lambda`` ("after", progpy's
#: convention) or the last at or before it ("before": the prediction in force at ``t_lambda``).
SIDES = ("after", "before")


# --- input checks ----------------------------------------------------------------------------

def _vector(x: ArrayLike, what: str, *, allow_inf: bool = True) -> np.ndarray:
    v = np.asarray(x, dtype=float)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"{what}: expected a non-empty 1-D sequence, got shape {v.shape}")
    if np.isnan(v).any():
        raise ValueError(f"{what}: NaN at position {int(np.flatnonzero(np.isnan(v))[0])}")
    if not allow_inf and not np.isfinite(v).all():
        raise ValueError(f"{what}: must be finite")
    return v


def _pair(pred: ArrayLike, true: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    p = _vector(pred, "predicted RUL")
    t = _vector(true, "true RUL", allow_inf=False)
    if p.shape != t.shape:
        raise ValueError(f"predicted and true RUL must be of one length, got {p.size} and "
                         f"{t.size}")
    return p, t


def _profile(flights: ArrayLike, pred: ArrayLike, eol: float) -> tuple[np.ndarray, np.ndarray]:
    """One unit's prediction profile: flights strictly increasing and before ``eol``."""
    f = _vector(flights, "flights", allow_inf=False)
    p = _vector(pred, "predicted RUL")
    if p.shape != f.shape:
        raise ValueError(f"flights and predictions must be of one length, got {f.size} and "
                         f"{p.size}")
    if f.size > 1 and not (np.diff(f) > 0).all():
        raise ValueError("flights must be strictly increasing")
    if not math.isfinite(eol) or eol <= f[-1]:
        raise ValueError(f"EOL must be finite and after the last prediction (flight "
                         f"{f[-1]:g}), got {eol!r}")
    return f, p


def _check_alpha(alpha: float) -> None:
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must lie in (0, 1), got {alpha!r}")


# --- errors of final predictions -------------------------------------------------------------

def rmse(pred: ArrayLike, true: ArrayLike) -> float:
    """Root-mean-square RUL error.

    ``sqrt(mean((pred - true)^2))``.

    Parameters
    ----------
    pred, true : sequence of float
        Predicted and true RUL, flights (one per unit); ``pred`` may be inf (then so is the
        result), ``true`` must be finite.

    Returns
    -------
    float
        Flights.
    """
    p, t = _pair(pred, true)
    return float(np.sqrt(np.mean((p - t) ** 2)))


def mae(pred: ArrayLike, true: ArrayLike) -> float:
    """Mean absolute RUL error ``mean(|pred - true|)``, flights (inputs as :func:`rmse`)."""
    p, t = _pair(pred, true)
    return float(np.mean(np.abs(p - t)))


def phm08_terms(pred: ArrayLike, true: ArrayLike) -> np.ndarray:
    """Per-prediction terms of the PHM08 challenge score (Saxena et al. 2008), dimensionless.

    ``s_i = exp(-d_i / 13) - 1`` when ``d_i = pred_i - true_i < 0`` (early), ``exp(d_i / 10)
    - 1`` when ``d_i >= 0`` (late): a late prediction costs more than an early one of the same
    size; >= 0, 0 is perfect, inf for an infinite late prediction.  The challenge summed
    them; the board takes their mean (:func:`phm08_mean`) and median per unit.

    Parameters
    ----------
    pred, true : sequence of float
        Predicted and true RUL, flights (the challenge's cycles); as :func:`rmse`.
    """
    p, t = _pair(pred, true)
    d = p - t
    with np.errstate(over="ignore"):  # an absurdly late prediction scores inf, not a warning
        return np.where(d < 0, np.expm1(-d / 13.0), np.expm1(d / 10.0))


def within_share(pred: ArrayLike, true: ArrayLike, alpha: float = 0.2) -> float:
    """Share of predictions within ``+- alpha`` of the truth:
    ``mean((1 - alpha) true <= pred <= (1 + alpha) true)`` (bounds included; the headline's
    accuracy at the cut).

    Parameters
    ----------
    pred, true : sequence of float
        Predicted (inf allowed: a miss) and true RUL, flights.
    alpha : float
        Relative half-width, in (0, 1).

    Returns
    -------
    float
        In [0, 1].
    """
    p, t = _pair(pred, true)
    _check_alpha(alpha)
    return float(np.mean(((1.0 - alpha) * t <= p) & (p <= (1.0 + alpha) * t)))


def clip_rul(pred: ArrayLike, horizon: float) -> np.ndarray:
    """Predicted RULs clipped to ``[0, horizon]`` flights (an infinite or longer prediction
    says "not within the horizon"); ``horizon`` finite and > 0."""
    if not (math.isfinite(horizon) and horizon > 0):
        raise ValueError(f"horizon must be finite and > 0, got {horizon!r}")
    return np.clip(_vector(pred, "predicted RUL"), 0.0, horizon)


def phm08_mean(pred: ArrayLike, true: ArrayLike, horizon: float) -> float:
    """The PHM08 score per unit: ``mean_i s_i`` of :func:`phm08_terms` with the predictions
    clipped to ``[0, horizon]`` flights (:func:`clip_rul`), so one infinite prediction does not
    make the score infinite (dimensionless, >= 0; 0 is perfect)."""
    return float(np.mean(phm08_terms(clip_rul(pred, horizon), true)))


# --- accuracy over a unit's life -------------------------------------------------------------

def within_alpha(pred: float, true: float, alpha: float) -> bool:
    """Whether ``(1 - alpha) true <= pred <= (1 + alpha) true`` (bounds included).

    Parameters
    ----------
    pred, true : float
        Predicted and true RUL, flights.
    alpha : float
        Relative half-width of the cone, in (0, 1).
    """
    _check_alpha(alpha)
    if math.isnan(pred) or not math.isfinite(true):
        raise ValueError(f"pred must not be NaN and true must be finite, got {pred!r}, {true!r}")
    return bool((1.0 - alpha) * true <= pred <= (1.0 + alpha) * true)


def lambda_flight(start: float, eol: float, lam: float) -> float:
    """The time at which alpha-lambda accuracy is judged (Saxena et al. 2010).

    ``t_lambda = t_start + lambda (EOL - t_start)``.

    Parameters
    ----------
    start : float
        ``t_start``, the flight of the first prediction.
    eol : float
        True end of life, flight.
    lam : float
        ``lambda``, the share of the predicted part of life, in [0, 1].

    Returns
    -------
    float
        Flight.
    """
    if not 0.0 <= lam <= 1.0:
        raise ValueError(f"lambda must lie in [0, 1], got {lam!r}")
    return start + lam * (eol - start)


def prediction_at(flights: ArrayLike, t: float, side: str = "after") -> int | None:
    """Index of the prediction judged at time ``t``.

    Parameters
    ----------
    flights : sequence of float
        Flights of the predictions, increasing.
    t : float
        Flight.
    side : {"after", "before"}
        "after": the first prediction made at or after ``t`` (progpy's convention);
        "before": the last made at or before ``t`` (the one in force at ``t``).

    Returns
    -------
    int or None
        None when there is no such prediction.
    """
    if side not in SIDES:
        raise ValueError(f"side must be one of {SIDES}, got {side!r}")
    f = _vector(flights, "flights", allow_inf=False)
    idx = np.flatnonzero(f >= t) if side == "after" else np.flatnonzero(f <= t)
    if not idx.size:
        return None
    return int(idx[0] if side == "after" else idx[-1])


def alpha_lambda(flights: ArrayLike, pred: ArrayLike, eol: float, alpha: float = 0.2,
                 lam: float = 0.5, side: str = "after") -> bool | None:
    """Alpha-lambda accuracy of one unit (Saxena et al. 2010).

    The prediction judged at ``t_lambda`` (:func:`lambda_flight` with ``t_start`` the first
    prediction's flight; which one: :func:`prediction_at`) must lie in
    ``[(1 - alpha) r*, (1 + alpha) r*]``, ``r* = EOL - t`` the true RUL at that prediction's
    own flight ``t``.

    Parameters
    ----------
    flights : sequence of float
        Flights of the unit's predictions, strictly increasing, before ``eol``.
    pred : sequence of float
        Median predicted RUL at each, flights (inf allowed: outside any cone).
    eol : float
        True end of life, flight.
    alpha, lam : float
        Cone half-width (relative) and share of life.
    side : {"after", "before"}
        See :func:`prediction_at`.

    Returns
    -------
    bool or None
        None when no prediction qualifies (tracking stopped before ``t_lambda``).
    """
    f, p = _profile(flights, pred, eol)
    _check_alpha(alpha)
    i = prediction_at(f, lambda_flight(float(f[0]), eol, lam), side)
    return None if i is None else within_alpha(float(p[i]), eol - float(f[i]), alpha)


def prognostic_horizon(flights: ArrayLike, pred: ArrayLike, eol: float,
                       alpha: float = 0.1) -> float:
    """Prognostic horizon of one unit, Saxena et al. (2010) and progpy's definition.

    ``PH = EOL - t_i``, ``t_i`` the first prediction flight at which the prediction lies
    within ``r* +- alpha EOL`` (fixed-width bounds around the true RUL ``r* = EOL - t``,
    bounds included), whatever the later predictions do (first entry).

    Parameters
    ----------
    flights, pred, eol
        As :func:`alpha_lambda`.
    alpha : float
        Half-width of the bounds as a share of EOL, in (0, 1).

    Returns
    -------
    float
        Flights; 0 when no prediction enters the bounds.

    See Also
    --------
    prognostic_horizon_strict : from the first prediction after which every one stays inside.
    """
    f, p = _profile(flights, pred, eol)
    _check_alpha(alpha)
    inside = np.abs(p - (eol - f)) <= alpha * eol
    return float(eol - f[int(np.argmax(inside))]) if inside.any() else 0.0


def prognostic_horizon_strict(flights: ArrayLike, pred: ArrayLike, eol: float,
                              alpha: float = 0.1) -> float:
    """The strict prognostic horizon: ``EOL - t_i``, ``t_i`` the first prediction flight from
    which *every* prediction stays within ``r* +- alpha EOL`` (bounds included), so one lucky
    early prediction cannot earn a long horizon.  Never longer than
    :func:`prognostic_horizon`; 0 when the last prediction is outside.

    Parameters and returns as :func:`prognostic_horizon` (flights).
    """
    f, p = _profile(flights, pred, eol)
    _check_alpha(alpha)
    inside = np.abs(p - (eol - f)) <= alpha * eol
    if not inside[-1]:
        return 0.0
    out = np.flatnonzero(~inside)
    first = int(out[-1]) + 1 if out.size else 0
    return float(eol - f[first])


def monotonicity(series: ArrayLike) -> float:
    """Monotonicity of a series (Coble and Hines 2009).

    ``|#(x[k+1] > x[k]) - #(x[k+1] < x[k])| / (n - 1)``: 1 for a strictly monotone series, near
    0 for noise; equal steps count for neither side but for ``n - 1``.

    Parameters
    ----------
    series : sequence of float
        E.g. a unit's median RUL predictions (flights) or a fault's estimates; inf allowed.

    Returns
    -------
    float
        In [0, 1]; NaN for a single value.
    """
    x = _vector(series, "series")
    if x.size < 2:
        return math.nan
    with np.errstate(invalid="ignore"):  # inf - inf: an equal step, counted for neither side
        d = np.diff(x)
    return float(abs(int((d > 0).sum()) - int((d < 0).sum())) / (x.size - 1))


# --- intervals and detection -----------------------------------------------------------------

def coverage(low: ArrayLike, high: ArrayLike, true: ArrayLike) -> float:
    """Share of intervals holding the truth: ``mean(low <= true <= high)`` (bounds included).

    Parameters
    ----------
    low, high : sequence of float
        Interval bounds (may be infinite), the unit of ``true``.
    true : sequence of float
        The true values, finite.

    Returns
    -------
    float
        In [0, 1].
    """
    lo, hi = _vector(low, "low"), _vector(high, "high")
    t = _vector(true, "true", allow_inf=False)
    if not lo.shape == hi.shape == t.shape:
        raise ValueError(f"low, high and true must be of one length, got {lo.size}, "
                         f"{hi.size}, {t.size}")
    return float(np.mean((lo <= t) & (t <= hi)))


def mean_width(low: ArrayLike, high: ArrayLike) -> float:
    """Mean width ``mean(high - low)`` of intervals (the unit of the bounds; inf when any
    bound is infinite): the sharpness that :func:`coverage` alone does not see."""
    lo, hi = _vector(low, "low"), _vector(high, "high")
    if lo.shape != hi.shape:
        raise ValueError(f"low and high must be of one length, got {lo.size} and {hi.size}")
    if (hi < lo).any():
        raise ValueError("an interval has high < low")
    return float(np.mean(hi - lo))


def detection_delay(flights: ArrayLike, flagged: ArrayLike, onset: float | None
                    ) -> float | None:
    """Flights from a fault's true onset to its first detection at or after it.

    ``delay = min{t_k : flagged_k, t_k >= onset} - onset``.

    Parameters
    ----------
    flights : sequence of float
        Inspection flights.
    flagged : sequence of bool
        Whether each inspection flags the fault.
    onset : float or None
        Flight at which the truth first lies past the detection level (None: never).

    Returns
    -------
    float or None
        Flights; None without an onset; inf when never flagged from the onset on.
    """
    f = _vector(flights, "flights", allow_inf=False)
    g = np.asarray(flagged, dtype=bool)
    if g.shape != f.shape:
        raise ValueError(f"flights and flags must be of one length, got {f.size} and {g.size}")
    if onset is None:
        return None
    hit = np.flatnonzero(g & (f >= onset))
    return float(f[hit[0]] - onset) if hit.size else math.inf


def false_alarm_rate(flagged: ArrayLike, healthy: ArrayLike) -> float:
    """Share of healthy inspections that flag a fault: ``#(flagged & healthy) / #healthy``.

    Parameters
    ----------
    flagged, healthy : sequence of bool
        Per inspection: flagged by the tracker; the truth not past the detection level.

    Returns
    -------
    float
        In [0, 1]; NaN without a healthy inspection.
    """
    g = np.asarray(flagged, dtype=bool)
    h = np.asarray(healthy, dtype=bool)
    if g.shape != h.shape or g.ndim != 1:
        raise ValueError(f"flags and health must be 1-D of one length, got shapes {g.shape} "
                         f"and {h.shape}")
    n = int(h.sum())
    return float((g & h).sum() / n) if n else math.nan
