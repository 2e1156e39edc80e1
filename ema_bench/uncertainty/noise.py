"""The noise level of a fit: what the sensors' datasheet says, and what the residuals say.

The sensors add white noise of ``noise_frac`` of their span and quantise to 12 bits
(:mod:`~ema_bench.physics.sensors`); the quantisation error of a noisy signal is uniform over
one step, so each sample carries variance ``noise_std**2 + lsb**2 / 12``.  A residual level
well above that means the model misses something (model-form error on the reference track),
and intervals from the datasheet noise alone would be too narrow.
"""

from __future__ import annotations

import numpy as np

from ..objective import Objective
from ..physics.sensors import SENSORS
from ..traces import SIGNALS


def known_sigma() -> np.ndarray:
    """Per-signal standard deviation of the sensors' error (noise and ADC), shape (4,),
    ``SIGNALS`` order and canonical units."""
    return np.array([np.hypot(s.noise_std, s.lsb / np.sqrt(12.0)) for s in SENSORS])


def weighed(objective: Objective) -> np.ndarray:
    """Per residual element (stacked layout), whether the fitness weighs its output (all,
    unless an information condition of suite ``emafdi-v2`` masks some: ``objective.mask``,
    or a robust loss rejects them: ``objective.rejected``)."""
    mask = getattr(objective, "mask", None)   # objective-like test models carry none
    idx = objective.signal_index
    seen = np.ones(idx.size, bool) if mask is None else np.asarray(mask)[idx] > 0.0
    # samples a robust loss rejects (the diagnosis's heavy-tailed noise) are no noise sample
    rejected = getattr(objective, "rejected", None)
    return seen if rejected is None else seen & ~rejected


def estimated_sigma(objective: Objective, residual: np.ndarray, n_params: int) -> np.ndarray:
    """Per-signal standard deviation of the raw residual ``model - data`` (stacked layout),
    shape (4,): the root mean square over that signal's samples, degrees of freedom
    corrected for the ``n_params`` fitted parameters (shared out by sample count).  Only
    weighted elements count; a signal the fitness does not weigh (an information condition
    of suite ``emafdi-v2``: its data are withheld) gets the datasheet level
    (:func:`known_sigma`), which no interval then uses."""
    seen = weighed(objective)
    idx = objective.signal_index[seen]
    n = np.bincount(idx, minlength=len(SIGNALS)).astype(float)
    ss = np.bincount(idx, weights=residual[seen] ** 2, minlength=len(SIGNALS))
    dof = np.maximum(n * (1.0 - n_params / max(idx.size, 1)), 1.0)
    return np.where(n > 0, np.sqrt(ss / dof), known_sigma())
