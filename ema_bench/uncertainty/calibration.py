"""Split-conformal calibration of the interval half-widths.

The Laplace and profile intervals rest on a smooth, locally quadratic fitness; the monitor's
dry friction and backlash make it slightly rough at the scale of the noise (a stick-slip
transition moves by one integration step), and the model-form allowance rests on a few
calibration instances.  So each half-width ``h`` (noise half-width combined in quadrature with
the allowance) is multiplied by a per-fault factor: the conformal quantile of the
nonconformity scores ``|t - t_hat| / h`` of a *calibration* coverage run, in which the truth
is known (``ema-bench coverage --calibrate``, root seed :data:`CALIBRATION_ROOT_SEED`).  Coverage
is reported on other instances (root seed 0), so the factors are not fitted to the figures they
are judged by; for instances drawn like the calibration ones, split-conformal theory guarantees
marginal coverage of at least the level.  The scores ship as ``calibration.json``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..faults import FAULT_NAMES

PATH = Path(__file__).with_name("calibration.json")
#: The root seed of the calibration runs (coverage is reported at root seed 0).
CALIBRATION_ROOT_SEED = 1


def calibration_kind(track: str | None) -> str:
    """The calibration set for data from ``track``: ``twin`` for the monitor's own data,
    ``reference`` for everything the monitor did not make (the reference track, files)."""
    return "twin" if track == "twin" else "reference"


def calibration_key(kind: str, method: str, model_form: str) -> str:
    return f"{kind}|{method}|{model_form}"


@lru_cache(maxsize=1)
def shipped() -> dict[str, object]:
    """The shipped calibration (empty scores if the file is absent)."""
    if not PATH.exists():
        return {"scores": {}}
    data = json.loads(PATH.read_text())
    if data.get("faults") != list(FAULT_NAMES):
        raise ValueError(f"{PATH} is for faults {data.get('faults')}, not {list(FAULT_NAMES)}")
    return data


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
    """Per-fault factors (4,) for ``level``; None where the shipped file has no scores for
    this (kind, method, model form): such intervals are uncalibrated, and say so."""
    scores = (data or shipped())["scores"].get(calibration_key(kind, method, model_form))
    if not scores:
        return None
    return np.array([conformal_quantile(scores[n], level) for n in FAULT_NAMES])


def score(truth: float, estimate: float, low: float, high: float) -> float:
    """Nonconformity score of one interval: the truth's distance from the estimate over the
    half-width on its side (``<= 1``: inside)."""
    half = (estimate - low) if truth < estimate else (high - estimate)
    d = abs(truth - estimate)
    return 0.0 if d == 0.0 else (d / half if half > 0 else math.inf)
