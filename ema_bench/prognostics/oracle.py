"""The honest Bayes oracle of a campaign: the best RUL any tracker can be expected to give at
each failing unit's cut.

For each failing unit the oracle knows what no tracker can: the unit's law parameters (its
friction rate, wear rate, coil growth rate, mean duty; ``truth[u]["params"]``), whether its
coil short has begun, and its true faults at the cut (its last inspection).  It runs
``n_paths`` futures of the laws from there
(:class:`~ema_bench.prognostics.laws.ForwardPaths`, 1-flight blocks): what is left unknown is
the future's own randomness (duty, friction's gamma increments, backlash jumps, a coil
short's onset and growth noise).  It conditions them on the published cut rule (each future's
life ``L`` weighted by :func:`~ema_bench.prognostics.campaign.cut_likelihood`: the cut was
drawn at 50-95 % of the life, which a long future makes unlikely), and answers the point that
maximises the probability of lying within ``+-alpha`` of the true RUL
(:func:`~ema_bench.prognostics.bayes.best_point`) with the weighted 95 % interval.

No tracker is expected to beat it on the share within +-20 % (it is the Bayes decision for that
criterion given more than a tracker sees); on other figures (MAE, interval width) a tracker
may come out ahead by chance or because the point maximising the hit probability is not the
median.
"""

from __future__ import annotations

import numpy as np

from ..seeding import child
from .bayes import best_point, weighted_quantile
from .campaign import cut_likelihood
from .laws import ForwardPaths

#: Monte Carlo futures per unit, block length (flights) and look-ahead (flights).
N_PATHS = 4000
STEP = 1.0
HORIZON = 1500.0


class OracleError(ValueError):
    """A truth the oracle cannot use (no law parameters)."""


def unit_futures(truth: dict, laws: dict, thresholds: dict[str, float], every: int,
                 stop: tuple[float, float], rng: np.random.Generator,
                 n_paths: int = N_PATHS, na_growth: np.ndarray | None = None,
                 known: dict[str, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, bool]:
    """Futures of one failing unit drawn from its true state at its cut, weighed by the cut
    rule: what the oracle decides on, and what expected hits are judged on
    (:mod:`~ema_bench.prognostics.expected`).

    Parameters are those of :func:`oracle_unit`, and ``na_growth`` (n_paths,): each path's
    coil-short growth rate (per unit duty) in place of the unit's true one (default), for
    bounds that know everything the oracle knows but that rate
    (``benchmarks/prognostics_ceiling.py``); ``known`` replaces more of what the oracle knows
    by per-path values drawn from what a view of the unit's past leaves of it, for the
    data-only bounds: ``x0`` (n_paths, 4, the faults now), ``fst_rate``, ``blk_rate``,
    ``na_growth``, ``mean_duty`` (n_paths,) and ``begun`` (n_paths, bool: the short has
    begun); each key given replaces the truth's value.

    Returns
    -------
    rul : ndarray (n_paths,)
        Each future's remaining life from the cut, flights (``inf`` beyond the look-ahead).
    weights : ndarray (n_paths,)
        The cut rule's probability of this cut given each future's life
        (:func:`~ema_bench.prognostics.campaign.cut_likelihood`); all ones when no future
        fits the rule.
    weighted : bool
        False when no future fitted the cut rule and the weights are uniform.
    """
    p = truth.get("params")
    if not p:
        raise OracleError(f"truth of unit {truth.get('unit')} has no law parameters")
    cut = int(truth["last_flight"])
    k = {"x0": np.tile(np.array(truth["faults"][str(cut)], dtype=float), (n_paths, 1)),
         "mean_duty": p["mean_duty"], "begun": np.full(n_paths, p["na_onset"] <= cut),
         **{r: np.full(n_paths, p[r]) for r in ("fst_rate", "blk_rate", "na_growth")}}
    if na_growth is not None:
        k["na_growth"] = np.asarray(na_growth, dtype=float)
    k.update(known or {})
    rates = {"Fst": k["fst_rate"], "BLK": k["blk_rate"], "Na": k["na_growth"]}
    paths = ForwardPaths(rng, k["x0"], rates, laws, k["mean_duty"], k["begun"])
    rul = paths.first_failure(thresholds, STEP, HORIZON)
    w = cut_likelihood(cut, cut + rul, every, stop)
    weighted = bool(w.sum() > 0)
    return rul, (w if weighted else np.ones_like(rul)), weighted


def oracle_unit(truth: dict, laws: dict, thresholds: dict[str, float], every: int,
                stop: tuple[float, float], rng: np.random.Generator, n_paths: int = N_PATHS,
                alpha: float = 0.2) -> dict:
    """The oracle's prediction at one failing unit's cut.

    Parameters
    ----------
    truth : dict
        The unit's record of ``truth.json`` (``eol`` not None, ``params``, ``faults``,
        ``last_flight``).
    laws : dict
        The campaign's ``laws``.
    thresholds : dict
        Failure thresholds, physical units.
    every : int
        Flights between inspections.
    stop : (lo, hi)
        The cut rule's range (the manifest's ``cut_rule["stop"]``).
    rng : Generator
    n_paths : int
    alpha : float
        The headline's relative half-width.

    Returns
    -------
    dict
        ``rul`` (the Bayes point), ``rul_low``, ``rul_high`` (weighted 2.5 and 97.5 %), flights;
        ``p_within`` (the posterior probability that ``rul`` is within +-alpha of the truth,
        on the futures the point was chosen on: optimistic; the board judges it on
        independent futures, :mod:`~ema_bench.prognostics.expected`);
        ``quantiles`` (level -> weighted quantile of the RUL, flights, at
        :data:`~ema_bench.prognostics.distributions.LEVELS`); ``cut_weighted`` (False when no
        future fitted the cut rule and the unweighted futures were used).
    """
    from .distributions import LEVELS, level_key

    rul, w, weighted = unit_futures(truth, laws, thresholds, every, stop, rng, n_paths)
    point = best_point(rul, w, alpha)
    low, high = weighted_quantile(rul, w, [0.025, 0.975])
    lo_ok, hi_ok = (1 - alpha) * rul <= point, point <= (1 + alpha) * rul
    qs = weighted_quantile(rul, w, LEVELS)
    return {"rul": point, "rul_low": float(min(low, point)), "rul_high": float(max(high, point)),
            "p_within": float(np.sum(w * (lo_ok & hi_ok)) / np.sum(w)),
            "quantiles": {level_key(q): float(v) for q, v in zip(LEVELS, qs)},
            "cut_weighted": weighted}


def oracle_predictions(truth: dict[str, dict], laws: dict, thresholds: dict[str, float],
                       every: int, cut_rule: dict, n_paths: int = N_PATHS, seed: int = 0,
                       alpha: float = 0.2) -> dict[str, dict]:
    """:func:`oracle_unit` at the cut of every failing unit of a campaign's truth (about
    0.3 s per unit at 4000 paths).

    Unit ``k`` of the sorted truth gets child ``k`` of ``seed``: a unit's prediction does not
    depend on which other units are scored.  Returns unit -> its prediction."""
    stop = tuple(cut_rule.get("stop", (0.5, 0.95)))
    return {unit: oracle_unit(t, laws, thresholds, every, stop, rng, n_paths, alpha)
            for unit, t, rng in failing_units(truth, seed)}


def failing_units(truth: dict[str, dict], seed: int):
    """(unit, its truth, its generator) for every failing unit: unit ``k`` of the sorted
    truth gets child ``k`` of ``seed``, so a unit's draws do not depend on which other units
    are scored."""
    for k, unit in enumerate(sorted(truth)):
        if truth[unit]["eol"] is not None:
            yield unit, truth[unit], np.random.default_rng(child(seed, k))
