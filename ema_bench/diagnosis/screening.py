"""Which library effect explains the residuals best: a linearised score test.

For each effect, the change of the whitened training outputs per unit of the effect
(finite difference at the fitted point) is projected off the directions the four faults can
already move (they will be refitted); the score is the drop of the sum of squared whitened
residuals a least-squares step along what is left would give (chi-square with 1 degree of
freedom under the null).  One-sided effects (lower bound 0) score 0 when the residual asks for
a negative value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import EFFECT_NAMES, EFFECTS
from .features import whiten


@dataclass(frozen=True)
class Candidate:
    name: str
    score: float       # SSE drop (whitened), chi2(1) under the null
    step: float        # linearised estimate of the effect value, its unit
    signature: str


def stack(outputs: dict[str, np.ndarray], tests: tuple[str, ...]) -> np.ndarray:
    """Whitened outputs of the given tests as one vector; ``outputs[t]`` is (k, n, 4)."""
    return np.concatenate([whiten(outputs[t]).reshape(outputs[t].shape[0], -1)
                           for t in tests], axis=1)


def score_effects(residual: np.ndarray, base: np.ndarray, fault_jac: np.ndarray,
                  effect_cols: dict[str, tuple[np.ndarray, float]]) -> list[Candidate]:
    """Rank effects.

    Parameters
    ----------
    residual : whitened measured-minus-model vector (training tests).
    base : whitened model outputs at the fit (same layout).
    fault_jac : (m, k) whitened output changes for small steps of the fitted parameters.
    effect_cols : effect -> (whitened outputs with the effect stepped by ``h``, ``h``).
    """
    q, _ = np.linalg.qr(fault_jac)
    out = []
    for name, (outputs, h) in effect_cols.items():
        j = (outputs - base) / h
        j_perp = j - q @ (q.T @ j)
        den = float(j_perp @ j_perp)
        if den <= 0.0:
            out.append(Candidate(name, 0.0, 0.0, EFFECTS[EFFECT_NAMES.index(name)].signature))
            continue
        step = float(residual @ j_perp) / den
        spec = EFFECTS[EFFECT_NAMES.index(name)]
        score = step**2 * den
        if spec.lower >= 0.0 and step < 0.0:
            score = 0.0
        out.append(Candidate(name, score, step, spec.signature))
    return sorted(out, key=lambda c: -c.score)
