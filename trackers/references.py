"""The no-sensing references: what a tracker earns without reading a single trace.

``rul-age``
    ``RUL = age`` (the inspection's flight), interval ``[0, inf]``, no fault estimate beyond
    nominal within the fault box.  Under the old headline (alpha-lambda at half the true life)
    it scored 100 %; at the hidden cut it must score low.
``life-table``
    The unit's age, the fleet's life distribution from the published laws
    (:func:`ema_bench.prognostics.bayes.fleet_lives`) and the published cut rule
    (:func:`ema_bench.prognostics.campaign.cut_likelihood`, applied as if this inspection were
    the cut, which the scored one is): the posterior of the life given survival to the age and
    the cut there; its Bayes point for the headline
    (:func:`~ema_bench.prognostics.bayes.best_point`) and 95 % interval.

Both never call for replacement and spend no model run.  They read only what every tracker is
given (the manifest's settings and the inspection's flight).
"""

from __future__ import annotations

import math

import numpy as np

from ema_bench.faults import FAULT_NAMES, LOWER, NOMINAL, UPPER
from ema_bench.prognostics.bayes import best_point, fleet_lives, weighted_quantile
from ema_bench.prognostics.campaign import cut_likelihood
from ema_bench.prognostics.tracking import Inspection, TrackStep, register_tracker


def _step(insp: Inspection, rul: float, low: float, high: float) -> TrackStep:
    return TrackStep(flight=insp.flight,
                     estimate={n: float(v) for n, v in zip(FAULT_NAMES, NOMINAL)},
                     low={n: float(v) for n, v in zip(FAULT_NAMES, LOWER)},
                     high={n: float(v) for n, v in zip(FAULT_NAMES, UPPER)},
                     rul=float(rul), rul_low=float(low), rul_high=float(high),
                     failing_fault=None, replace=False, evaluations=0)


@register_tracker("rul-age", description="no-sensing reference: RUL = the unit's age "
                  "(flights), interval [0, inf]; reads no trace")
def age_factory(campaign_info: dict, seed: np.random.SeedSequence):
    def step(insp: Inspection) -> TrackStep:
        return _step(insp, float(insp.flight), 0.0, math.inf)
    return step


@register_tracker("life-table", description="no-sensing reference: the unit's age, the "
                  "fleet's life distribution from the published laws and the published cut "
                  "rule; Bayes point for +-20 % and 95 % interval; reads no trace")
def life_table_factory(campaign_info: dict, seed: np.random.SeedSequence, *,
                       alpha: float = 0.2):
    lives = fleet_lives(campaign_info["laws"])
    every = int(campaign_info["inspection_every"])
    stop = campaign_info.get("cut_rule", {}).get("stop", [0.5, 0.95])

    def step(insp: Inspection) -> TrackStep:
        c = float(insp.flight)
        w = cut_likelihood(c, lives, every, stop)
        if w.sum() <= 0:   # no life of the sample fits: survival only
            w = (lives > c).astype(float)
        if w.sum() <= 0:
            return _step(insp, math.inf, math.inf, math.inf)
        rul = lives - c
        point = best_point(rul, w, alpha)
        low, high = weighted_quantile(rul, w, [0.025, 0.975])
        return _step(insp, point, min(low, point), max(high, point))
    return step
