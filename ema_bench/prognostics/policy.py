"""Replacement policies from a tracker's RUL, costed against the oracle policy.

A **tracker policy** replaces a unit at the first tracked inspection where the tracker's
signal (``rul_low``, its 95 % lower bound, or ``rul``, its point) is at most a threshold
``theta`` (flights); if none does up to the cut (the unit's last inspection), it schedules the
replacement from its forecast at the cut, as the clock would run it down: at the first later
inspection ``cut + k every`` with ``signal - k every <= theta``.  ``(signal, theta)`` are
tuned per tracker on the **frozen training split** (:func:`tune`, refused on a sealed
campaign) and applied unchanged to every other campaign.

The **oracle policy** knows each unit's true state at the cut (the oracle's futures,
:func:`~ema_bench.prognostics.oracle.unit_futures`, weighed by the cut rule) and picks each
unit's replacement delay ``d`` (a multiple of the inspection spacing, ``0 .. DMAX``) to
minimise the fleet's expected cost per flight (Dinkelbach's iteration on the renewal-reward
ratio below): on the same units and futures no policy that replaces at or after the cut does
better (``tests/test_prognostics_policy.py``).

**Cost model: ``EMAFault/Maintain-v0``'s** (flights' revenue): an inspection 0.5, a planned
replacement 40, a failure in service 400.  A unit's life under a policy, for a future with
remaining life ``R`` at the cut ``c``: inspections every ``every`` flights from the first to
the last before its end; a replacement at ``c + d`` when ``d < R`` (planned), else a failure
at ``c + R``.  The figure is the **cost per 100 flights**, ``sum_u E[cost_u] / sum_u
E[flights_u]``, the long-run cost rate of an actuator position (renewal reward), which is
what Maintain-v0's mean cost per flight converges to.  Cost per unit alone (beside it) is no
judge: replacing every unit at its cut costs about 40 per unit and throws a third of the
lives away.  A replacement before the cut is planned (the unit was seen alive later).  A unit
without a step at its cut never replaces (``d = DMAX``); futures beyond the oracle's
look-ahead are replaced at ``DMAX``.  Units that never fail (gain drift only) are not costed
here (their false replacements are the score's ``decisions``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .oracle import HORIZON

#: Maintain-v0's costs, flights' revenue (the defaults of its keyword arguments).
INSPECT_COST, REPLACE_COST, FAILURE_COST = 0.5, 40.0, 400.0
#: The tracker signals a policy may read at each inspection.
SIGNALS = ("rul_low", "rul")
#: Thresholds tried when tuning, flights.
THRESHOLDS = tuple(float(t) for t in range(0, 305, 5))
#: The longest replacement delay after the cut, flights (the oracle's look-ahead).
DMAX = HORIZON
FORMAT = "ema-bench-policy-thresholds"


class PolicyError(ValueError):
    """A thresholds file or a campaign the policy cannot use (one line)."""


def unit_cost(d: float, rul: np.ndarray, cut: float, every: int) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """Cost (flights' revenue) and flights flown of one unit per future, replaced ``d``
    flights after its cut (``d < 0``: before it, at an inspection the unit survived).

    Parameters
    ----------
    d : float
        Replacement delay after the cut, flights (capped at :data:`DMAX`).
    rul : ndarray
        The futures' remaining lives at the cut, flights (``inf`` beyond the look-ahead).
    cut : float
        The cut's flight.
    every : int
        Flights between inspections.
    """
    d = min(float(d), DMAX)
    r = np.asarray(rul, dtype=float)
    fail = d >= r
    end = np.where(fail, cut + np.where(fail, r, 0.0), cut + d)
    # inspections at every, 2 every, ... strictly before a failure, up to a replacement's
    n_insp = np.where(fail, np.ceil(end / every) - 1, np.floor(end / every))
    cost = INSPECT_COST * n_insp + np.where(fail, FAILURE_COST, REPLACE_COST)
    return cost, end


def tracker_delay(rows: list[dict], cut: float, every: int, signal: str, theta: float) -> float:
    """A tracker policy's replacement delay after the cut, flights (module docstring):
    negative when a step before the cut already called it; :data:`DMAX` without a step at
    the cut."""
    if not rows or int(rows[-1]["flight"]) != int(cut):
        return DMAX
    for r in rows:
        if float(r[signal]) <= theta:
            return float(r["flight"]) - cut
    s = float(rows[-1][signal])
    if not math.isfinite(s):
        return DMAX
    return float(every * math.ceil((s - theta) / every))


def _grid(every: int) -> np.ndarray:
    return np.arange(0.0, DMAX + every, float(every))


def oracle_delays(futures: dict, truth: dict, every: int, iterations: int = 20
                  ) -> dict[str, float]:
    """The oracle policy: per unit the delay on the inspection grid that minimises the
    fleet's expected cost per flight under its futures (Dinkelbach: minimise ``E[cost] -
    lam E[flights]`` per unit, ``lam`` the last iterate's rate, until ``lam`` settles)."""
    grid = _grid(every)
    tables = {}
    for u, (rul, w) in futures.items():
        c = float(truth[u]["last_flight"])
        cols = [unit_cost(d, rul, c, every) for d in grid]
        wn = w / w.sum()
        tables[u] = (np.array([cost @ wn for cost, _ in cols]),
                     np.array([fl @ wn for _, fl in cols]))
    lam, pick = 0.0, {}
    for _ in range(iterations):
        pick = {u: int(np.argmin(ec - lam * ef)) for u, (ec, ef) in tables.items()}
        new = (sum(tables[u][0][i] for u, i in pick.items())
               / sum(tables[u][1][i] for u, i in pick.items()))
        if abs(new - lam) <= 1e-12 * max(1.0, new):
            break
        lam = new
    return {u: float(grid[i]) for u, i in pick.items()}


def expected_costs(delays: dict[str, float], futures: dict, truth: dict, every: int
                   ) -> dict[str, np.ndarray]:
    """Per unit (sorted) the expected cost, flights and failure probability of the delays."""
    units = sorted(delays)
    cost, flights, fail = [], [], []
    for u in units:
        rul, w = futures[u]
        wn = w / w.sum()
        c, f = unit_cost(delays[u], rul, float(truth[u]["last_flight"]), every)
        cost.append(c @ wn)
        flights.append(f @ wn)
        fail.append(float(wn @ (min(delays[u], DMAX) >= rul)))
    return {"units": units, "cost": np.array(cost), "flights": np.array(flights),
            "fail": np.array(fail)}


def rate(e: dict[str, np.ndarray], idx: np.ndarray | None = None) -> np.ndarray | float:
    """Cost per 100 flights of :func:`expected_costs` (``idx``: bootstrap resamples)."""
    with np.errstate(divide="ignore"):   # a policy replacing at flight 0: infinite
        if idx is None:
            return float(100.0 * e["cost"].sum() / e["flights"].sum())
        return 100.0 * e["cost"][idx].sum(axis=-1) / e["flights"][idx].sum(axis=-1)


def _run_inputs(run: Path | str, truth_file: Path | str | None):
    """A run's steps, tracker name, campaign, its truth and the failing units' futures."""
    from .scoring import _load, campaign_futures

    steps, _, m, camp, truth = _load(Path(run), truth_file)
    return steps, m.get("tracker"), camp, truth, campaign_futures(camp, truth)


def tracker_rate(steps: dict, futures: dict, truth: dict, every: int, signal: str,
                 theta: float) -> dict[str, np.ndarray]:
    """:func:`expected_costs` of a tracker policy on the failing units."""
    delays = {u: tracker_delay(steps.get(u, []), truth[u]["last_flight"], every, signal,
                               theta) for u in futures}
    return expected_costs(delays, futures, truth, every)


def tune(runs: list[Path | str], truth: Path | str | None = None) -> dict:
    """Each run's ``(signal, theta)`` minimising its cost per 100 flights on its campaign (the
    training split): a thresholds document (module docstring).  PolicyError on a sealed
    campaign (trackers tune on the published campaign only) or on runs of two campaigns."""
    trackers, camp0 = {}, None
    for run in runs:
        steps, name, camp, tr, fut = _run_inputs(run, truth)
        if camp.seed is None:
            raise PolicyError(f"{run}: tracks a sealed campaign; thresholds are tuned on the "
                              "published training split only")
        if camp0 is not None and camp.digest != camp0.digest:
            raise PolicyError(f"{run}: another campaign than {camp0.root}; tune on one")
        camp0 = camp
        best = min(((rate(tracker_rate(steps, fut, tr, camp.inspection_every, s, t)), s, t)
                    for s in SIGNALS for t in THRESHOLDS), key=lambda x: x[0])
        trackers[name] = {"signal": best[1], "threshold": best[2],
                          "cost_per_100_flights": best[0]}
    if camp0 is None:
        raise PolicyError("no run to tune on")
    return {"format": FORMAT, "version": 1,
            "tuned_on": {"campaign": camp0.name, "track": camp0.track, "seed": camp0.seed,
                         "units": len(camp0.units), "manifest_digest": camp0.digest},
            "costs": {"inspect": INSPECT_COST, "replace": REPLACE_COST,
                      "failure": FAILURE_COST},
            "trackers": trackers}


def read_thresholds(path: Path | str) -> dict:
    """A thresholds file of :func:`tune`; PolicyError (one line naming it) otherwise."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise PolicyError(f"{path}: cannot read a thresholds file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != 1:
        raise PolicyError(f"{path}: not a policy thresholds file ({FORMAT}, version 1)")
    for name, t in doc.get("trackers", {}).items():
        if (not isinstance(t, dict) or t.get("signal") not in SIGNALS
                or not isinstance(t.get("threshold"), (int, float))):
            raise PolicyError(f"{path}: tracker {name!r} needs a signal {SIGNALS} and a "
                              "threshold")
    return doc


def score_policies(runs: list[Path | str], thresholds: Path | str | dict,
                   truth: Path | str | None = None, n_boot: int = 2000) -> list[dict]:
    """Each run's tracker policy (its tuned ``signal``, ``theta``) beside the oracle policy
    (:func:`score_policy`)."""
    doc = thresholds if isinstance(thresholds, dict) else read_thresholds(thresholds)
    out = []
    for run in runs:
        steps, name, camp, tr, fut = _run_inputs(run, truth)
        if name not in doc["trackers"]:
            raise PolicyError(f"{run}: no tuned threshold for tracker {name!r}")
        t = doc["trackers"][name]
        out.append({"tracker": name, "campaign": camp.name, "track": camp.track,
                     "sealed": camp.seed is None,
                     **score_policy(steps, fut, tr, camp.inspection_every, t["signal"],
                                    float(t["threshold"]), n_boot)})
    return out


def score_policy(steps: dict, futures: dict, truth: dict, every: int, signal: str,
                 theta: float, n_boot: int = 2000) -> dict:
    """A tracker policy and the oracle policy on the same failing units and futures.

    Parameters
    ----------
    steps : dict
        Unit -> the tracker's steps (``read_track``).
    futures : dict
        Failing unit -> (remaining lives at the cut, flights; cut-rule weights).
    truth : dict
        Unit -> its truth (``last_flight``).
    every : int
        Flights between inspections.
    signal, theta : str, float
        The policy's signal (:data:`SIGNALS`) and threshold, flights.
    n_boot : int
        Bootstrap resamples over units (paired for the ratio).

    Returns
    -------
    dict
        ``units``, ``signal``, ``threshold``, ``cost_per_100_flights`` (``value``, ``ci``),
        ``cost_per_unit``, ``failures`` (expected count), ``oracle`` (the same three) and
        ``ratio`` (tracker / oracle cost per 100 flights, ``value``, ``ci``).
    """
    from .scoring import _ci, boot_indices

    e = tracker_rate(steps, futures, truth, every, signal, theta)
    o = expected_costs(oracle_delays(futures, truth, every), futures, truth, every)
    idx = boot_indices(len(e["units"]), n_boot)
    with np.errstate(divide="ignore", invalid="ignore"):   # a policy flying no flight
        b, ob = rate(e, idx), rate(o, idx)
        value = rate(e) / rate(o)
        ratio_ci = _ci(b / ob)
    return {"units": len(e["units"]), "signal": signal, "threshold": float(theta),
            "cost_per_100_flights": {"value": rate(e), "ci": _ci(b)},
            "cost_per_unit": float(e["cost"].mean()), "failures": float(e["fail"].sum()),
            "oracle": {"cost_per_100_flights": {"value": rate(o), "ci": _ci(ob)},
                       "cost_per_unit": float(o["cost"].mean()),
                       "failures": float(o["fail"].sum())},
            "ratio": {"value": float(value), "ci": ratio_ci}}


def policy_table(scored: list[dict]) -> list[str]:
    """Markdown: one row per tracker policy, then the oracle policy per campaign."""
    from ..escape import markdown

    def cell(h):
        return f"{h['value']:.2f} [{h['ci'][0]:.2f}, {h['ci'][1]:.2f}]"

    lines = ["| policy | track | failing units | signal <= threshold | cost / 100 flights | "
             "cost / unit | expected failures | cost / oracle's |", "|" + "---|" * 8]
    oracles = {}
    for s in scored:
        lines.append(f"| {markdown(s['tracker'])} | {s['track']} | {s['units']} | "
                     f"{s['signal']} <= {s['threshold']:g} | {cell(s['cost_per_100_flights'])}"
                     f" | {s['cost_per_unit']:.1f} | {s['failures']:.1f} | "
                     f"{cell(s['ratio'])} |")
        oracles.setdefault(s["track"], s)
    for track, s in oracles.items():
        o = s["oracle"]
        lines.append(f"| **oracle policy** | {track} | {s['units']} | true state | "
                     f"{cell(o['cost_per_100_flights'])} | {o['cost_per_unit']:.1f} | "
                     f"{o['failures']:.1f} | 1 |")
    return lines
