"""The one run record: what a solver run on a problem produced, as JSON.

``ema-bench solve --json`` prints it, ``ema-bench leaderboard`` appends it to ``runs.jsonl``
(one line per run), ``--check`` compares records, ``ema-bench validate`` checks them and
``ema-bench export`` converts them; their identity
(:func:`~ema_bench.leaderboard.run_store.run_identity`: solver, case, track, seed, budget, root
seed, model version) decides what is the same run.

Every record carries the suite version (``suite``), the model version and a ``manifest``
(package versions, platform, CPU, threads, git commit: :mod:`~ema_bench.manifest`).  On a
suite instance it carries the anytime view the scores are built from: ``targets`` (the
evaluation at which each fixed target was first reached: fitness targets from the suite's
best-known ``f*``, parameter targets judged at the best-so-far point) and ``best_at`` (the
best-so-far fitness at fixed budgets).

Those figures are claims; the evidence they are re-derived from (record schema 2,
``"schema": 2``) is the ``trajectory``: every improvement of the best-so-far fitness as
``[evaluation, fitness, vector]``, thinned to at most :data:`MAX_TRAJECTORY_POINTS` points
plus the points no thinning may drop (each target's first hit, the last improvement at or
before each ``best_at`` checkpoint, the first and the last improvement).  ``ema-bench
validate`` re-evaluates every trajectory vector and recomputes every figure from it and the
instance's truth (:mod:`~ema_bench.leaderboard.derive`); scores are computed from that
re-derivation, never from the claims.  Records without ``schema`` are *legacy* (schema 1):
no vectors but the final one.  ``seed_scheme`` says how the solver's seed came from the run
node (:data:`~ema_bench.seeding.SEED_SCHEMES`; absent: 1, the committed boards' spawn),
which replay needs to run the solver again.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .faults import N_FAULTS, faults_to_dict
from .manifest import manifest
from .scoring import SUCCESS_RANGE_ERROR, first_hits, improvements, range_error
from .seeding import SEED_SCHEME
from .suites import find, suite_of
from .suites.targets import (
    BUDGET_CHECKPOINTS,
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    fitness_targets,
    precision_key,
)

if TYPE_CHECKING:
    from .problem import Problem
    from .registry import SolveResult

#: Best-so-far points a legacy record's ``trace`` kept: every improvement, thinned to at most
#: this many (a legacy trace that long may have lost a target's first hit).
MAX_TRACE_POINTS = 200
#: The record schema: 2 adds ``trajectory`` (absent: a legacy record, schema 1).
RECORD_SCHEMA = 2
#: Trajectory points kept by thinning (the points that carry a target's first hit or a
#: ``best_at`` value come on top: at most 4 + 3 + 13 + 2 more).
MAX_TRAJECTORY_POINTS = 48


def schema(record: dict) -> int:
    """The record's schema version: 1 for legacy records (written before versions)."""
    return int(record.get("schema", 1))


def seed_scheme(record: dict) -> object:
    """The seed scheme the record's solver seed was derived with
    (:data:`~ema_bench.seeding.SEED_SCHEMES`): 1, the spawn, for records written before
    schemes were recorded (the committed boards)."""
    return record.get("seed_scheme", 1)


def trajectory_indices(X: np.ndarray, f: np.ndarray, truth: np.ndarray | None,
                       f_levels: list[float], ranges: np.ndarray | None = None,
                       judged: np.ndarray | None = None) -> np.ndarray:
    """0-based evaluations kept in the trajectory: the improvements, thinned geometrically to
    :data:`MAX_TRAJECTORY_POINTS`, plus every improvement no thinning may drop (the first hit
    of each fitness level in ``f_levels`` and of each parameter target against ``truth``, the
    last improvement at or before each ``best_at`` checkpoint, the first and the last).
    ``truth`` holds the faults (of fault ``ranges`` when None) or every searched parameter
    with its ``ranges``; ``judged`` masks the parameters without a parameter target."""
    idx = improvements(f)
    if idx.size <= MAX_TRAJECTORY_POINTS:
        return idx
    pos = set(np.unique(np.geomspace(1, idx.size, MAX_TRAJECTORY_POINTS).astype(int) - 1))
    pos |= {0, idx.size - 1}
    fi = f[idx]
    for level in f_levels:
        hit = np.flatnonzero(fi <= level)
        pos |= set(hit[:1].tolist())
    if truth is not None:
        err = (range_error(X[idx, :len(truth)], truth) if ranges is None else
               np.abs(X[idx, :len(truth)] - truth) / ranges)
        err = np.max(err if judged is None else err[:, judged], axis=-1)
        for level in PARAMETER_TARGETS:
            pos |= set(np.flatnonzero(err <= level)[:1].tolist())
    for b in BUDGET_CHECKPOINTS:
        before = np.flatnonzero(idx < b)
        if before.size:
            pos.add(int(before[-1]))
    return idx[sorted(pos)]


def trajectory(X: np.ndarray, f: np.ndarray, keep: np.ndarray) -> list[list]:
    """``[evaluation (1-based), fitness, vector]`` at the kept evaluations."""
    return [[int(i) + 1, float(f[i]), [float(v) for v in X[i]]] for i in keep]


def run_record(problem: Problem, result: SolveResult, *, case: str, track: str, seed: int,
               budget: int, root_seed: int, wall_s: float, info: str = "") -> dict[str, Any]:
    """The record of one finished run (deterministic apart from the wall times).

    Scoring fields (``truth``, ``success``, ``evals_to_success``, ``accuracy``,
    ``range_error``, ``fitness_at_truth``) are there when the problem has a truth."""
    rec: dict[str, Any] = {
        "key": f"{result.solver}|{case}|{track}|{seed}",
        "solver": result.solver, "case": case, "track": track, "seed": int(seed),
        "budget": int(budget), "root_seed": int(root_seed),
        "model_version": suite_of(case).model_version, "suite": suite_of(case).id,
        "manifest": manifest(sorted(result.library or {})),
        "x": faults_to_dict(result.x[:N_FAULTS]),
        "fitness": result.fitness,
        "evaluations": result.evaluations,
        "stop_reason": result.stop_reason,
        "failures": problem.failures,
        "schema": RECORD_SCHEMA,
        "seed_scheme": SEED_SCHEME,
        "wall_s": wall_s,
        "solver_wall_s": result.wall_s,
        "library": result.library,
        "info": info,
    }
    if problem.dim > N_FAULTS:
        rec["fitted_effects"] = dict(zip(problem.names[N_FAULTS:],
                                         map(float, result.x[N_FAULTS:])))
    hist = problem.history()
    best = hist["best"]
    inst = find(case)   # None: a case drawn from the seed, custom faults
    known = None if inst is None else inst.best_known(track, seed, root_seed)
    # what the parameter targets judge: the instance's frame (every searched parameter; on
    # a suite's reference track maybe fewer), else the problem's true faults
    every = ranges = judged = None
    if problem.has_truth:
        every, ranges, judged = (inst.frame(track) if inst is not None else
                                 (np.array(list(problem.score(problem.lower).truth.values())),
                                  None, None))
    precisions = FITNESS_PRECISIONS if inst is None else inst.fitness_precisions
    levels = [] if known is None else fitness_targets(known["f_star"], known["f_nominal"],
                                                      precisions)
    keep = trajectory_indices(hist["x"], hist["fitness"], every, levels, ranges, judged)
    rec["trajectory"] = trajectory(hist["x"], hist["fitness"], keep)
    # the trace is the trajectory without vectors, and the last evaluation
    rec["trace"] = [[p[0], p[1]] for p in rec["trajectory"]]
    if best.size and rec["trace"][-1][0] != best.size:
        rec["trace"].append([int(best.size), float(best[-1])])
    rec["best_at"] = [[b, float(best[b - 1])] for b in BUDGET_CHECKPOINTS if b <= best.size]
    if problem.has_truth:
        score = problem.score(result.x)
        hits = problem.parameter_hits(PARAMETER_TARGETS, judged=judged, scales=ranges)
        ok = (np.abs(result.x[:every.size] - every) / ranges <= SUCCESS_RANGE_ERROR
              if ranges is not None else None)
        success = score.success if ok is None else bool(
            np.all(ok if judged is None else ok[judged]))
        rec.update(x=score.x, truth=score.truth, fitness_at_truth=problem.fitness_at_truth(),
                   success=success,
                   evals_to_success=problem.parameter_hits(
                       (SUCCESS_RANGE_ERROR,), judged=judged, scales=ranges)[0]
                   if success else None,
                   accuracy=score.accuracy, range_error=score.range_error,
                   targets=anytime_targets(best, hits, known, precisions))
    return rec


def anytime_targets(best: np.ndarray, parameter_hits: list[int | None],
                    known: dict | None,
                    precisions: Sequence[float] = FITNESS_PRECISIONS) -> dict[str, Any]:
    """The ``targets`` field: per target level, the evaluation at which it was first
    reached (None: not reached).  ``fitness`` is None where the suite has no best-known
    ``f*`` for the instance; ``precisions``: the suite's fitness ladder."""
    out: dict[str, Any] = {"parameters": {precision_key(p): h for p, h in
                                          zip(PARAMETER_TARGETS, parameter_hits)},
                           "fitness": None}
    if known is not None:
        levels = fitness_targets(known["f_star"], known["f_nominal"], precisions)
        out["fitness"] = dict(zip(map(precision_key, precisions),
                                  first_hits(best, levels)))
        out["f_star"], out["f_nominal"] = known["f_star"], known["f_nominal"]
    return out
