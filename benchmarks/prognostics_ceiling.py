"""How far can a tracker get on coil shorts?  Bounds that know everything the oracle knows
but the unit's coil growth rate (issue 47: is >= 0.9 of the oracle on coil shorts reachable?).

The oracle (``ema_bench/prognostics/oracle.py``) knows four things no tracker sees: the unit's
law parameters (friction rate, wear rate, mean duty and the coil's growth rate ``g``), its
true faults at the cut without noise, whether (and when) its coil short began, and the cut
rule's weighting, which is published.  Each **level** below is given all of that except
``g``, which it must infer from a view of the unit's past; its futures are the oracle's
(:func:`~ema_bench.prognostics.oracle.unit_futures`, the same generator) with each path's
``g`` drawn from the posterior of that view, and its point is the Bayes point for +-20 %
(:func:`~ema_bench.prognostics.bayes.best_point`):

- ``oracle``: the true ``g`` (reproduces the oracle's point exactly: a check of the plumbing);
- ``flights``: the exact shorted share after **every flight** since the onset and every
  flight's duty (the unit's history, regenerated from the campaign's public seed and checked
  against ``truth.json``): each flight's log-share rise is ``g duty eps``, ``eps ~ Gamma(4,
  1/4)``, so the likelihood is exact (``loglik_flights``);
- ``inspections``: the exact share at the **inspections** only (and at the onset, whose
  flight it is told) with every flight's duty: each interval's rise is ``g sum(duty eps)``,
  a weighted sum of gammas, matched to a gamma in mean and variance (``loglik_intervals``);
- ``prior``: nothing on ``g`` but the fleet's prior (a tracker before the onset).

The **data-only ladder** (:data:`DATA_LEVELS`) then takes the oracle's other knowledge away
one item at a time, each level knowing what the one before knew less one item, so that the
last knows only what a tracker can learn (:func:`data_knowledge`):

- ``duty``: ``inspections`` with the flights' duties only as the operator logs them, summed
  per interval: the unit's mean duty from its posterior (fleet prior, ``Gamma(k_d F, m /
  k_d)`` likelihood of the summed duty of ``F`` flights), ``g`` from each interval's rise
  with the flights' shares of the logged duty unknown (:func:`span_moments`);
- ``rates``: also the friction and wear rates, from their posteriors given the noise-free
  faults at the inspections (:func:`rate_evidence`; a jump-free interval shows the wear rate,
  so it stays nearly known);
- ``onset``: also the onset flight, known only to lie in the interval before the first
  inspection with a share (the law's exponential onset prior over it, marginalised jointly
  with ``g``);
- ``fits``: the shares at the inspections and the faults at the cut seen only through fits
  with the run's measured errors (:func:`fit_noise`: robust standard deviations of fit -
  truth over the committed run's inspections; one draw of errors per unit): whether and when
  the short began, ``g`` and the share now from the change-point posterior of those fits
  (``trackers/coil_onset.py``: an extended Kalman filter per onset hypothesis, so this level
  is a bound up to that filter's linearisation), friction and backlash now from their fit
  (flat prior).  The rates keep their noise-free posteriors: the fits' errors (about 3e-4 N m,
  3e-6 rad) are 0.1-1 % of the rises the rates are learned from.

Each of these is a garbling of the oracle's knowledge and (but for ``fits``' filter) an
exact or moment-matched posterior of what it is told, so each level's point is the Bayes point
given its view; the ladder's steps say which item costs what.

A tracker sees noisy fits of the share at the inspections only, the logged duty per interval
(not per flight), and neither the onset flight nor the other parameters, so every view it
has is a garbling of ``flights`` (and, but for the within-interval duties and the onset
flight, of ``inspections``): given that level's information, its Bayes point maximises each
unit's posterior expected hit, and no tracker's point does better in expectation over units
drawn from the laws, on every group defined by what the level knows (the units whose short
has begun by the cut, ``begun``).  The issue's coil-short group is defined by the unit's
future (the fault that fails first), so a tracker could trade other units for it; the bound
there is the level's figure, not a theorem.

Every unit's points (each level's, the committed run's at the cut, the oracle's) are judged on
the board's futures (``expected.FUTURES_SEED``) as on the board; the paired ratios to the
oracle are printed with bootstrap intervals over units, overall, by failing fault, by cut
position and for ``begun``::

    python benchmarks/prognostics_ceiling.py leaderboards/campaign/twin/fleet-bayes-cut \\
        --out ceiling.jsonl [--units u002,u013]

``--simulate N`` measures the bounds on the coil shorts among ``N`` units drawn from the
campaign's published laws instead (the generator's own code, no traces; the fits' errors
still measured on the run)::

    python benchmarks/prognostics_ceiling.py leaderboards/campaign/twin/fleet-bayes-cut \\
        --simulate 800 --seed 47 --out simulated.jsonl

On the training split only (the published twin campaign and its laws); lines already in
``--out`` are kept (resumable).  About 1 CPU-s a unit (nine sets of 4,000 futures).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from prognostics_offline import _ratio  # benchmarks/ (the script's folder) is on the path
from prognostics_subset import judge_points, pending
from scipy.special import gammaln

from ema_bench.faults import FAULT_INDEX, LOWER, UPPER
from ema_bench.prognostics import track_io
from ema_bench.prognostics.bayes import best_point
from ema_bench.prognostics.campaign import (
    _conditions,
    _inspection_flights,
    get_spec,
    load_campaign,
    load_truth,
)
from ema_bench.prognostics.laws import THRESHOLDS, unit_history
from ema_bench.prognostics.oracle import N_PATHS, unit_futures
from ema_bench.prognostics.tables import GROUPS
from ema_bench.seeding import child, run_seed, stream
from ema_bench_trackers.coil_onset import onset_paths, onset_posterior

#: The data-only ladder: each level knows what the one before knew less one more item.
DATA_LEVELS = ("duty", "rates", "onset", "fits")

LEVELS = ("oracle", "flights", "inspections", "prior", *DATA_LEVELS)
#: The ladder's items: (what is taken away, the level that knew it, the level that does not).
LADDER = (("growth rate", "oracle", "inspections"),
          ("mean and per-flight duty", "inspections", "duty"), ("rates", "duty", "rates"),
          ("onset flight", "rates", "onset"),
          ("noise-free faults", "onset", "fits"))
F_NA, F_FST, F_BLK = FAULT_INDEX["Na"], FAULT_INDEX["Fst"], FAULT_INDEX["BLK"]
#: The log-growth grid of the posterior: the prior's median +- 6 log-sds, this many points.
GRID = 4001


def lognormal_grid(median: float, sigma: float, n: int = GRID
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Grid of a log-normal quantity's log (its median +- 6 log-sds, ``n`` points) and the
    prior's log-density on it (unnormalised)."""
    lg = np.linspace(math.log(median) - 6.0 * sigma, math.log(median) + 6.0 * sigma, n)
    return lg, -0.5 * ((lg - math.log(median)) / sigma) ** 2


def log_grid(laws: dict) -> np.ndarray:
    """Grid of ``log g`` covering the fleet's prior (log-normal) by +- 6 log-sds."""
    return lognormal_grid(laws["na_growth_median"], laws["na_growth_sigma"])[0]


def log_prior(lg: np.ndarray, laws: dict) -> np.ndarray:
    """The fleet's log-normal prior of ``g`` as a density of ``log g`` (unnormalised)."""
    mu, s = math.log(laws["na_growth_median"]), laws["na_growth_sigma"]
    return -0.5 * ((lg - mu) / s) ** 2


def loglik_flights(lg: np.ndarray, rise: np.ndarray, duty: np.ndarray, k: float
                   ) -> np.ndarray:
    """Log-likelihood of ``log g`` from each flight's rise of the log share (``rise = g duty
    eps``, ``eps ~ Gamma(k, 1/k)``: ``rise / duty ~ Gamma(k, g / k)``), exact."""
    z = np.asarray(rise, float) / np.asarray(duty, float)
    g = np.exp(lg)[:, None]
    return np.sum(-k * np.log(g) - k * z[None, :] / g, axis=1)


def loglik_intervals(lg: np.ndarray, rise: np.ndarray, d1: np.ndarray, d2: np.ndarray,
                     k: float, full: bool = False) -> np.ndarray:
    """Log-likelihood of ``log g`` from each interval's rise of the log share, ``g sum(duty_f
    eps_f)`` (mean ``g d1``, variance ``g^2 d2 / k``, ``d1``, ``d2`` the sums of the flights'
    duties and squared duties): a gamma of that mean and variance (shape ``k d1^2 / d2``).
    ``full``: with the gamma's normalising terms (to compare spans of other lengths)."""
    rise, d1, d2 = (np.asarray(a, float) for a in (rise, d1, d2))
    shape = k * d1 ** 2 / d2
    scale = np.exp(lg)[:, None] * (d2 / (k * d1))[None, :]
    ll = np.sum(-shape[None, :] * np.log(scale) - rise[None, :] / scale, axis=1)
    return ll + np.sum((shape - 1.0) * np.log(rise) - gammaln(shape)) if full else ll


def span_moments(n_part, n, duty, k_d: float, k_e: float) -> tuple[np.ndarray, np.ndarray]:
    """``d1``, ``d2`` of :func:`loglik_intervals` for the log share's rise over the last
    ``n_part`` flights of an interval of ``n`` flights whose **logged** duty is ``duty``: the
    flights' own duties unknown, each a ``Dirichlet(k_d, ..., k_d)`` share of the logged sum
    (gamma duties given their sum), so the rise ``g duty sum_f w_f eps_f`` has mean
    ``g duty n_part / n`` and variance ``g^2 duty^2 Var(sum_f w_f eps_f)``."""
    n_part, n, duty = (np.asarray(a, float) for a in (n_part, n, duty))
    second = (n_part * (k_d + 1.0) * (1.0 + 1.0 / k_e) + n_part * (n_part - 1.0) * k_d) / (
        n * (n * k_d + 1.0))
    return duty * n_part / n, k_e * duty ** 2 * (second - (n_part / n) ** 2)


def posterior_draws(lg: np.ndarray, logpost: np.ndarray, rng: np.random.Generator,
                    n: int) -> np.ndarray:
    """``n`` draws of ``g`` from a posterior of ``log g`` on the grid ``lg`` (each draw
    spread uniformly over its grid cell)."""
    p = np.exp(logpost - logpost.max())
    i = rng.choice(lg.size, size=n, p=p / p.sum())
    h = lg[1] - lg[0]
    return np.exp(lg[i] + h * (rng.random(n) - 0.5))


def growth_evidence(level: str, history, onset: int, cut: int, flights: list[int],
                    laws: dict, lg: np.ndarray) -> np.ndarray:
    """The log-likelihood of ``log g`` on the grid that ``level`` knows at the cut (zero for
    ``prior``, and for every level while no short has begun)."""
    if level == "prior" or onset >= cut:
        return np.zeros_like(lg)
    k = laws["na_growth_shape"]
    log_s = np.full(history.faults.shape[0], -np.inf)
    log_s[onset:cut + 1] = np.log(1.0 - history.faults[onset:cut + 1, F_NA])
    if level == "flights":
        f = np.arange(onset + 1, cut + 1)
        return loglik_flights(lg, log_s[f] - log_s[f - 1], history.duty[f - 1], k)
    points = sorted({onset, *(f for f in flights if onset < f <= cut)})
    a, b = np.array(points[:-1]), np.array(points[1:])
    d = history.duty
    d1 = np.array([d[x:y].sum() for x, y in zip(a, b)])
    d2 = np.array([(d[x:y] ** 2).sum() for x, y in zip(a, b)])
    return loglik_intervals(lg, log_s[b] - log_s[a], d1, d2, k)


def logged_evidence(lg: np.ndarray, onset: int, view: dict, laws: dict) -> np.ndarray:
    """The log-likelihood of ``log g`` from the noise-free shares at the inspections after an
    onset at flight ``onset``, knowing only each interval's **logged** duty
    (:func:`span_moments`; the onset's interval: its last ``F_i - onset`` flights), normalised
    so that two onsets compare."""
    f, duty, log_s = view["flights"], view["duty"], view["log_share"]
    i = int(np.searchsorted(f, onset))           # the first inspection at or after the onset
    start = np.concatenate([[float(onset)], f[i:-1]])
    before = np.concatenate([[math.log(laws["na_initial_short"])], log_s[i:-1]])
    n_part, n = f[i:] - start, f[i:] - f[i - 1:-1]
    keep = n_part > 0                            # an onset at an inspection: no rise yet
    if not keep.any():
        return np.zeros_like(lg)
    d1, d2 = span_moments(n_part, n, duty[i:], laws["duty_shape"], laws["na_growth_shape"])
    return loglik_intervals(lg, (log_s[i:] - before)[keep], d1[keep], d2[keep],
                            laws["na_growth_shape"], full=True)


def onset_unknown_evidence(lg: np.ndarray, view: dict, laws: dict) -> np.ndarray:
    """:func:`logged_evidence` with the onset flight unknown within its inspection interval
    (the noise-free shares show the interval: the first inspection with a share), its prior
    the law's exponential onset, marginalised."""
    f, log_s = view["flights"], view["log_share"]
    i = int(np.flatnonzero(np.isfinite(log_s))[0])
    if abs(log_s[i] - math.log(laws["na_initial_short"])) < 1e-12:
        candidates = [int(f[i])]                 # the share is the initial one: begun there
    else:
        candidates = list(range(int(f[i - 1]) + 1, int(f[i])))
    rows = np.array([logged_evidence(lg, o, view, laws) - o / laws["na_onset_mean"]
                     for o in candidates])
    top = rows.max(axis=0)
    return top + np.log(np.exp(rows - top).sum(axis=0))


def rate_evidence(view: dict, laws: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Posteriors (``log`` grid, log-density) of the unit's mean duty, friction rate and wear
    rate from the logged duties and the **noise-free** faults at the inspections: the mean
    duty from the flights' summed duty (``Gamma(k_d F, m / k_d)``, exact), the friction rate
    from the total rise (a gamma process: ``Gamma(a D, r / a)``, exact), the wear rate per
    interval from wear alone or wear plus a jump (the calm rise known to 1 %, the grid's
    resolution; one exponential jump)."""
    f, duty, x = view["flights"], view["duty"], view["faults"]
    total, k_d = float(duty.sum()), laws["duty_shape"]
    lm, pm = lognormal_grid(1.0, laws["duty_unit_sigma"])
    out = {"mean_duty": (lm, pm - k_d * f[-1] * lm - k_d * total * np.exp(-lm))}
    lr, pr = lognormal_grid(laws["fst_rate_median"], laws["fst_rate_sigma"])
    a, rise = laws["fst_shape"], float(x[-1, F_FST] - x[0, F_FST])
    out["fst_rate"] = (lr, pr - a * total * lr - a * rise * np.exp(-lr))
    lw, pw = lognormal_grid(laws["blk_rate_median"], laws["blk_rate_sigma"])
    w = np.exp(lw)[:, None]
    d, r = duty[None, 1:], np.diff(x[:, F_BLK])[None, :]
    sd = 0.01 * w * d
    calm = np.exp(-0.5 * ((r - w * d) / sd) ** 2) / (sd * math.sqrt(2.0 * math.pi))
    mu = laws["blk_jump_mean"]
    jump = np.where(r > w * d, np.exp(-np.maximum(r - w * d, 0.0) / mu) / mu, 0.0)
    p = -np.expm1(-laws["blk_jump_rate"] * d)
    out["blk_rate"] = (lw, pw + np.log((1.0 - p) * calm + p * jump + 1e-300).sum(axis=1))
    return out


def data_knowledge(level: str, t: dict, laws: dict, view: dict, seen: dict,
                   rng: np.random.Generator, n: int = N_PATHS) -> dict[str, np.ndarray]:
    """What a data-only ``level`` knows of the unit at its cut, as per-path values for
    :func:`~ema_bench.prognostics.oracle.unit_futures` (``known``): each level of
    :data:`DATA_LEVELS` knows what the previous one did less one item.

    ``duty``: the flights' duties only as the operator logs them (per interval): the mean duty
    from its posterior, the growth rate from the shares at the inspections and the onset
    flight (:func:`logged_evidence`); ``rates``: also the friction and wear rates from their
    posteriors (:func:`rate_evidence`); ``onset``: also the onset flight only as far as the
    shares show it (:func:`onset_unknown_evidence`); ``fits``: the shares and the faults at
    the cut only as fits with the run's measured errors show them (``seen``): onset, growth
    rate and the share now from the change-point posterior of those fits
    (``trackers/coil_onset.py``, an extended Kalman filter per onset hypothesis), friction and
    backlash now from the fit (a flat prior)."""
    depth = DATA_LEVELS.index(level)
    post = rate_evidence(view, laws)
    known = {"mean_duty": posterior_draws(*post["mean_duty"], rng, n)}
    cut, onset = int(t["last_flight"]), int(t["params"]["na_onset"])
    if level == "fits":
        lg, prior = lognormal_grid(laws["na_growth_median"], laws["na_growth_sigma"], 400)
        f, duty = view["flights"], view["duty"]
        cp = onset_posterior(f, duty, seen["share"], np.full(f.size, seen["sd"]["Na"]), laws,
                             np.exp(lg), prior, float(duty.sum() / f[-1]))
        begun, s_now, known["na_growth"] = onset_paths(rng, *cp, np.exp(lg), n)
        x0 = np.tile(view["faults"][-1], (n, 1))
        x0[:, F_NA] = 1.0 - s_now
        for j, name in ((F_FST, "Fst"), (F_BLK, "BLK")):
            x0[:, j] = seen["cut"][j] + seen["sd"][name] * rng.standard_normal(n)
        known.update(x0=x0, begun=begun)
    else:
        lg = log_grid(laws)
        evidence = (np.zeros_like(lg) if onset > cut
                    else onset_unknown_evidence(lg, view, laws) if level == "onset"
                    else logged_evidence(lg, onset, view, laws))
        known["na_growth"] = posterior_draws(lg, log_prior(lg, laws) + evidence, rng, n)
    if depth >= DATA_LEVELS.index("rates"):
        known.update({r: posterior_draws(*post[r], rng, n) for r in ("fst_rate", "blk_rate")})
    return known


def unit_view(t: dict, records: list) -> dict:
    """What the inspections up to the cut show without noise: their flights, the logged duty
    since the previous one (0 for the first), the true faults and the log shorted share."""
    cut = int(t["last_flight"])
    recs = [r for r in records if r.flight <= cut]
    x = np.array([t["faults"][str(r.flight)] for r in recs], dtype=float)
    with np.errstate(divide="ignore"):
        log_s = np.log(1.0 - x[:, F_NA])
    return {"flights": np.array([r.flight for r in recs], dtype=float),
            "duty": np.array([0.0] + [float(r.conditions["duty_since_last"])
                                      for r in recs[1:]]),
            "faults": x, "log_share": log_s}


def fit_noise(log, truth: dict) -> dict[str, float] | None:
    """The run's measured fit errors (robust standard deviation, 1.4826 x the median absolute
    deviation of fit - truth over its inspections): ``Na`` where a short is present (a
    healthy coil's fit sits on its bound), ``Fst`` and ``BLK`` everywhere; None for a run
    without fits (a no-sensing reference: no ``fits`` level)."""
    err: dict[str, list] = {"Na": [], "Fst": [], "BLK": []}
    for u, steps in log.steps.items():
        for r in steps:
            x = truth[u]["faults"][str(r["flight"])]
            for name, j in (("Na", F_NA), ("Fst", F_FST), ("BLK", F_BLK)):
                e = (r.get("estimate") or {}).get(name)
                if e is not None and math.isfinite(e) and (name != "Na" or x[F_NA] < 1.0):
                    err[name].append(e - x[j])
    if not all(err.values()):
        return None
    return {k: float(1.4826 * np.median(np.abs(np.array(v) - np.median(v))))
            for k, v in err.items()}


def unit_points(camp, truth: dict, unit: str, k: int, history, flights: list[int],
                noise: dict | None = None) -> dict:
    """Each level's Bayes point at the unit's cut (flights); ``noise``: the fits' measured
    errors (:func:`fit_noise`), for the ``fits`` level."""
    t, laws = truth[unit], camp.laws
    cut, onset = int(t["last_flight"]), int(t["params"]["na_onset"])
    lg = log_grid(laws)
    stop = tuple(camp.cut_rule["stop"])
    view = unit_view(t, camp.units[unit])
    out = {}
    for j, level in enumerate(LEVELS):
        rng = np.random.default_rng(child(child(2, k), j))
        if level == "oracle":
            known = {}
        elif level in DATA_LEVELS:
            if level == "fits" and noise is None:
                continue
            known = data_knowledge(level, t, laws, view, seen_through(view, noise, k), rng)
        else:
            post = log_prior(lg, laws) + growth_evidence(level, history, onset, cut, flights,
                                                         laws, lg)
            known = {"na_growth": posterior_draws(lg, post, rng, N_PATHS)}
        rul, w, _ = unit_futures(t, laws, camp.thresholds, camp.inspection_every, stop,
                                 np.random.default_rng(child(0, k)), N_PATHS, known=known)
        out[level] = best_point(rul, w, 0.2)
    return out


def seen_through(view: dict, noise: dict | None, k: int) -> dict:
    """The unit's shares at the inspections and faults at the cut as fits with the measured
    errors ``noise`` show them (one draw per unit: child ``k`` of seed 3)."""
    if noise is None:
        return {}
    rng = np.random.default_rng(child(3, k))
    share = 1.0 - view["faults"][:, F_NA] + noise["Na"] * rng.standard_normal(len(view["faults"]))
    cut = view["faults"][-1].copy()
    cut[F_FST] += noise["Fst"] * rng.standard_normal()
    cut[F_BLK] += noise["BLK"] * rng.standard_normal()
    return {"share": share, "cut": cut, "sd": noise}


def history_of(camp, truth: dict, unit: str):
    """The unit's life regenerated from the campaign's public seed (as ``campaign make``
    draws it), checked against the truth's faults at every inspection flight."""
    node = run_seed(camp.seed, list(camp.units).index(unit))
    h = unit_history(stream(node, "instance"), get_spec(camp.name).laws, wear=True)
    for f, x in truth[unit]["faults"].items():
        if not np.allclose(h.faults[int(f), F_NA], x[F_NA], rtol=0, atol=1e-12):
            raise SystemExit(f"{unit}: the regenerated history is not the truth's at {f}")
    return h


def unit_line(camp, truth: dict, u: str, history, noise: dict,
              committed: float | None = None) -> dict:
    """One unit's points and expected hits (on the board's futures), every level's."""
    t0 = time.process_time()
    t = truth[u]
    points = unit_points(camp, truth, u, sorted(truth).index(u), history,
                         [int(f) for f in t["faults"]], noise)
    if committed is not None:
        points["committed"] = committed
    return {"unit": u, "failing_fault": t["failing_fault"], "life_fraction": t["life_fraction"],
            "begun": int(t["params"]["na_onset"]) <= int(t["last_flight"]), "points": points,
            **judge_points(camp, truth, u, points), "fit_sd": noise,
            "cpu_s": time.process_time() - t0}


def _append(out: Path, line: dict) -> None:
    with out.open("a") as fh:
        fh.write(json.dumps(line) + "\n")


def measure(run: str, out: Path, units: list[str] | None) -> list[dict]:
    log = track_io.read_track(run)
    camp = load_campaign(track_io.campaign_path(run, log.manifest), traces=False)
    if camp.seed is None:
        raise SystemExit(f"{run}: a sealed campaign; the bounds are measured on the "
                         "published training split only")
    truth = load_truth(camp.root, camp)
    failing = [u for u in camp.units if truth[u]["eol"] is not None]
    noise = fit_noise(log, truth)
    for u in pending(out, units or failing):
        _append(out, unit_line(camp, truth, u, history_of(camp, truth, u), noise,
                               float(log.steps[u][-1]["rul"])))
    return [json.loads(x) for x in out.read_text().splitlines()]


def simulated_fleet(name: str, n: int, seed: int, fault: str | None = "Na",
                    every: int | None = None):
    """``n`` units drawn from the published laws of campaign ``name`` by the generator's own
    code (run ``i`` of ``seed``: its laws and its cut as ``campaign make`` draws a test
    unit's, an inspection every ``every`` flights, default the campaign's), without their
    traces: (a campaign-like object, truth, histories) of those that fail by ``fault`` (every
    failing unit for None)."""
    spec = get_spec(name)
    every, stop = every or spec.inspection_every, spec.test_stop
    truth, records, histories = {}, {}, {}
    for i in range(n):
        node = run_seed(seed, i)
        h = unit_history(stream(node, "instance"), spec.laws, wear=True)
        if h.eol is None or fault not in (None, h.failing_fault):
            continue
        flights = _inspection_flights(h, every, "test", stop,
                                      np.random.default_rng(stream(node, "plan")))
        u = f"s{i:05d}"
        truth[u] = {"unit": u, "eol": h.eol, "failing_fault": h.failing_fault,
                    "last_flight": flights[-1], "life_fraction": flights[-1] / h.eol,
                    "faults": {str(f): [float(v) for v in np.clip(h.faults[f], LOWER, UPPER)]
                               for f in flights}, "params": h.params.to_dict()}
        records[u] = [SimpleNamespace(flight=f, conditions=_conditions(
            h, f, flights[j - 1] if j else None)) for j, f in enumerate(flights)]
        histories[u] = h
    camp = SimpleNamespace(laws=spec.laws.to_dict(), thresholds=dict(THRESHOLDS),
                           inspection_every=every, cut_rule={"stop": list(stop)},
                           units=records)
    return camp, truth, histories


def measure_simulated(run: str, out: Path, n: int, seed: int) -> list[dict]:
    """The bounds on the coil shorts among ``n`` units drawn from the laws (``--simulate``),
    the fits' errors measured on ``run``."""
    log = track_io.read_track(run)
    camp = load_campaign(track_io.campaign_path(run, log.manifest), traces=False)
    noise = fit_noise(log, load_truth(camp.root, camp))
    sim, truth, histories = simulated_fleet(camp.name, n, seed)
    for u in pending(out, list(truth)):
        _append(out, unit_line(sim, truth, u, histories[u], noise))
    return [json.loads(x) for x in out.read_text().splitlines()]


def summary(lines: list[dict]) -> list[str]:
    """Per group, each level's and the committed run's expected ratio to the oracle."""
    groups = {"all": lines, **{g: [x for x in lines if rule(x)] for g, rule in GROUPS.items()},
              "begun": [x for x in lines if x["begun"]],
              "Na, begun": [x for x in lines if x["begun"] and x["failing_fault"] == "Na"],
              "Na, not begun": [x for x in lines if not x["begun"]
                                and x["failing_fault"] == "Na"]}
    q = np.quantile
    text = []
    for name, sel in groups.items():
        if not sel:
            continue
        idx = np.random.default_rng(0).integers(0, len(sel), (4000, len(sel)))
        cells, ratios = [], {"oracle": (1.0, np.ones(len(idx)))}
        for key in (k for k in (*LEVELS[1:], "committed") if k in sel[0]):
            r, rb = ratios[key] = _ratio(sel, key, idx)
            cells.append(f"{key} {r:.3f} [{q(rb, .025):.3f}, {q(rb, .975):.3f}]")
        text.append(f"{name} ({len(sel)} units): " + "; ".join(cells))
        steps = [(item, a, b) for item, a, b in LADDER if a in ratios and b in ratios]
        if steps:   # what each item of the ladder costs (paired: the same bootstrap units)
            text.append(f"  {name}, cost of: " + "; ".join(
                f"{item} {ratios[a][0] - ratios[b][0]:+.3f} "
                f"[{q(ratios[a][1] - ratios[b][1], .025):+.3f}, "
                f"{q(ratios[a][1] - ratios[b][1], .975):+.3f}]" for item, a, b in steps))
    text.append(f"{sum(x['cpu_s'] for x in lines):.0f} CPU-s")
    return text


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", help="a committed run of the training split (its campaign's truth "
                               "beside its manifest): its point at the cut is judged beside")
    p.add_argument("--out", type=Path, required=True, help="JSON lines, appended")
    p.add_argument("--units", help="comma-separated units (default: every failing unit)")
    p.add_argument("--simulate", type=int, metavar="N",
                   help="instead of the campaign's units, the coil shorts among N units drawn "
                        "from its published laws (traces not made; the fits' errors still "
                        "measured on RUN)")
    p.add_argument("--seed", type=int, default=47, help="root seed of --simulate")
    a = p.parse_args()
    lines = (measure_simulated(a.run, a.out, a.simulate, a.seed) if a.simulate
             else measure(a.run, a.out, a.units.split(",") if a.units else None))
    print("\n".join(summary(lines)))


if __name__ == "__main__":
    main()
