"""Split-conformal calibration of the named effects' intervals.

The workflow's interval of a named effect (:func:`~ema_bench.diagnosis.fitting.interval`) is
a profile-likelihood interval: it counts the sensor noise (estimated from the residuals), not
the model-form bias of data the monitor did not make.  On the reference model the fit of the
right effect set lies off the truth by a few noise widths in a few cases (a near-threshold
delay of 0.584 ms fitted at 0.575 ms with a 2.2 us half-width), so 38 of 44 named true
effects of the blind suite of seed 6988 were covered, 86 % of a 95 % interval.

Each half-width is therefore multiplied by one factor: the split-conformal quantile
(:func:`~ema_bench.uncertainty.conformal.conformal_quantile`) of the nonconformity scores
``|t - t_hat| / h`` (:func:`~ema_bench.uncertainty.conformal.score`) of *calibration* cases:
the effect cases (single, near-threshold, two-effect) of a blind suite drawn at root seed
:data:`CALIBRATION_SEED`, whose right effect set is fitted as the workflow fits it (base fit,
then the set warm-started at the base faults and each effect's screening step).  Blind suites
are reported at other seeds, so the factor is not fitted to the coverage it is judged by.  One
factor is pooled over effects (a handful of cases per effect is too few for a quantile of its
own), so the guarantee is marginal over the blind suite's mix of effects; it is never below 1
(the profile interval of the noise alone is the narrowest honest one).  The scores ship as
``interval_calibration.json`` (read by :mod:`~ema_bench.diagnosis.interval_table`);
``ema-bench blind --calibrate --out DIR`` recomputes them into DIR/interval_calibration.json.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..interval_calibration_files import inside_package
from ..jsonio import write_atomic
from ..objective import N_FAULTS
from ..seeding import run_seed, stream
from ..uncertainty.conformal import conformal_quantile, score
from .fitting import effect_spec, fit, profile, subset_traces
from .interval_table import TABLE, read
from .results import HOLDOUT, TRAIN, Settings

#: The shipped table (read-only: :func:`calibrate` writes a user file).
PATH = TABLE.shipped
#: Root seed of the calibration cases (blind suites are reported at other seeds).
CALIBRATION_SEED = 1


def case_scores(case, seed: int, settings: Settings) -> dict:
    """Fit a calibration case's true effect set as the workflow would and score the
    uncalibrated 95 % interval of each of its effects (a :func:`~ema_bench.diagnosis.blind.
    run_cases` runner)."""
    from .blind import measured_traces

    measured = subset_traces(measured_traces(case, seed), TRAIN + HOLDOUT)
    measured = measured.with_meta(faults=None, effects=None)
    node = stream(run_seed(seed, case.index), "diagnosis")
    base = fit(measured, (), settings, stream(node, "fit", 0, 0))
    names = tuple(sorted(case.effects))
    start = np.r_[base.x[:N_FAULTS],
                  [np.clip(effect_spec(n).detect, effect_spec(n).lower, effect_spec(n).upper)
                   for n in names]]
    f = fit(measured, names, settings, stream(node, "fit", 1, 1), start)
    iv = profile(f, measured, names)
    rows = []
    for n in names:
        i = N_FAULTS + names.index(n)
        est, low, high = (float(v[i]) for v in (iv.estimate, iv.low, iv.high))
        truth = case.effects[n]
        rows.append({"case": case.index, "category": case.category, "effect": n,
                     "truth": truth, "estimate": est, "low": low, "high": high,
                     "score": score(truth, est, low, high)})
    return {"index": case.index, "rows": rows}


def calibrate(path: Path | str, cases: int = 60, workers: int = 1,
              seed: int = CALIBRATION_SEED, quiet: bool = True) -> dict:
    """Score the effect cases among the first ``cases`` of the blind suite of root ``seed``
    and write the scores to the user file ``path`` (about 15 CPU-seconds per case).

    ValueError for a path inside the package: the shipped table is replaced only by
    ``python -m ema_bench.interval_calibration_files``, in a checkout."""
    if inside_package(path):
        raise ValueError(f"{path}: inside the package, whose data is read-only")
    from .blind import draw_cases, run_cases

    todo = [c for c in draw_cases(cases, seed) if c.kind == "effect"]
    rows = [row for rec in run_cases(todo, seed, Settings(), workers, case_scores,
                                     label="interval calibration", quiet=quiet)
            for row in rec["rows"]]
    rows.sort(key=lambda r: (r["case"], r["effect"]))
    data = {"root_seed": seed, "suite_cases": cases, "effect_cases": len(todo),
            "factor_95": max(1.0, conformal_quantile([r["score"] for r in rows], 0.95)),
            "scores": rows}
    write_atomic(Path(path), json.dumps(data, indent=1) + "\n")
    read.cache_clear()
    return data
