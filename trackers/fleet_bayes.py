"""``fleet-bayes``: each unit's degradation-law parameters updated from its fits, the fleet's
published laws as priors; RUL by running the laws forward.

The campaign's manifest publishes the fleet's laws (``laws``: the families and the fleet-level
distributions of their parameters, :class:`~ema_bench.prognostics.laws.FleetLaws`), as an
operator would know them from run-to-failure fleets; the unit's own parameters stay hidden.
Each inspection is identified as in the other baselines (:class:`~._common.Fitter`, logged
confounders switched on, Laplace intervals); then, on a grid per parameter:

``Fst``, a gamma process in duty
    The rise since the first inspection over the logged duty ``D`` is ``Gamma(a D, r / a)``
    (``a`` the law's shape): likelihood of the unit's rate ``r`` from its normal approximation
    ``N(r D, r^2 D / a + s^2)`` (``s``: the two fits' standard deviations), prior the fleet's
    log-normal.
``BLK``, wear plus jumps
    Each interval's rise is ``w D`` plus, with probability ``1 - exp(-lambda D)``, an
    exponential jump (the law's rate and mean size): a two-component likelihood of the wear
    rate ``w`` per interval, prior the fleet's log-normal.
``Na``, a coil short
    Healthy (the fitted shorted share ``1 - Na`` within 3 standard deviations of zero): the
    onset is memoryless (exponential, the law's mean), so the future holds an onset at that
    hazard.  Short present: the log-share's rises over duty give the growth rate ``g``
    (``N(g D, g^2 D m (1 + 1/k_d) / k_e + s_y^2)``), prior the fleet's log-normal.
Forward
    2,000 paths (``n_paths``) from the current estimates (drawn within their intervals),
    parameters drawn from their posteriors, duty around the unit's logged mean ``m``: the laws
    run forward by :class:`~ema_bench.prognostics.laws.ForwardPaths` in 2-flight blocks
    (``step_flights``; 1 or 8,000 paths change no board figure beyond noise:
    ``leaderboards/campaign/README.md``) until a fault crosses its threshold (up to 1,500
    flights).  Median and 2.5-97.5 % of the first crossing.
Replacement
    :func:`~._common.replace_now`, as every baseline.

``fleet-bayes-cut``
    The same tracker, its reported RUL also conditioned on the campaign's published cut rule
    (:func:`~ema_bench.prognostics.campaign.cut_likelihood`, applied as if this inspection were
    the cut, which the scored one is, as the ``life-table`` reference and the oracle do): the
    forward paths' lives weighed by the rule, the Bayes point for +-20 %
    (:func:`~ema_bench.prognostics.bayes.best_point`) and the weighted 95 % interval.  The
    replacement decision keeps the unweighted paths: an inspection that is not the cut must not
    be decided as if it were.
``fleet-bayes-whole``
    ``fleet-bayes-onset`` whose cut-conditioned RUL (point, interval, quantiles) is in whole
    flights: a true RUL is ``EOL - flight``, EOL the first flight at which a fault is past its
    threshold, so each future's first passage (interpolated within its 2-flight block) is
    rounded up before the Bayes point is chosen.  The point then lies at ``0.8 R`` of a whole
    ``R`` and counts that life in its +-20 % window, which a point a hair below (the
    interpolated futures' choice) misses.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ema_bench.faults import FAULT_INDEX
from ema_bench.prognostics.bayes import best_point, weighted_quantile
from ema_bench.prognostics.campaign import cut_likelihood
from ema_bench.prognostics.distributions import LEVELS, level_key
from ema_bench.prognostics.laws import FleetLaws, ForwardPaths
from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker

from ._common import (
    HORIZON_FLIGHTS,
    REPLACE_HORIZON,
    REPLACE_PROB,
    first_passage,
    make_step,
    replace_now,
    rng_of,
    summarise,
    to_damage,
    unit_setup,
)
from .coil_onset import onset_paths, onset_posterior

N_PATHS = 2000
STEP = 2.0          # flights per forward step
GRID = 400          # points of each parameter's posterior grid
ONSET_SD = 3.0      # a short is present when 1 - Na exceeds this many standard deviations


def _grid(median: float, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Log-spaced grid over a log-normal prior (+- 7 sigma) and its log-density."""
    z = np.linspace(-7.0, 7.0, GRID)
    return median * np.exp(sigma * z), -0.5 * z ** 2


def _posterior(log_prior: np.ndarray, log_like: np.ndarray) -> np.ndarray:
    lp = log_prior + log_like
    w = np.exp(lp - lp.max())
    return w / w.sum()


def _normal_ll(x: float | np.ndarray, mean: np.ndarray, var: np.ndarray) -> np.ndarray:
    return -0.5 * ((x - mean) ** 2 / var + np.log(var))


def _cut_summary(summary, t: np.ndarray, flight: float, every: int,
                 stop: tuple[float, float], alpha: float = 0.2):
    """``summary`` with its RUL point and interval taken from the path lives ``flight + t``
    weighed by the cut rule (unchanged when no path is compatible with a cut here)."""
    w = cut_likelihood(float(flight), float(flight) + t, every, stop)
    if w.sum() <= 0:
        return summary
    point = best_point(t, w, alpha)
    low, high = weighted_quantile(t, w, [0.025, 0.975])
    qs = weighted_quantile(t, w, LEVELS)
    return dataclasses.replace(summary, rul=point, low=float(min(low, point)),
                               high=float(max(high, point)),
                               quantiles={level_key(q): float(v) for q, v in zip(LEVELS, qs)})


@register_tracker("fleet-bayes-whole", description="fleet-bayes-onset whose cut-conditioned "
                  "RUL is in whole flights (each future's first passage rounded up, as a true "
                  "RUL is): the Bayes point over whole-flight lives", cut_rule=True,
                  coil="changepoint", whole_flights=True)
@register_tracker("fleet-bayes-onset", description="fleet-bayes-cut with the coil short's "
                  "onset as a change point of the Na fits (joint posterior of the onset "
                  "interval and the growth rate, trackers/coil_onset.py)", cut_rule=True,
                  coil="changepoint")
@register_tracker("fleet-bayes-cut", description="fleet-bayes whose reported RUL is also "
                  "conditioned on the published cut rule (Bayes point for +-20 %, weighted "
                  "95 % interval); replacement decided as fleet-bayes", cut_rule=True)
@register_tracker("fleet-bayes", description="Bayesian update of the unit's degradation-law "
                  "parameters (friction rate, wear rate, coil growth) from its fits, the "
                  "fleet's published laws as priors; RUL by running the laws forward")
def factory(campaign_info: dict, seed: np.random.SeedSequence, *, n_paths: int = N_PATHS,
            first_budget: int = 1500, global_budget: int = 1000,
            replace_prob: float = REPLACE_PROB, cut_rule: bool = False,
            coil: str = "threshold", whole_flights: bool = False, step_flights: float = STEP):
    if coil not in ("threshold", "changepoint"):
        raise ValueError(f"coil must be 'threshold' or 'changepoint', got {coil!r}")
    u = unit_setup(campaign_info, seed, first_budget, global_budget)
    thresholds, every, names, d_thr, fitter, mc_seed = (u.thresholds, u.every, u.names, u.d_thr,
                                                        u.fitter, u.mc_seed)
    laws = {**FleetLaws().to_dict(), **campaign_info.get("laws", {})}
    fst_grid, fst_prior = _grid(laws["fst_rate_median"], laws["fst_rate_sigma"])
    blk_grid, blk_prior = _grid(laws["blk_rate_median"], laws["blk_rate_sigma"])
    na_grid, na_prior = _grid(laws["na_growth_median"], laws["na_growth_sigma"])
    k_d = float(laws["duty_shape"])
    stop = tuple(campaign_info.get("cut_rule", {}).get("stop", (0.5, 0.95)))
    hist: dict[str, list] = {"flight": [], "duty": [], "x": [], "sd": []}

    def step(insp: Inspection) -> TrackStep:
        fit = fitter(insp)
        c = insp.conditions
        hist["flight"].append(insp.flight)
        hist["duty"].append(float(c.get("duty_since_last", 0.0) or 0.0) if hist["x"] else 0.0)
        hist["x"].append(fit.x.copy())
        hist["sd"].append(fit.sd.copy())
        x, sd = np.array(hist["x"]), np.array(hist["sd"])
        duty = np.array(hist["duty"])
        flown = hist["flight"][-1] - hist["flight"][0]
        m = float(duty.sum() / flown) if flown > 0 else 1.0
        post = {}
        # friction: the rise over the total duty
        if "Fst" in names:
            j = FAULT_INDEX["Fst"]
            D, rise = duty.sum(), x[-1, j] - x[0, j]
            a = laws["fst_shape"]
            ll = (_normal_ll(rise, fst_grid * D, fst_grid ** 2 * D / a + sd[-1, j] ** 2
                             + sd[0, j] ** 2) if D > 0 else np.zeros(GRID))
            post["Fst"] = _posterior(fst_prior, ll)
        # backlash: per interval, wear alone or wear plus a jump
        if "BLK" in names:
            j = FAULT_INDEX["BLK"]
            lam, mu = laws["blk_jump_rate"], laws["blk_jump_mean"]
            ll = np.zeros(GRID)
            for k in range(1, len(duty)):
                D, rise = duty[k], x[k, j] - x[k - 1, j]
                var = sd[k, j] ** 2 + sd[k - 1, j] ** 2 + (0.1 * blk_grid * D) ** 2
                p = 1.0 - math.exp(-lam * D)
                calm = np.exp(_normal_ll(rise, blk_grid * D, var)) / np.sqrt(2 * np.pi)
                excess = rise - blk_grid * D
                jump = np.where(excess > 0, np.exp(-np.maximum(excess, 0) / mu) / mu, 1e-300)
                ll += np.log((1 - p) * calm + p * jump + 1e-300)
            post["BLK"] = _posterior(blk_prior, ll)
        # coil: present or not, and its growth rate
        short = None
        onset = None
        if "Na" in names and coil == "changepoint":
            j = FAULT_INDEX["Na"]
            onset = onset_posterior(np.array(hist["flight"]), duty, 1.0 - x[:, j], sd[:, j],
                                    laws, na_grid, na_prior, m)
        elif "Na" in names:
            j = FAULT_INDEX["Na"]
            s = 1.0 - x[:, j]
            present = s > np.maximum(ONSET_SD * sd[:, j], 1e-3)
            ll = np.zeros(GRID)
            if present[-1]:
                short = float(s[-1])
                k0 = int(np.flatnonzero(~present)[-1] + 1) if (~present).any() else 0
                y, sy = np.log(s[k0:]), sd[k0:, j] / s[k0:]
                ke = laws["na_growth_shape"]
                for k in range(1, len(y)):
                    D = duty[k0 + k]
                    var = na_grid ** 2 * D * m * (1 + 1 / k_d) / ke + sy[k] ** 2 + sy[k - 1] ** 2
                    ll += _normal_ll(y[k] - y[k - 1], na_grid * D, var)
            post["Na"] = _posterior(na_prior, ll)
        rng = rng_of(mc_seed, insp.index)
        grids = {"Fst": fst_grid, "BLK": blk_grid, "Na": na_grid}
        # where the unit is now, within its fit; its parameters drawn from their posteriors
        x0 = np.tile(fit.x, (n_paths, 1)) + rng.standard_normal((n_paths, len(fit.x))) * fit.sd
        rates = {f: rng.choice(grids[f], size=n_paths, p=post[f]) for f in post}
        begun = np.full(n_paths, short is not None)
        if onset is not None:   # each path's onset and growth from the change-point posterior
            begun, s_now, rates["Na"] = onset_paths(rng, *onset, na_grid, n_paths)
            x0[:, FAULT_INDEX["Na"]] = 1.0 - s_now
            short = float(np.mean(begun)) if begun.mean() >= 0.5 else None
        paths = ForwardPaths(rng, x0, rates, laws, m, begun)
        cross = first_passage(to_damage(paths.x, names, thresholds),
                              lambda dt: to_damage(paths.advance(dt), names, thresholds),
                              d_thr, step_flights, HORIZON_FLIGHTS)
        summary = summarise(cross, names, REPLACE_HORIZON * every)
        replace = replace_now(summary, fit.low, fit.high, names, thresholds, replace_prob)
        profile = None
        if cut_rule:   # the unconditioned median stays the profile's (scoring's diagnostics)
            profile = summary.rul
            life = cross.min(axis=1)   # a true RUL is whole flights: EOL is a flight
            summary = _cut_summary(summary, np.ceil(life) if whole_flights else life,
                                   insp.flight, every, stop)
        return make_step(insp, fit.x, fit.low, fit.high, summary, replace, fit.evaluations,
                         profile, fit=fit.how, mean_duty=m, coil_present=short is not None)
    return step
