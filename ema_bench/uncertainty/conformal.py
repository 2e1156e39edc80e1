"""Split-conformal calibration of the interval half-widths.

The Laplace and profile intervals rest on a smooth, locally quadratic fitness; the monitor's
dry friction and backlash make it slightly rough at the scale of the noise (a stick-slip
transition moves by one integration step), and the model-form allowance rests on a few
calibration instances.  So each half-width ``h`` (noise half-width combined in quadrature with
the allowance) is multiplied by a per-fault factor: the conformal quantile of the
nonconformity scores ``|t - t_hat| / h`` of a *calibration* coverage run, in which the truth
is known (``ema-bench coverage --calibrate --out DIR``, root seed
:data:`CALIBRATION_ROOT_SEED`).  Coverage
is reported on other instances (root seed 0), so the factors are not fitted to the figures they
are judged by; for instances drawn like the calibration ones, split-conformal theory guarantees
marginal coverage of at least the level.  The scores ship as ``calibration.json``; a user
table is used only when named (``--calibration FILE`` or ``EMA_BENCH_CALIBRATION``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..faults import FAULT_NAMES
from ..interval_calibration_files import TABLES, active, check_table

#: The root seed of the calibration runs (coverage is reported at root seed 0).
CALIBRATION_ROOT_SEED = 1


def calibration_kind(track: str | None) -> str:
    """The calibration set for data from ``track``: ``twin`` for the monitor's own data,
    ``reference`` for everything the monitor did not make (the reference track, files)."""
    return "twin" if track == "twin" else "reference"


def calibration_key(kind: str, method: str, model_form: str) -> str:
    return f"{kind}|{method}|{model_form}"


TABLE = TABLES["calibration.json"]
#: The shipped table (read-only; a user table is named by ``EMA_BENCH_CALIBRATION``).
PATH = TABLE.shipped


@lru_cache(maxsize=4)
def read(path: Path) -> dict[str, object]:
    """The calibration table in ``path`` (empty scores if the file is absent); ValueError
    (one line) for a file that is not one, or one made for other faults."""
    if not path.exists():
        return {"scores": {}}
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a calibration table ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("scores"), dict):
        raise ValueError(f"{path}: not a calibration table (no 'scores' object)")
    if data.get("faults") != list(FAULT_NAMES):
        raise ValueError(f"{path} is for faults {data.get('faults')}, not {list(FAULT_NAMES)}")
    check_table(TABLE.name, data, str(path))   # every score finite and non-negative
    return data


def active_table() -> dict[str, object]:
    """The active calibration: the shipped file, or the user file named by
    ``EMA_BENCH_CALIBRATION`` (:mod:`ema_bench.interval_calibration_files`)."""
    return read(active(TABLE)[0])


def calibration_size(kind: str, method: str, model_form: str,
                     data: Mapping[str, object] | None = None) -> int:
    """How many calibration instances the active table holds for (kind, method, model form)
    (0 where it has none)."""
    data = data or active_table()
    run = data.get("runs", {}).get(calibration_key(kind, method, model_form))
    if run:
        return int(run["instances"])
    scores = data["scores"].get(calibration_key(kind, method, model_form))
    return len(next(iter(scores.values()))) if scores else 0


def conformal_quantile(scores: Iterable[float], level: float) -> float:
    """The split-conformal quantile: the ``ceil((n + 1) level)``-th smallest score (the
    largest where that index passes ``n``, which then under-covers slightly)."""
    s = np.sort(np.asarray(list(scores), dtype=float))
    if s.size == 0:
        return 1.0
    k = min(math.ceil((s.size + 1) * level), s.size)
    return float(s[k - 1])


def calibration_factor(kind: str, method: str, model_form: str, level: float,
                       data: Mapping[str, object] | None = None) -> np.ndarray | None:
    """Per-fault factors (4,) for ``level``; None where the active table has no scores for
    this (kind, method, model form): such intervals are uncalibrated, and say so."""
    scores = (data or active_table())["scores"].get(calibration_key(kind, method, model_form))
    if not scores:
        return None
    return np.array([conformal_quantile(scores[n], level) for n in FAULT_NAMES])


def score(truth: float, estimate: float, low: float, high: float) -> float:
    """Nonconformity score of one interval: the truth's distance from the estimate over the
    half-width on its side (``<= 1``: inside)."""
    half = (estimate - low) if truth < estimate else (high - estimate)
    d = abs(truth - estimate)
    return 0.0 if d == 0.0 else (d / half if half > 0 else math.inf)
