"""Every derived figure of a run record, recomputed from its evidence and the instance's truth.

The one re-derivation behind ``ema-bench validate`` (:mod:`.validate`), the success table
(:mod:`.scores`) and the anytime scores (:mod:`.anytime`): a record's own claims (``success``,
``evals_to_success``, ``accuracy``, ``range_error``, ``targets``, ``best_at``) are never read
here, so a record scores the same everywhere, and a record whose claims disagree with this is
refused by ``validate``.  The truth comes from the suite (:func:`truth_of`), ``f*`` from the
shipped targets, never from the record.

Evidence by schema (:func:`~ema_bench.records.schema`):

- **schema 2**: the ``trajectory`` (every kept improvement with its vector; thinning never
  drops a target's first hit nor a ``best_at`` point), so every figure is exact.  That the
  trajectory's vectors have the fitness it states is :mod:`.validate`'s re-evaluation.
- **legacy** (schema 1, no trajectory): the ``trace`` (best-so-far fitness at each
  improvement, thinned geometrically to :data:`~ema_bench.records.MAX_TRACE_POINTS` points) and
  the final vector ``x``.  Fitness-target hits and ``best_at`` come from the trace (exact
  unless it was thinned; then the first trace point that reaches a target, the latest the hit
  can be).  Parameter-target hits cannot be re-derived without the vectors: they are credited
  conservatively, at the evaluation where the final vector was found (the last improvement)
  when the final vector lies within the target, else as missed; ``evals_to_success`` likewise.
  A legacy run is therefore never credited earlier than its evidence shows; replay
  (``validate --replay``) is what verifies a legacy record's claimed parameter hits.

A record whose ``budget`` is below its ``evaluations`` (``--check`` re-scores committed runs at
a smaller budget that way, :func:`~.check.truncate`) is derived from its evidence up to the
budget: exact for schema 2; a legacy run cut before its final vector was found has no known
vector there, so it is scored as unsuccessful with no parameter hit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..faults import FAULT_NAMES, LOWER, N_FAULTS, UPPER
from ..params import MODEL_PARAMS, EMAParams, model_params
from ..records import schema
from ..scoring import SUCCESS_RANGE_ERROR, paper_accuracy, range_error
from ..suites import find
from ..suites.targets import (
    BUDGET_CHECKPOINTS,
    PARAMETER_TARGETS,
    fitness_targets,
    precision_key,
)
from .run_store import is_error, model_version


class DerivationError(ValueError):
    """The record lacks the evidence a figure is derived from (a one-line reason)."""


@dataclass(frozen=True)
class Derived:
    """The figures of one record, re-derived from its evidence.

    ``fitness_hits`` / ``parameter_hits``: target key (``1e-2``, ``0.01``) -> evaluation of the
    first hit (None: missed); ``fitness_hits`` is None where the suite has no ``f*``.
    ``exact``: the figures are the run's own (schema 2, or a legacy trace never thinned);
    otherwise (legacy) hits are the latest the evidence allows."""

    schema: int
    error: bool
    success: bool
    evals_to_success: int | None
    accuracy: dict[str, float | None] | None
    range_error: dict[str, float] | None
    fitness_hits: dict[str, int | None] | None
    parameter_hits: dict[str, int | None]
    best_at: list[list[float]]
    f_star: float | None
    f_nominal: float | None
    fitness: float | None           # the final best-so-far fitness of the evidence
    last_improvement: int | None    # evaluation where the final vector was first evaluated


_NO_HITS = dict.fromkeys(map(precision_key, PARAMETER_TARGETS))


def params_of(record: dict) -> EMAParams:
    """The models' parameters of the record's own model version, which replay re-runs it on
    and re-evaluation re-evaluates it on (version 2's libm trigonometry moves tier-12
    outputs at the rounding level, which a finite-difference solver magnifies into another
    path); ValueError, one line, for a version this installation cannot build."""
    v = model_version(record)
    try:
        return model_params(v)
    except KeyError:
        raise ValueError(f"model version {v!r}: this installation builds versions "
                         f"{', '.join(sorted(MODEL_PARAMS))}") from None


def best_known_of(record: dict) -> dict | None:
    """The best-known entry a record is judged on: its instance's, at the record's track,
    seed, root seed and model version (:meth:`~ema_bench.suites.base.Instance.best_known`),
    never the record's own claim; None where the suite has no fixed target."""
    inst = find(str(record["case"]))
    return None if inst is None else inst.best_known(
        str(record["track"]), int(record["seed"]), int(record.get("root_seed") or 0),
        model_version(record))


def truth_of(record: dict) -> np.ndarray:
    """The true faults of the record's instance, from the suite (or, for a case drawn from the
    seed, the rebuilt instance), never from the record."""
    return frame_of(record)[0][:N_FAULTS]


@lru_cache(maxsize=256)
def _rebuilt_truth(case: str, track: str, seed: int, root_seed: int) -> np.ndarray:
    from ..seeding import run_seed
    from ..suites.problem import make_problem

    p = make_problem(case, track=track, seed=run_seed(root_seed, seed), budget=1)
    return np.array([p.score(p.nominal).truth[n] for n in FAULT_NAMES])


def frame_of(record: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Truth, ranges and judged mask of the parameters the record's parameter targets and
    success judge: the instance's frame (:meth:`~ema_bench.suites.base.Instance.frame`: every
    searched parameter, on a suite's reference track maybe fewer, from the shipped table,
    never the record), or the faults of a case drawn from the seed, rebuilt."""
    inst = find(record["case"])
    if inst is None:
        truth = _rebuilt_truth(record["case"], record["track"], int(record["seed"]),
                               int(record.get("root_seed", 0)))
        return truth, UPPER - LOWER, np.ones(N_FAULTS, bool)
    truth, ranges, judged = inst.frame(record["track"])
    return truth, ranges, np.ones(truth.size, bool) if judged is None else judged


def _points(record: dict) -> tuple[list[int], list[float], list[np.ndarray] | None]:
    """Evaluations, fitness and (schema 2) vectors of the record's evidence."""
    exact = schema(record) >= 2
    name = "trajectory" if exact else "trace"
    tr = record.get(name)
    if not isinstance(tr, list) or not tr:
        raise DerivationError(f"{'schema-2' if exact else 'legacy'} record without a {name}")
    try:
        return ([int(p[0]) for p in tr], [float(p[1]) for p in tr],
                [np.asarray(p[2], dtype=float) for p in tr] if exact else None)
    except (TypeError, ValueError, IndexError) as exc:
        raise DerivationError(f"malformed {name} ({exc})") from None


def _first(values: list[bool], ev: list[int]) -> int | None:
    return next((e for e, ok in zip(ev, values) if ok), None)


def derive(record: dict) -> Derived:
    """The record's figures from its evidence (:class:`Derived`); DerivationError if the
    evidence is missing or malformed.  An error record reached nothing."""
    s = schema(record)
    if is_error(record):
        return Derived(s, True, False, None, None, None, None, dict(_NO_HITS), [], None,
                       None, None, None)
    ev, fit, vecs = _points(record)
    n_eval = int(record.get("evaluations", ev[-1]))
    # a record re-scored at a smaller budget (``--check``'s truncation): its evidence up to it
    cut = min(int(record.get("budget", n_eval)), n_eval)
    keep = [i for i, e in enumerate(ev) if e <= cut] or [0]
    ev, fit = [ev[i] for i in keep], [fit[i] for i in keep]
    vecs = None if vecs is None else [vecs[i] for i in keep]
    every, ranges, judged = frame_of(record)   # parameter targets and success judge these
    truth = every[:N_FAULTS]
    if vecs is not None:
        final = vecs[-1][:N_FAULTS]
    else:
        try:
            final = np.array([float(record["x"][n]) for n in FAULT_NAMES])
        except (KeyError, TypeError, ValueError) as exc:
            raise DerivationError(f"final vector x unreadable ({exc})") from None
    err = range_error(final, truth)
    inst, known = find(record["case"]), best_known_of(record)
    # improvements only: a legacy trace ends with the last evaluation, which may repeat
    imp = [i for i in range(len(fit)) if i == 0 or fit[i] < fit[i - 1]]
    last = ev[imp[-1]]
    # legacy, cut before the final vector was found: the vector at the cut is unknown
    known_final = True
    if vecs is None:
        full_imp = [p[0] for i, p in enumerate(record["trace"])
                    if i == 0 or p[1] < record["trace"][i - 1][1]]
        known_final = full_imp[-1] <= cut
    f_hits = None
    if known is not None:
        levels = fitness_targets(known["f_star"], known["f_nominal"], inst.fitness_precisions)
        f_hits = {precision_key(p): _first([f <= lv for f in fit], ev)
                  for p, lv in zip(inst.fitness_precisions, levels)}
    if vecs is not None:
        worst = [float(np.max((np.abs(v[:every.size] - every) / ranges)[judged]))
                 for v in vecs]
        p_hits = {precision_key(p): _first([w <= p for w in worst], ev)
                  for p in PARAMETER_TARGETS}
    else:   # legacy: the final vector, from where it was found (the latest it can be)
        p_hits = {precision_key(p): (last if known_final and float(np.max(err)) <= p
                                     else None) for p in PARAMETER_TARGETS}
    err_all = err if vecs is None else (np.abs(vecs[-1][:every.size] - every) / ranges)[judged]
    success = bool(np.all(err_all <= SUCCESS_RANGE_ERROR)) and known_final
    best_at = [[b, next(f for e, f in zip(reversed(ev), reversed(fit)) if e <= b)]
               for b in BUDGET_CHECKPOINTS if ev[0] <= b <= cut]
    return Derived(
        schema=s, error=False, success=success,
        evals_to_success=p_hits[precision_key(SUCCESS_RANGE_ERROR)] if success else None,
        accuracy=dict(zip(FAULT_NAMES, paper_accuracy(final, truth))),
        range_error=dict(zip(FAULT_NAMES, map(float, err))),
        fitness_hits=f_hits, parameter_hits=p_hits, best_at=best_at,
        f_star=None if known is None else known["f_star"],
        f_nominal=None if known is None else known["f_nominal"],
        fitness=fit[imp[-1]], last_improvement=last)


# A board is scored several times over (tables, page, summary): derive each record once.
_MEMO: dict[int, tuple[dict, Derived]] = {}
_MEMO_MAX = 200_000


def derived(record: dict) -> Derived:
    """:func:`derive`, memoised per record object (records are not modified after reading;
    the memo keeps the record alive so its id is not reused)."""
    hit = _MEMO.get(id(record))
    if hit is not None and hit[0] is record:
        return hit[1]
    d = derive(record)
    if len(_MEMO) >= _MEMO_MAX:
        _MEMO.clear()
    _MEMO[id(record)] = (record, d)
    return d


def precision(d: Derived, budget: int, evaluations: int) -> float:
    """Best-so-far precision ``(f - f*) / (f_nominal - f*)`` after ``budget`` evaluations, from
    the derived ``best_at`` (the last checkpoint at or before ``budget``) or the final fitness
    once the run has stopped; nan without ``f*``, for an error record or before the first
    checkpoint."""
    if d.error or d.f_star is None:
        return math.nan
    if budget >= evaluations:
        f = d.fitness
    else:
        pts = [f for b, f in d.best_at if b <= budget]
        if not pts:
            return math.nan
        f = pts[-1]
    return (f - d.f_star) / (d.f_nominal - d.f_star)
