"""Score a tracked campaign against its hidden truth.

:func:`score_tracking` reads a tracking run (``DIR2/manifest.json`` and ``DIR2/track.jsonl`` of
:func:`~ema_bench.prognostics.track_run.track_campaign`), the campaign its manifest names and the
campaign's truth, given explicitly (default: the ``truth.json`` that ``campaign make`` wrote in
the campaign folder); a truth file of another campaign is refused
(:func:`~ema_bench.prognostics.campaign.read_truth`).  Formulas in
:mod:`~ema_bench.prognostics.metrics`; the rules:

**The headline: RUL at the hidden cut.**  Every failing test unit (``eol`` not null) is judged
at its *cut*, its last inspection (drawn at 50-95 % of its life by the published cut rule),
with the tracker's prediction there, whatever the tracker decided before (tracking goes on past
a replacement call).  A unit without a step at its cut (untracked, or the tracker failed on
it) counts with an infinite prediction and interval ``[inf, inf]``: a miss, not covered,
infinitely wide.  Over the failing units:

- ``within``: share of predictions within ``+-alpha`` (0.2) of the true RUL;
- ``mae``, ``rmse``: RUL errors in flights, the predictions clipped to ``[0, H]`` with the
  documented horizon ``H`` = :data:`HORIZON_INSPECTIONS` inspection intervals (500 flights
  on fleet-v1, longer than any true RUL at a cut: a prediction beyond it says "not within the
  horizon");
- ``phm08``: the PHM08 score per unit (mean of the challenge's terms), same clipping;
- ``coverage``: share of 95 % RUL intervals holding the true RUL; ``width``: their mean
  width, flights (infinite when one is), so that ``[0, inf]`` buys no credit.

Beside them, scored at the same cut: ``expected``, the expected hit rate (the probability
that the point lands within ``+-alpha`` under each unit's futures drawn from its true state,
averaged; :mod:`~ema_bench.prognostics.expected`), the board's headline, since the realised
``within`` also carries the luck of the units' futures; ``phm08_median``, the median unit's
PHM08 term (robust: one unit's exponential does not carry it); the interval scores ``is50``,
``is80``, ``is95``, coverages ``cov50``, ``cov80`` and ``crps`` of the predictive
distribution (:mod:`~ema_bench.prognostics.distributions`).

Each comes with a bootstrap interval over units (:data:`N_BOOT` resamples, 2.5-97.5 %
percentiles, seed :data:`BOOT_SEED`) and, when the oracle is scored
(:mod:`~ema_bench.prognostics.oracle`), as a ratio to the oracle's figure on the same units
with a *paired* bootstrap interval (the same resampled units for both).

**Maintenance decisions**, scored on their own: a unit's decision is its first step with
``replace``.  ``false_replacements``: on units that never fail (gain drift only);
``early_replacements``: on failing units more than :data:`EARLY_FACTOR` inspection intervals
before EOL; ``failures_in_service``: failing units never replaced although an inspection saw
them with less than one inspection interval of life left (they fail before the next one);
``wasted_flights``: mean true RUL thrown away at the replacements of failing units;
``maintenance_cost``: replacements + :data:`FAILURE_COST` x failures in service, per unit.

**Diagnostics** (never the headline): the alpha-lambda curve over lambda 0.5 .. 0.9 (the
prediction judged is the first at or after ``t_lambda = t_0 + lambda (EOL - t_0)``, ``t_0`` the
first inspection; share of the failing units with such a prediction, their count beside it:
the cut precedes ``t_lambda`` on many units); the prognostic horizon at ``+- PH_ALPHA x EOL``
(first entry, Saxena et al. and progpy; and the strict variant), median over failing units;
monotonicity of the median RUL and of the failing fault's estimate (mean); tracking per fault
(RMSE of the estimates over every tracked inspection, share of the fault's range, and the share
of 95 % intervals holding the truth); detection of each fault with a threshold (its detection
level lies :data:`DETECTION_SHARE` of the way from nominal to the threshold; onset: the first
inspection past it; a flag: the whole 95 % interval past it; ``detection_delay`` median,
``false_alarm_rate`` pooled).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..faults import FAULT_INDEX, FAULT_NAMES, LOWER, NOMINAL, UPPER
from . import distributions, expected, metrics
from .campaign import load_campaign, read_truth
from .expected import at_most, expected_hits
from .laws import DAMAGE_SIGN
from .oracle import N_PATHS, oracle_predictions
from .track_io import campaign_path, read_track
from .tracking import TRACK_FILE, VERSION

#: The headline's relative half-width (+-20 %).
ALPHA = 0.2
#: Point predictions are clipped to this many inspection intervals for MAE, RMSE and PHM08.
HORIZON_INSPECTIONS = 50
#: Bootstrap resamples over units and their seed.
N_BOOT = 2000
BOOT_SEED = 0
#: A replacement more than this many inspection intervals before EOL is early.
EARLY_FACTOR = 3
#: Cost of a failure in service, in replacements.
FAILURE_COST = 10.0
#: Detection level: this share of the way from nominal to the failure threshold.
DETECTION_SHARE = 0.25
#: Half-width of the prognostic horizon's bounds, share of EOL.
PH_ALPHA = 0.1
#: The lambdas of the alpha-lambda diagnostic curve.
LAMBDAS = (0.5, 0.6, 0.7, 0.8, 0.9)
#: Which prediction alpha-lambda judges (:func:`metrics.prediction_at`).
ALPHA_LAMBDA_SIDE = "after"
#: The headline figures, in board order: the expected and realised hit rates
#: (:mod:`~ema_bench.prognostics.expected`), point errors, PHM08 per unit (mean and median
#: term), the 95 % interval, and the distribution's figures
#: (:mod:`~ema_bench.prognostics.distributions`).
HEADLINE = ("expected", "within", "mae", "rmse", "phm08", "phm08_median", "coverage", "width",
            "is95", "crps", "is50", "is80", "cov50", "cov80")


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
    """Every step complete, no NaN, at an inspection flight of the truth (read_track's
    schema, :data:`~.track_io.STEP_SCHEMA`, has checked that every field is there)."""
    for r in rows:
        at = f"{where}: unit {unit} flight {r.get('flight')}"
        for k in ("estimate", "low", "high"):
            if not isinstance(r[k], dict) or set(FAULT_NAMES) - set(r[k]):
                raise ScoringError(f"{at}: {k!r} must give every fault {list(FAULT_NAMES)}")
            if any(v is None or math.isnan(v) for v in r[k].values()):
                raise ScoringError(f"{at}: {k!r} holds NaN or null")
        if any(r[k] is None or math.isnan(r[k]) for k in ("rul", "rul_low", "rul_high")):
            raise ScoringError(f"{at}: RUL is NaN")
        if r["rul"] < 0:
            raise ScoringError(f"{at}: negative RUL {r['rul']}")
        if r.get("rul_quantiles"):
            try:
                distributions.check_quantiles(r["rul_quantiles"])
            except ValueError as exc:
                raise ScoringError(f"{at}: {exc}") from None
        if str(r["flight"]) not in truth["faults"]:
            raise ScoringError(f"{at}: not an inspection flight of the campaign's truth (was "
                               "the campaign remade?)")


def _load(out: Path, truth_file: Path | str | None = None):
    """The run's steps, failed units and manifest, its campaign and the campaign's truth."""
    log = read_track(out)  # TrackerError naming the folder when there is no manifest.json
    m = log.manifest
    if m.get("version") != VERSION:
        raise ScoringError(f"{out / 'manifest.json'}: tracking run version {m.get('version')!r}"
                           f" (this ema-bench scores version {VERSION}: every inspection to "
                           "the cut); track the campaign again")
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
    truth = read_truth(camp.root if truth_file is None else truth_file, camp)["units"]
    extra = sorted(set(log.steps) - set(truth))
    if extra:
        raise ScoringError(f"{out / TRACK_FILE}: units {extra} are not in the campaign's truth:"
                           " tracked another campaign?")
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
               alpha: float = ALPHA) -> dict:
    """The figures of one unit (the module docstring's rules).

    Parameters
    ----------
    rows : list of dict
        The unit's steps (``read_track(...).steps[unit]``), in flight order (may be empty:
        an untracked unit).
    truth : dict
        The unit's entry of ``truth.json``.
    thresholds : dict
        Failure thresholds per fault, physical units.
    every : int
        Flights between inspections.
    alpha : float
        The headline's relative half-width.

    Returns
    -------
    dict
        ``unit``, ``eol``, ``failing_fault``, ``inspections`` (tracked), ``cut`` (the last
        inspection's flight), ``at_cut`` (a step there), ``replaced_at`` (flight of the first
        replacement call, or None); with steps, ``fault_error`` / ``fault_coverage`` per fault
        and ``detection``; for a failing unit also ``true_rul`` (at the cut), ``rul``,
        ``rul_low``, ``rul_high`` (at the cut; inf without a step there), ``within``,
        ``covered``, ``width``, ``predicted_fault``, ``alpha_lambda`` (lambda -> bool or
        None), ``prognostic_horizon``, ``prognostic_horizon_strict``, ``monotonicity``,
        ``fault_monotonicity``, ``early_replacement``, ``failure_in_service``.
    """
    eol = truth["eol"]
    cut = int(truth["last_flight"])
    replaced = next((r for r in rows if r["replace"]), None)
    final = rows[-1] if rows and int(rows[-1]["flight"]) == cut else None
    rec: dict = {"unit": truth["unit"], "eol": eol, "failing_fault": truth["failing_fault"],
                 "inspections": len(rows), "cut": cut, "at_cut": final is not None,
                 "replaced_at": None if replaced is None else int(replaced["flight"])}
    if rows:
        est = np.array([[r["estimate"][n] for n in FAULT_NAMES] for r in rows])
        lo = np.array([[r["low"][n] for n in FAULT_NAMES] for r in rows])
        hi = np.array([[r["high"][n] for n in FAULT_NAMES] for r in rows])
        true = np.array([truth["faults"][str(r["flight"])] for r in rows], dtype=float)
        err = (est - true) / (UPPER - LOWER)
        rec.update({
            "fault_error": {n: float(np.sqrt(np.mean(err[:, j] ** 2)))
                            for j, n in enumerate(FAULT_NAMES)},
            "fault_coverage": {n: metrics.coverage(lo[:, j], hi[:, j], true[:, j])
                               for j, n in enumerate(FAULT_NAMES)},
            "detection": detection(rows, truth, thresholds)})
    if eol is None:
        return rec
    true_rul = float(eol - cut)
    rul, low, high = ((float(final["rul"]), float(final["rul_low"]), float(final["rul_high"]))
                      if final is not None else (math.inf, math.inf, math.inf))
    flights = np.array([r["flight"] for r in rows], dtype=float)
    # the profile diagnostics read the unconditioned forecasts (a cut-conditioned ``rul``
    # is scored at the cut only)
    pred = np.array([r.get("profile_rul", r["rul"]) for r in rows], dtype=float)
    failing = truth["failing_fault"]
    # an inspection that saw less than one interval of life left, with no replacement by then
    short = [r for r in rows if eol - r["flight"] < every]
    rec.update({
        "true_rul": true_rul, "rul": rul, "rul_low": low, "rul_high": high,
        "quantiles": dict(final.get("rul_quantiles") or {}) if final is not None else {},
        "life_fraction": cut / eol,
        "within": bool((1 - alpha) * true_rul <= rul <= (1 + alpha) * true_rul),
        "covered": bool(low <= true_rul <= high),
        "width": math.inf if math.isinf(low) or math.isinf(high) else high - low,
        "predicted_fault": final.get("failing_fault") if final is not None else None,
        "alpha_lambda": {lam: _alpha_lambda(flights, pred, eol, alpha, lam) for lam in LAMBDAS},
        "prognostic_horizon": (metrics.prognostic_horizon(flights, pred, eol, PH_ALPHA)
                               if rows else 0.0),
        "prognostic_horizon_strict": (metrics.prognostic_horizon_strict(flights, pred, eol,
                                                                        PH_ALPHA)
                                      if rows else 0.0),
        "monotonicity": metrics.monotonicity(pred) if rows else math.nan,
        "fault_monotonicity": (metrics.monotonicity(est[:, FAULT_INDEX[failing]])
                               if rows and failing in FAULT_INDEX else math.nan),
        "early_replacement": bool(replaced is not None
                                  and eol - replaced["flight"] > EARLY_FACTOR * every),
        "failure_in_service": bool(short and (replaced is None
                                              or replaced["flight"] > short[0]["flight"])),
    })
    return rec


def _alpha_lambda(flights: np.ndarray, pred: np.ndarray, eol: float, alpha: float,
                  lam: float) -> bool | None:
    if not flights.size:
        return None
    return metrics.alpha_lambda(flights, pred, eol, alpha, lam, ALPHA_LAMBDA_SIDE)


# --- the fleet -------------------------------------------------------------------------------

def headline_columns(units: list[dict], horizon: float, alpha: float = ALPHA
                     ) -> dict[str, np.ndarray]:
    """Per failing unit (in the given order) the terms the headline figures average:
    ``within``, ``abs`` and ``sq`` errors and ``phm08`` terms of the clipped prediction,
    ``covered``, ``width``, ``expected`` (the expected hit, ``nan`` when not judged) and the
    distribution's terms (:func:`~ema_bench.prognostics.distributions.columns`).
    ``units``: rows with ``rul``, ``rul_low``, ``rul_high`` and ``true_rul`` (a tracker's
    :func:`score_unit` rows or the oracle's; ``expected_hit`` and ``quantiles`` when
    given)."""
    pred = np.array([u["rul"] for u in units], dtype=float)
    true = np.array([u["true_rul"] for u in units], dtype=float)
    low = np.array([u["rul_low"] for u in units], dtype=float)
    high = np.array([u["rul_high"] for u in units], dtype=float)
    clipped = metrics.clip_rul(pred, horizon)
    with np.errstate(invalid="ignore"):   # a missing prediction's [inf, inf]: infinitely wide
        width = np.where(np.isinf(low) | np.isinf(high), np.inf, high - low)
    return {"within": ((1 - alpha) * true <= pred) & (pred <= (1 + alpha) * true),
            "abs": np.abs(clipped - true), "sq": (clipped - true) ** 2,
            "phm08": metrics.phm08_terms(clipped, true),
            "covered": (low <= true) & (true <= high), "width": width,
            "expected": np.array([u.get("expected_hit", math.nan) for u in units], dtype=float),
            **distributions.columns(units, horizon)}


#: Each headline figure from the columns of a set of units (``idx``: their rows).
_STATS: dict[str, Callable[[dict, np.ndarray], np.ndarray]] = {
    "within": lambda c, i: c["within"][i].mean(axis=-1),
    "mae": lambda c, i: c["abs"][i].mean(axis=-1),
    "rmse": lambda c, i: np.sqrt(c["sq"][i].mean(axis=-1)),
    "phm08": lambda c, i: c["phm08"][i].mean(axis=-1),
    # robust PHM08: the median unit's term (one unit's exponential no longer carries it)
    "phm08_median": lambda c, i: np.median(c["phm08"][i], axis=-1),
    "expected": lambda c, i: c["expected"][i].mean(axis=-1),
    "coverage": lambda c, i: c["covered"][i].mean(axis=-1),
    "width": lambda c, i: c["width"][i].mean(axis=-1),
    **{k: (lambda c, i, k=k: c[k][i].mean(axis=-1))
       for k in ("is95", "crps", "is50", "is80", "cov50", "cov80")},
}


def boot_indices(n: int, n_boot: int = N_BOOT, seed: int = BOOT_SEED) -> np.ndarray:
    """Bootstrap resamples (n_boot, n) of ``n`` units: the same for every tracker of a
    campaign and for its oracle (paired)."""
    return np.random.default_rng(seed).integers(0, n, size=(n_boot, n))


def _ci(values: np.ndarray) -> list[float]:
    """2.5-97.5 % percentiles without interpolation (an infinite resample stays infinite)."""
    v = values[~np.isnan(values)]
    if not v.size:
        return [math.nan, math.nan]
    return [float(x) for x in np.quantile(v, [0.025, 0.975], method="inverted_cdf")]


def _ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        r = a / b
    # 0/0 is a tie (ratio 1); x/0 infinite
    return np.where((a == 0) & (b == 0), 1.0, r)


def headline(cols: dict[str, np.ndarray], oracle_cols: dict[str, np.ndarray] | None = None,
             n_boot: int = N_BOOT, seed: int = BOOT_SEED) -> dict[str, dict]:
    """Each headline figure: ``value``, bootstrap interval ``ci``; with the oracle's columns
    (same units, same order) ``oracle`` and ``ratio`` (value and paired ``ratio_ci``)."""
    n = len(cols["within"])
    if not n:
        return {k: {"value": math.nan, "ci": [math.nan, math.nan]} for k in HEADLINE}
    idx = boot_indices(n, n_boot, seed)
    every = np.arange(n)
    out = {}
    for k in HEADLINE:
        stat = _STATS[k]
        v, boot = float(stat(cols, every)), stat(cols, idx)
        rec = {"value": v, "ci": _ci(boot)}
        if oracle_cols is not None:
            ov, oboot = float(stat(oracle_cols, every)), stat(oracle_cols, idx)
            rec.update({"oracle": ov, "oracle_ci": _ci(oboot),
                        "ratio": float(_ratio(np.array(v), np.array(ov))),
                        "ratio_ci": _ci(_ratio(boot, oboot))})
        out[k] = rec
    return out


def oracle_rows(truth: dict[str, dict], predictions: dict[str, dict]) -> list[dict]:
    """The oracle's rows (as :func:`headline_columns` reads them) for the failing units."""
    return [{"unit": u, "true_rul": float(truth[u]["eol"] - truth[u]["last_flight"]),
             **predictions[u]} for u in sorted(predictions)]


def decisions(units: list[dict], every: int) -> dict:
    """The maintenance decisions of a run (the module docstring's rules)."""
    failing = [u for u in units if u["eol"] is not None]
    never = [u for u in units if u["eol"] is None]
    replaced = [u for u in units if u["replaced_at"] is not None]
    wasted = [u["eol"] - u["replaced_at"] for u in failing if u["replaced_at"] is not None]
    fails = sum(u["failure_in_service"] for u in failing)
    return {"replacements": len(replaced),
            "false_replacements": sum(u["replaced_at"] is not None for u in never),
            "early_replacements": sum(u["early_replacement"] for u in failing),
            "failures_in_service": fails,
            "wasted_flights": _mean(wasted),
            "maintenance_cost": ((len(replaced) + FAILURE_COST * fails) / len(units)
                                 if units else math.nan)}


def diagnostics(failing: list[dict]) -> dict:
    """The alpha-lambda curve, prognostic horizons and monotonicity over the failing units."""
    curve = {}
    for lam in LAMBDAS:
        judged = [u["alpha_lambda"][lam] for u in failing if u["alpha_lambda"][lam] is not None]
        curve[f"{lam:g}"] = {"share": sum(judged) / len(judged) if judged else math.nan,
                             "units": len(judged)}
    return {"alpha_lambda": curve,
            "prognostic_horizon": _median([u["prognostic_horizon"] for u in failing]),
            "prognostic_horizon_strict": _median([u["prognostic_horizon_strict"]
                                                  for u in failing]),
            "monotonicity": _mean([u["monotonicity"] for u in failing]),
            "fault_monotonicity": _mean([u["fault_monotonicity"] for u in failing]),
            "failing_fault_named": (sum(u["predicted_fault"] == u["failing_fault"]
                                        for u in failing) / len(failing)
                                    if failing else math.nan)}


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


_ORACLE_CACHE: dict[tuple, dict] = {}
_FUTURES_CACHE: dict[tuple, dict] = {}


def campaign_futures(camp, truth: dict[str, dict], n_paths: int | None = None) -> dict:
    """The failing units' futures that expected hits are judged on
    (:func:`~ema_bench.prognostics.expected.campaign_futures`; memoised per campaign)."""
    n = N_PATHS if n_paths is None else int(n_paths)
    key = (camp.digest, n)
    if key not in _FUTURES_CACHE:
        _FUTURES_CACHE[key] = expected.campaign_futures(
            truth, camp.laws, camp.thresholds, camp.inspection_every, camp.cut_rule, n)
    return _FUTURES_CACHE[key]


def campaign_oracle(camp, truth: dict[str, dict], n_paths: int | None = None,
                    seed: int = 0, alpha: float = ALPHA) -> dict[str, dict]:
    """The oracle's predictions at the cuts of a campaign (memoised per campaign digest:
    several runs of one campaign share it)."""
    n = N_PATHS if n_paths is None else int(n_paths)
    key = (camp.digest, n, seed, alpha)
    if key not in _ORACLE_CACHE:
        _ORACLE_CACHE[key] = oracle_predictions(truth, camp.laws, camp.thresholds,
                                                camp.inspection_every, camp.cut_rule, n,
                                                seed, alpha)
    return _ORACLE_CACHE[key]


def score_tracking(out: Path | str, truth: Path | str | None = None, alpha: float = ALPHA,
                   oracle: bool = True, n_boot: int = N_BOOT,
                   oracle_paths: int | None = None, tracked_only: bool = False) -> dict:
    """Score the tracking run in ``out`` against its campaign's truth.

    Parameters
    ----------
    out : path
        The run folder (``DIR2`` of ``ema-bench campaign track``): ``manifest.json`` naming the
        campaign folder, ``track.jsonl``.
    truth : path, optional
        The campaign's truth file (or a folder holding it as ``truth.json``); default the
        campaign folder's ``truth.json``.  Another campaign's is refused.
    alpha : float
        The headline's relative half-width, in (0, 1).
    oracle : bool
        Also the campaign's oracle (:mod:`~ema_bench.prognostics.oracle`, about 0.3 s per
        failing unit) and each headline figure's ratio to it.
    n_boot : int
        Bootstrap resamples.
    oracle_paths : int, optional
        The oracle's futures per unit (default :data:`~ema_bench.prognostics.oracle.N_PATHS`).
    tracked_only : bool
        Score only the units the run has tracked to their cut (a run still going, or cut
        short): every figure, and the oracle's, on that subset (``scored_units`` says how
        many); never for a final board, where a missing unit is a miss.

    Returns
    -------
    dict
        ``tracker``, ``campaign``, ``definition_version``, ``track``, ``split``, ``alpha``,
        ``rul_horizon`` (flights); counts ``units``, ``tracked``, ``failing_units``,
        ``missing_at_cut`` (failing units without a step at their cut), ``untracked`` and
        ``failed_units`` (lists); ``headline`` (figure -> value, ``ci``, and with the oracle
        ``oracle``, ``oracle_ci``, ``ratio``, ``ratio_ci``); ``decisions``
        (:func:`decisions`); ``diagnostics`` (:func:`diagnostics`); ``fault_error`` and
        ``fault_coverage`` per fault; ``detection_delay``, ``detections``, ``onsets``,
        ``false_alarm_rate``; ``reliability`` (central level -> observed coverage,
        :func:`~ema_bench.prognostics.distributions.reliability`); ``per_unit`` rows
        (:func:`score_unit`, with ``expected_hit`` when judged) and with the oracle
        ``oracle_per_unit``, ``oracle_reliability`` and ``luck`` (for the tracker and the
        oracle: realised ``hits``, ``expected_hits`` and ``p_at_most``, the chance of so few
        hits or fewer under the units' futures).

    Raises
    ------
    ScoringError, CampaignError, TrackerError
        One line naming the file: a missing or broken file, a run or truth of another
        campaign.
    """
    if not 0.0 < alpha < 1.0:
        raise ScoringError(f"alpha must lie in (0, 1), got {alpha!r}")
    out = Path(out)
    steps, failed, m, camp, truth = _load(out, truth)
    every = camp.inspection_every
    horizon = float(HORIZON_INSPECTIONS * every)
    full = truth   # the oracle's seeds follow the whole campaign's units
    if tracked_only:   # the units tracked to their cut
        done = {u for u, rows in steps.items()
                if rows and int(rows[-1]["flight"]) == truth[u]["last_flight"]}
        truth = {u: t for u, t in truth.items() if u in done}
    units = [score_unit(steps.get(u, []), truth[u], camp.thresholds, every, alpha)
             for u in sorted(truth)]
    tracked = [u for u in units if u["inspections"]]
    failing = [u for u in units if u["eol"] is not None]
    res: dict = {
        "tracker": m.get("tracker"), "campaign": camp.name,
        "definition_version": camp.definition_version, "track": camp.track,
        "split": camp.split, "alpha": alpha, "rul_horizon": horizon,
        "units": len(camp.units), "tracked": len(tracked), "failing_units": len(failing),
        "missing_at_cut": sum(not u["at_cut"] for u in failing),
        "untracked": sorted(u["unit"] for u in units if not u["inspections"]),
        "failed_units": failed, "tracked_only": bool(tracked_only),
        "scored_units": len(units),
    }
    orows = None
    if oracle and failing:
        predictions = campaign_oracle(camp, full, oracle_paths, alpha=alpha)
        orows = oracle_rows(truth, {u: p for u, p in predictions.items() if u in truth})
        # expected hits: both points judged on the same futures, not the oracle's own
        futures = campaign_futures(camp, full, oracle_paths)
        for rows in (failing, orows):
            for r, e in zip(rows, expected_hits(rows, futures, alpha)):
                r["expected_hit"] = float(e)
        ocols = headline_columns(orows, horizon, alpha)
        cols = headline_columns(failing, horizon, alpha)
        res["headline"] = headline(cols, ocols, n_boot)
        res["luck"] = {who: {"hits": int(c["within"].sum()),
                             "expected_hits": float(c["expected"].sum()),
                             "p_at_most": at_most(c["expected"], int(c["within"].sum()))}
                       for who, c in (("tracker", cols), ("oracle", ocols))}
        res["oracle_reliability"] = distributions.reliability(orows)
    else:
        res["headline"] = headline(headline_columns(failing, horizon, alpha), None, n_boot)
    res["reliability"] = distributions.reliability(failing)
    res["decisions"] = decisions(units, every)
    res["diagnostics"] = diagnostics(failing)
    res.update(_pooled(tracked, steps, truth))
    det = [d for u in tracked for d in u["detection"].values()]
    delays = [d["delay"] for d in det if d["delay"] is not None]
    healthy = sum(d["healthy"] for d in det)
    res.update({
        "detection_delay": _median(delays), "onsets": len(delays),
        "detections": sum(math.isfinite(d) for d in delays),
        "false_alarm_rate": sum(d["false_flags"] for d in det) / healthy if healthy else math.nan,
    })
    res["per_unit"] = units
    if orows is not None:
        res["oracle_per_unit"] = orows
    return res
