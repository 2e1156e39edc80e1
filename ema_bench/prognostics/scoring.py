"""Score a tracked campaign against its hidden truth.

:func:`score_tracking` reads a tracking run (``DIR2/manifest.json`` and ``DIR2/track.jsonl`` of
:func:`~ema_bench.prognostics.tracking.track_campaign`) and the ``truth.json`` of the campaign
its manifest names.  The formulas are in :mod:`~ema_bench.prognostics.metrics`; the rules:

- **Final prediction**: a unit's last tracked step, i.e. its last inspection, or the step at
  which the tracker called for replacement (tracking stops there), or its last step before the
  tracker failed on it.  Its true RUL is ``eol - flight`` of that step.  RUL RMSE, MAE, the
  PHM08 score (summed, C-MAPSS style), ``rul_coverage`` and ``failing_fault_named`` use the
  final predictions of the units that fail (``eol`` not null).
- **Infinite RUL** (the tracker sees no failure coming): every median RUL is capped at
  ``rul_cap`` = :data:`CAP_FACTOR` x the longest life (EOL) in the campaign's truth, a large,
  finite late error; RUL intervals are not capped (an infinite upper bound covers any truth).
- **alpha-lambda**: the prediction judged is the first at or after ``t_lambda = t_0 + lambda
  (EOL - t_0)``, ``t_0`` the unit's first inspection (:data:`ALPHA_LAMBDA_SIDE`, progpy's
  convention); within ``+- alpha`` of the true RUL at that prediction's flight.
- **Untracked units** (in the truth, no step in ``track.jsonl``) are listed in ``untracked``;
  failing ones count as misses in ``alpha_lambda`` and ``rul_coverage`` (whose denominator is
  every failing unit of the campaign) and are left out of the errors (no prediction).  A
  failing unit whose tracking stopped before ``t_lambda`` is a miss too.
- ``false_replacements``: replacements on units that never fail (gain drift only);
  ``early_replacements``: on failing units more than :data:`EARLY_FACTOR` inspection
  intervals before their EOL.
- **Tracking per fault** (Na, Fst, BLK, Gprop): RMSE of the estimates over every tracked
  inspection of every unit, as a share of the fault's range (``UPPER - LOWER``), and the share
  of those inspections' 95 % intervals holding the truth.
- **Detection** of a fault with a failure threshold: its *detection level* lies
  :data:`DETECTION_SHARE` of the way from nominal to the threshold.  Onset: the first
  inspection at which the truth lies past the level.  An inspection *flags* the fault when its
  whole 95 % interval lies past the level, i.e. excludes every healthy value (the healthy
  value itself is not known per unit: as-built faults scatter around nominal, e.g. Fst 0.170
  to 0.185 N m s/rad against 0.169, so "interval excludes nominal" would flag sound units).
  ``detection_delay``: flights from onset to the first flag at or after it (median over the
  unit-fault pairs with an onset; inf when never flagged); ``false_alarm_rate``: flags at
  inspections whose truth is not past the level, over those inspections (pooled).
- **Prognostic horizon**: ``+- PH_ALPHA x EOL`` bounds, median over tracked failing units;
  **monotonicity** of the capped median RUL (and ``fault_monotonicity`` of the estimate of the
  fault that fails), mean over tracked failing units with two steps or more.
- **Oracle bound** (:func:`oracle_bound`, ``oracle=True``): alpha-lambda and RUL coverage of a
  tracker that knows each failing unit's law parameters and its true faults at the judged
  inspection, so that only the future's randomness is unknown: what no tracker can beat.
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path

import numpy as np

from ..faults import FAULT_INDEX, FAULT_NAMES, LOWER, NOMINAL, UPPER
from ..seeding import child
from . import metrics
from .campaign import load_campaign, load_truth
from .laws import DAMAGE_SIGN, ForwardPaths
from .tracking import TRACK_FILE, campaign_path, read_track

#: An infinite (or larger) median RUL counts as this many times the campaign's longest life.
CAP_FACTOR = 2.0
#: A replacement more than this many inspection intervals before EOL is early.
EARLY_FACTOR = 3
#: Detection level: this share of the way from nominal to the failure threshold.
DETECTION_SHARE = 0.25
#: Half-width of the prognostic horizon's bounds, share of EOL.
PH_ALPHA = 0.1
#: Which prediction alpha-lambda judges (:func:`metrics.prediction_at`).
ALPHA_LAMBDA_SIDE = "after"

_STEP_KEYS = ("flight", "estimate", "low", "high", "rul", "rul_low", "rul_high", "replace")


class ScoringError(ValueError):
    """A tracking run that cannot be scored: one line naming the file and the reason."""


def _median(values: list) -> float:
    v = [x for x in values if x is not None and not math.isnan(x)]
    return float(statistics.median(v)) if v else math.nan


def _mean(values: list) -> float:
    v = [x for x in values if x is not None and not math.isnan(x)]
    return float(np.mean(v)) if v else math.nan


# --- reading and checking --------------------------------------------------------------------

def _check_steps(unit: str, rows: list[dict], truth: dict, where: str) -> None:
    """Every step complete, no NaN, at an inspection flight of the truth."""
    for r in rows:
        at = f"{where}: unit {unit} flight {r.get('flight')}"
        missing = [k for k in _STEP_KEYS if k not in r]
        if missing:
            raise ScoringError(f"{at}: step lacks {missing}")
        for k in ("estimate", "low", "high"):
            if not isinstance(r[k], dict) or set(FAULT_NAMES) - set(r[k]):
                raise ScoringError(f"{at}: {k!r} must give every fault {list(FAULT_NAMES)}")
            if any(v is None or math.isnan(v) for v in r[k].values()):
                raise ScoringError(f"{at}: {k!r} holds NaN or null")
        if any(r[k] is None or math.isnan(r[k]) for k in ("rul", "rul_low", "rul_high")):
            raise ScoringError(f"{at}: RUL is NaN")
        if r["rul"] < 0:
            raise ScoringError(f"{at}: negative RUL {r['rul']}")
        if str(r["flight"]) not in truth["faults"]:
            raise ScoringError(f"{at}: not an inspection flight of the campaign's truth (was "
                               "the campaign remade?)")


def _load(out: Path) -> tuple[dict[str, list[dict]], list[str], dict, object, dict]:
    """The run's steps, failed units and manifest, its campaign and the campaign's truth."""
    log = read_track(out)  # TrackerError naming the folder when there is no manifest.json
    m = log.manifest
    if not (out / TRACK_FILE).is_file():
        raise ScoringError(f"{out / TRACK_FILE}: no such file (nothing tracked yet?)")
    if not isinstance(m.get("campaign"), str):
        raise ScoringError(f"{out / 'manifest.json'}: names no campaign folder ('campaign')")
    camp = load_campaign(campaign_path(out, m), traces=False)  # CampaignError naming the file
    ours = {"campaign_name": camp.name, "campaign_seed": camp.seed, "track": camp.track,
            "split": camp.split}
    diff = {k: (m[k], v) for k, v in ours.items() if k in m and m[k] != v}
    if "campaign_name" not in m or diff:
        raise ScoringError(f"{out}: tracked another campaign than the one at {camp.root} "
                           f"(run, campaign: {diff or 'no campaign_name in the run manifest'});"
                           " was the campaign remade?")
    truth = load_truth(camp.root)
    extra = sorted(set(log.steps) - set(truth))
    if extra:
        raise ScoringError(f"{out / TRACK_FILE}: units {extra} are not in {camp.root}/"
                           "truth.json: tracked another campaign?")
    for unit, rows in log.steps.items():
        _check_steps(unit, rows, truth[unit], str(out / TRACK_FILE))
    return log.steps, sorted(log.failed), m, camp, truth


# --- one unit --------------------------------------------------------------------------------

def detection(rows: list[dict], truth: dict, thresholds: dict[str, float]) -> dict:
    """Per fault with a threshold: onset, delay, false flags and healthy inspections of one
    unit (the module docstring's rule)."""
    flights = [float(r["flight"]) for r in rows]
    out = {}
    for name, thr in thresholds.items():
        j, sign = FAULT_INDEX[name], DAMAGE_SIGN[name]
        level = NOMINAL[j] + DETECTION_SHARE * (thr - NOMINAL[j])
        true = np.array([truth["faults"][str(r["flight"])][j] for r in rows])
        past = sign * (true - level) > 0
        # the whole interval beyond the level: low above it (fails upwards), high below it
        edge = np.array([r["low" if sign > 0 else "high"][name] for r in rows])
        flag = sign * (edge - level) > 0
        onset = flights[int(np.argmax(past))] if past.any() else None
        out[name] = {"onset": onset, "delay": metrics.detection_delay(flights, flag, onset),
                     "false_flags": int((flag & ~past).sum()), "healthy": int((~past).sum())}
    return out


def score_unit(rows: list[dict], truth: dict, thresholds: dict[str, float], every: int,
               cap: float, alpha: float = 0.2, lam: float = 0.5) -> dict:
    """The figures of one tracked unit (the module docstring's rules).

    Parameters
    ----------
    rows : list of dict
        The unit's steps (``read_track(...).steps[unit]``), in flight order, at least one.
    truth : dict
        The unit's entry of ``truth.json``.
    thresholds : dict
        Failure thresholds per fault, physical units.
    every : int
        Flights between inspections.
    cap : float
        Cap on the median RUL, flights.
    alpha, lam : float
        alpha-lambda's cone half-width and share of life.

    Returns
    -------
    dict
        ``unit``, ``eol``, ``failing_fault``, ``inspections``, ``last_flight``, ``replaced``,
        ``fault_error`` / ``fault_coverage`` per fault, ``detection``; for a failing unit also
        ``true_rul``, ``rul`` (capped), ``rul_low``, ``rul_high``, ``rul_covered``,
        ``predicted_fault``, ``alpha_lambda`` (bool or None), ``alpha_lambda_flight``,
        ``prognostic_horizon``, ``monotonicity``, ``fault_monotonicity``,
        ``early_replacement``.
    """
    eol = truth["eol"]
    flights = np.array([r["flight"] for r in rows], dtype=float)
    est = np.array([[r["estimate"][n] for n in FAULT_NAMES] for r in rows])
    lo = np.array([[r["low"][n] for n in FAULT_NAMES] for r in rows])
    hi = np.array([[r["high"][n] for n in FAULT_NAMES] for r in rows])
    true = np.array([truth["faults"][str(r["flight"])] for r in rows], dtype=float)
    err = (est - true) / (UPPER - LOWER)
    last = rows[-1]
    rec: dict = {
        "unit": truth["unit"], "eol": eol, "failing_fault": truth["failing_fault"],
        "inspections": len(rows), "last_flight": int(flights[-1]),
        "replaced": bool(last["replace"]),
        "fault_error": {n: float(np.sqrt(np.mean(err[:, j] ** 2)))
                        for j, n in enumerate(FAULT_NAMES)},
        "fault_coverage": {n: metrics.coverage(lo[:, j], hi[:, j], true[:, j])
                           for j, n in enumerate(FAULT_NAMES)},
        "detection": detection(rows, truth, thresholds),
    }
    if eol is None:
        return rec
    pred = np.minimum(np.array([r["rul"] for r in rows], dtype=float), cap)
    true_rul = float(eol - flights[-1])
    i = metrics.prediction_at(flights, metrics.lambda_flight(float(flights[0]), eol, lam),
                              ALPHA_LAMBDA_SIDE)
    failing = truth["failing_fault"]
    rec.update({
        "true_rul": true_rul, "rul": float(pred[-1]),
        "rul_low": float(last["rul_low"]), "rul_high": float(last["rul_high"]),
        "rul_covered": bool(last["rul_low"] <= true_rul <= last["rul_high"]),
        "predicted_fault": last.get("failing_fault"),
        "alpha_lambda": metrics.alpha_lambda(flights, pred, eol, alpha, lam,
                                             ALPHA_LAMBDA_SIDE),
        "alpha_lambda_flight": None if i is None else int(flights[i]),
        "prognostic_horizon": metrics.prognostic_horizon(flights, pred, eol, PH_ALPHA),
        "monotonicity": metrics.monotonicity(pred),
        "fault_monotonicity": (metrics.monotonicity(est[:, FAULT_INDEX[failing]])
                               if failing in FAULT_INDEX else math.nan),
        "early_replacement": bool(last["replace"] and eol - flights[-1] > EARLY_FACTOR * every),
    })
    return rec


# --- the fleet -------------------------------------------------------------------------------

def _pooled(units: list[dict], rows: dict[str, list[dict]], truth: dict) -> dict:
    """Per-fault RMSE (share of range) and coverage pooled over every tracked inspection."""
    est, lo, hi, true = [], [], [], []
    for u in units:
        for r in rows[u["unit"]]:
            est.append([r["estimate"][n] for n in FAULT_NAMES])
            lo.append([r["low"][n] for n in FAULT_NAMES])
            hi.append([r["high"][n] for n in FAULT_NAMES])
            true.append(truth[u["unit"]]["faults"][str(r["flight"])])
    if not est:
        nan = {n: math.nan for n in FAULT_NAMES}
        return {"fault_error": nan, "fault_coverage": dict(nan)}
    est, lo, hi, true = (np.array(a, dtype=float) for a in (est, lo, hi, true))
    err = (est - true) / (UPPER - LOWER)
    return {"fault_error": {n: float(np.sqrt(np.mean(err[:, j] ** 2)))
                            for j, n in enumerate(FAULT_NAMES)},
            "fault_coverage": {n: metrics.coverage(lo[:, j], hi[:, j], true[:, j])
                               for j, n in enumerate(FAULT_NAMES)}}


def oracle_bound(truth: dict[str, dict], laws: dict, thresholds: dict[str, float],
                 alpha: float = 0.2, lam: float = 0.5, n_paths: int = 2000, seed: int = 0,
                 step: float = 2.0, horizon: float = 1500.0) -> dict:
    """alpha-lambda and RUL coverage of an oracle tracker over a campaign's failing units.

    At each failing unit's judged inspection (the first at or after ``t_lambda``, as the
    scoring's alpha-lambda) the oracle knows the unit's law parameters (``truth[u]["params"]``)
    and its true faults; it runs ``n_paths`` futures of the laws
    (:class:`~ema_bench.prognostics.laws.ForwardPaths`, ``step``-flight blocks up to
    ``horizon`` flights) to the first threshold crossing: RUL median and 2.5-97.5 %
    interval.  Only the future's randomness (duty, gamma increments, jumps, coil onset) is
    left, so no tracker can be expected to beat it.

    Parameters
    ----------
    truth : dict
        ``load_truth`` of the campaign.
    laws : dict
        The campaign's ``laws`` (:meth:`FleetLaws.to_dict`).
    thresholds : dict
        Failure thresholds, physical units.
    alpha, lam : float
        As :func:`score_tracking`.
    n_paths, seed : int
        Monte Carlo futures per unit; root seed (unit ``k`` of the sorted truth gets child
        ``k``).

    Returns
    -------
    dict
        ``oracle_alpha_lambda`` and ``oracle_rul_coverage`` (fractions of ``oracle_units``,
        the failing units with a judged inspection), ``oracle_units``.
    """
    hits, covered, n = 0, 0, 0
    for k, unit in enumerate(sorted(truth)):
        t = truth[unit]
        if t["eol"] is None:
            continue
        p = t.get("params")
        if not p:
            raise ScoringError(f"truth of unit {unit} has no law parameters: no oracle bound")
        flights = np.array(sorted(int(f) for f in t["faults"]), dtype=float)
        i = metrics.prediction_at(flights, metrics.lambda_flight(flights[0], t["eol"], lam),
                                  ALPHA_LAMBDA_SIDE)
        if i is None:
            continue
        f = int(flights[i])
        rng = np.random.default_rng(child(seed, k))
        x0 = np.tile(np.array(t["faults"][str(f)], dtype=float), (n_paths, 1))
        rates = {"Fst": np.full(n_paths, p["fst_rate"]), "BLK": np.full(n_paths, p["blk_rate"]),
                 "Na": np.full(n_paths, p["na_growth"])}
        paths = ForwardPaths(rng, x0, rates, laws, p["mean_duty"],
                             np.full(n_paths, p["na_onset"] <= f))
        rul = paths.first_failure(thresholds, step, horizon)
        med, low, high = np.quantile(rul, [0.5, 0.025, 0.975])
        true = float(t["eol"] - f)
        n += 1
        hits += metrics.within_alpha(float(med), true, alpha)
        covered += bool(low <= true <= high)
    return {"oracle_alpha_lambda": hits / n if n else math.nan,
            "oracle_rul_coverage": covered / n if n else math.nan, "oracle_units": n}


def score_tracking(out: Path | str, alpha: float = 0.2, lam: float = 0.5,
                   oracle: bool = False) -> dict:
    """Score the tracking run in ``out`` against its campaign's truth.

    Parameters
    ----------
    out : path
        The run folder (``DIR2`` of ``ema-bench campaign track``): ``manifest.json`` naming the
        campaign folder, ``track.jsonl``.
    alpha : float
        alpha-lambda's cone half-width, share of the true RUL, in (0, 1).
    lam : float
        Share of life at which alpha-lambda is judged, in [0, 1].
    oracle : bool
        Also the campaign's :func:`oracle_bound` (about 0.5 s per failing unit).

    Returns
    -------
    dict
        ``tracker``, ``campaign``, ``track``, ``split``, ``alpha``, ``lambda``, ``rul_cap``
        (flights); counts ``units`` (in the campaign), ``tracked``, ``failing_units`` (in the
        campaign), ``untracked`` and ``failed_units`` (lists); RUL figures ``rul_rmse``,
        ``rul_mae`` (flights), ``phm08_score``, ``alpha_lambda``, ``rul_coverage``,
        ``failing_fault_named`` (fractions), ``prognostic_horizon`` (flights, median),
        ``monotonicity`` and ``fault_monotonicity`` (mean); ``false_replacements``,
        ``early_replacements``; ``fault_error`` (share of range) and ``fault_coverage`` per
        fault; ``detection_delay`` (flights, median), ``detections`` (flagged onsets),
        ``onsets``, ``false_alarm_rate``; with ``oracle`` the :func:`oracle_bound` figures;
        ``per_unit`` rows (:func:`score_unit`).  NaN where a figure has nothing to average.

    Raises
    ------
    ScoringError, CampaignError, TrackerError
        One line naming the file: a missing or broken file, a run of another campaign.
    """
    if not 0.0 < alpha < 1.0 or not 0.0 <= lam <= 1.0:
        raise ScoringError(f"alpha must lie in (0, 1) and lambda in [0, 1], got {alpha!r}, "
                           f"{lam!r}")
    out = Path(out)
    steps, failed, m, camp, truth = _load(out)
    eols = [t["eol"] for t in truth.values() if t["eol"] is not None]
    cap = CAP_FACTOR * max(eols) if eols else math.nan
    units = [score_unit(steps[u], truth[u], camp.thresholds, camp.inspection_every, cap,
                        alpha, lam)
             for u in sorted(truth) if steps.get(u)]
    failing = [u for u in units if u["eol"] is not None]
    never = [u for u in units if u["eol"] is None]
    n_failing = len(eols)
    res: dict = {
        "tracker": m.get("tracker"), "campaign": camp.name, "track": camp.track,
        "split": camp.split, "alpha": alpha, "lambda": lam, "rul_cap": cap,
        "units": len(truth), "tracked": len(units), "failing_units": n_failing,
        "untracked": sorted(set(truth) - {u["unit"] for u in units}), "failed_units": failed,
    }
    nan = math.nan
    if failing:
        pred = [u["rul"] for u in failing]
        true = [u["true_rul"] for u in failing]
        res.update({"rul_rmse": metrics.rmse(pred, true), "rul_mae": metrics.mae(pred, true),
                    "phm08_score": metrics.phm08_score(pred, true)})
    else:
        res.update({"rul_rmse": nan, "rul_mae": nan, "phm08_score": nan})
    res.update({
        # over every failing unit of the campaign: untracked ones and None count as misses
        "alpha_lambda": (sum(u["alpha_lambda"] is True for u in failing) / n_failing
                         if n_failing else nan),
        "rul_coverage": sum(u["rul_covered"] for u in failing) / n_failing if n_failing else nan,
        "failing_fault_named": (sum(u["predicted_fault"] == u["failing_fault"] for u in failing)
                                / len(failing) if failing else nan),
        "prognostic_horizon": _median([u["prognostic_horizon"] for u in failing]),
        "monotonicity": _mean([u["monotonicity"] for u in failing]),
        "fault_monotonicity": _mean([u["fault_monotonicity"] for u in failing]),
        "false_replacements": sum(u["replaced"] for u in never),
        "early_replacements": sum(u["early_replacement"] for u in failing),
    })
    res.update(_pooled(units, steps, truth))
    det = [d for u in units for d in u["detection"].values()]
    delays = [d["delay"] for d in det if d["delay"] is not None]
    healthy = sum(d["healthy"] for d in det)
    res.update({
        "detection_delay": _median(delays), "onsets": len(delays),
        "detections": sum(math.isfinite(d) for d in delays),
        "false_alarm_rate": sum(d["false_flags"] for d in det) / healthy if healthy else nan,
    })
    if oracle:
        res.update(oracle_bound(truth, camp.laws, camp.thresholds, alpha, lam))
    res["per_unit"] = units
    return res
