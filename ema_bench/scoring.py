"""Scoring of an estimate against the truth (for the scorer, never for solvers): the paper's
accuracy, the range-normalised error and the success rule."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .faults import FAULT_NAMES, LOWER, UPPER, faults_to_dict

SUCCESS_RANGE_ERROR = 0.01  # a run succeeds when every parameter is within 1 % of its range


@dataclass(frozen=True)
class Score:
    """How close an estimate is to the truth (for the scorer, not for solvers)."""

    x: dict[str, float]
    truth: dict[str, float]
    accuracy: dict[str, float | None]   # paper formula, %, None where true = 0 and est != 0
    range_error: dict[str, float]       # |est - true| / (upper - lower)
    success: bool                       # every range error <= 1 %

    def as_dict(self) -> dict[str, object]:
        return {"x": self.x, "truth": self.truth, "accuracy": self.accuracy,
                "range_error": self.range_error, "success": self.success}


def paper_accuracy(est: np.ndarray, true: np.ndarray) -> list[float | None]:
    """The paper's ``100 (1 - |est - true| / |true|)`` per parameter, in %.

    Where the true value is 0 the formula is undefined: 100 if the estimate is exactly 0,
    else ``None`` (use the range-normalised error there)."""
    out: list[float | None] = []
    for e, t in zip(est, true):
        if t == 0.0:
            out.append(100.0 if e == 0.0 else None)
        else:
            out.append(float(100.0 * (1.0 - abs(e - t) / abs(t))))
    return out


def range_error(est: np.ndarray, true: np.ndarray) -> np.ndarray:
    """``|est - true| / (upper - lower)`` per parameter (defined when the truth is 0)."""
    return np.abs(np.asarray(est, float) - np.asarray(true, float)) / (UPPER - LOWER)


def successes(est: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Per row of ``est`` (n, 4): every parameter within 1 % of its range of ``true``."""
    return np.all(range_error(est, true) <= SUCCESS_RANGE_ERROR, axis=-1)


def score(est: np.ndarray, true: np.ndarray) -> Score:
    """The :class:`Score` of one estimate (faults, physical units)."""
    err = range_error(est, true)
    return Score(x=faults_to_dict(est), truth=faults_to_dict(true),
                 accuracy=dict(zip(FAULT_NAMES, paper_accuracy(est, true))),
                 range_error=dict(zip(FAULT_NAMES, map(float, err))),
                 success=bool(np.all(err <= SUCCESS_RANGE_ERROR)))


def first_hits(best: np.ndarray, thresholds: Sequence[float]) -> list[int | None]:
    """For each threshold, the evaluation (1-based) at which the best-so-far fitness ``best``
    (non-increasing, one entry per evaluation) first reaches ``<= threshold``, or None."""
    best = np.asarray(best, dtype=float)
    out: list[int | None] = []
    for thr in thresholds:
        hit = np.flatnonzero(best <= thr)
        out.append(int(hit[0]) + 1 if hit.size else None)
    return out


def improvements(f: np.ndarray) -> np.ndarray:
    """Indices of the evaluations that improved the best-so-far fitness (the first counts):
    from each one on, the best-so-far point is that evaluation's point."""
    f = np.asarray(f, dtype=float)
    if f.size == 0:
        return np.empty(0, dtype=int)
    prev = np.r_[np.inf, np.minimum.accumulate(f)[:-1]]
    return np.flatnonzero(f < prev)


def parameter_hits(X: np.ndarray, f: np.ndarray, true: np.ndarray,
                   levels: Sequence[float], ranges: np.ndarray | None = None,
                   judged: np.ndarray | None = None) -> list[int | None]:
    """For each level, the evaluation (1-based) from which the best-so-far point (the point
    a solver would report: lowest fitness so far) first has every fault within ``level`` of
    its range of ``true``, or None.  Judged at the best-so-far point, not at any evaluated
    point: a solver that passes near the truth without noticing is not credited.

    ``true`` holds the four faults, or every searched parameter (then ``ranges`` gives their
    ranges, physical units); ``judged`` (bool, one per value of ``true``) leaves out the
    parameters that carry no parameter target (default: all judged)."""
    true = np.asarray(true, dtype=float)
    rng = (UPPER - LOWER) if ranges is None else np.asarray(ranges, dtype=float)[:len(true)]
    keep = np.ones(len(true), dtype=bool) if judged is None else np.asarray(judged, bool)
    if not keep.any():
        return [None for _ in levels]
    idx = improvements(f)
    err = np.max((np.abs(np.asarray(X)[idx, :len(true)] - true) / rng)[:, keep], axis=-1) \
        if idx.size else np.empty(0)
    out: list[int | None] = []
    for level in levels:
        hit = np.flatnonzero(err <= level)
        out.append(int(idx[hit[0]]) + 1 if hit.size else None)
    return out
