"""The one run record: what a solver run on a problem produced, as JSON.

``ema-bench solve --json`` prints it, ``ema-bench leaderboard`` appends it to ``runs.jsonl``
(one line per run), ``--check`` compares records, ``ema-bench validate`` checks them and
``ema-bench export`` converts them; their identity
(:func:`~ema_bench.leaderboard.store.run_identity`: solver, case, track, seed, budget, root
seed, model version) decides what is the same run.

Every record carries the suite version (``suite``), the model version and a ``manifest``
(package versions, platform, CPU, threads, git commit: :mod:`~ema_bench.manifest`).  On a
suite instance it carries the anytime view the scores are built from: ``targets`` (the
evaluation at which each fixed target was first reached: fitness targets from the suite's
best-known ``f*``, parameter targets judged at the best-so-far point) and ``best_at`` (the
best-so-far fitness at fixed budgets).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .faults import N_FAULTS, faults_to_dict
from .manifest import manifest
from .scoring import first_hits
from .suite import (
    BUDGET_CHECKPOINTS,
    FITNESS_PRECISIONS,
    PARAMETER_TARGETS,
    SUITE_ID,
    best_known,
    fitness_targets,
    precision_key,
)
from .trace_cache import MODEL_VERSION

if TYPE_CHECKING:
    from .problem import Problem
    from .registry import SolveResult

# best-so-far checkpoints kept per run: every improvement, thinned to at most this many
MAX_TRACE_POINTS = 200


def thin_trace(best: np.ndarray) -> list[list[float]]:
    """``[evaluation, best-so-far]`` at each improvement (and the last evaluation)."""
    if best.size == 0:
        return []
    idx = np.flatnonzero(np.r_[True, best[1:] < best[:-1]])
    if idx.size > MAX_TRACE_POINTS:
        keep = np.unique(np.geomspace(1, idx.size, MAX_TRACE_POINTS).astype(int) - 1)
        idx = idx[keep]
    if idx[-1] != best.size - 1:
        idx = np.r_[idx, best.size - 1]
    return [[int(i) + 1, float(best[i])] for i in idx]


def run_record(problem: Problem, result: SolveResult, *, case: str, track: str, seed: int,
               budget: int, root_seed: int, wall_s: float, info: str = "") -> dict[str, Any]:
    """The record of one finished run (deterministic apart from the wall times).

    Scoring fields (``truth``, ``success``, ``evals_to_success``, ``accuracy``,
    ``range_error``, ``fitness_at_truth``) are there when the problem has a truth."""
    rec: dict[str, Any] = {
        "key": f"{result.solver}|{case}|{track}|{seed}",
        "solver": result.solver, "case": case, "track": track, "seed": int(seed),
        "budget": int(budget), "root_seed": int(root_seed), "model_version": MODEL_VERSION,
        "suite": SUITE_ID, "manifest": manifest(sorted(result.library or {})),
        "x": faults_to_dict(result.x[:N_FAULTS]),
        "fitness": result.fitness,
        "evaluations": result.evaluations,
        "stop_reason": result.stop_reason,
        "failures": problem.failures,
        "trace": thin_trace(problem.history()["best"]),
        "wall_s": wall_s,
        "solver_wall_s": result.wall_s,
        "library": result.library,
        "info": info,
    }
    if problem.dim > N_FAULTS:
        rec["fitted_effects"] = dict(zip(problem.names[N_FAULTS:],
                                         map(float, result.x[N_FAULTS:])))
    best = problem.history()["best"]
    rec["best_at"] = [[b, float(best[b - 1])] for b in BUDGET_CHECKPOINTS if b <= best.size]
    if problem.has_truth:
        score = problem.score(result.x)
        hits = problem.parameter_hits(PARAMETER_TARGETS)
        rec.update(x=score.x, truth=score.truth, fitness_at_truth=problem.fitness_at_truth(),
                   success=score.success,
                   evals_to_success=problem.first_success() if score.success else None,
                   accuracy=score.accuracy, range_error=score.range_error,
                   targets=anytime_targets(best, hits, best_known(case, track, seed,
                                                                  root_seed)))
    return rec


def anytime_targets(best: np.ndarray, parameter_hits: list[int | None],
                    known: dict | None) -> dict[str, Any]:
    """The ``targets`` field: per target level, the evaluation at which it was first
    reached (None: not reached).  ``fitness`` is None where the suite has no best-known
    ``f*`` for the instance."""
    out: dict[str, Any] = {"parameters": {precision_key(p): h for p, h in
                                          zip(PARAMETER_TARGETS, parameter_hits)},
                           "fitness": None}
    if known is not None:
        levels = fitness_targets(known["f_star"], known["f_nominal"])
        out["fitness"] = dict(zip(map(precision_key, FITNESS_PRECISIONS),
                                  first_hits(best, levels)))
        out["f_star"], out["f_nominal"] = known["f_star"], known["f_nominal"]
    return out
