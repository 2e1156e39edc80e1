"""The one run record: what a solver run on a problem produced, as JSON.

``ema-bench solve --json`` prints it, ``ema-bench leaderboard`` appends it to ``runs.jsonl``
(one line per run), ``--check`` compares records, and their identity
(:func:`~ema_bench.leaderboard.store.run_identity`: solver, case, track, seed, budget, root
seed, model version) decides what is the same run.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .faults import N_FAULTS, faults_to_dict
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
    if problem.has_truth:
        score = problem.score(result.x)
        rec.update(x=score.x, truth=score.truth, fitness_at_truth=problem.fitness_at_truth(),
                   success=score.success, evals_to_success=problem.first_success(),
                   accuracy=score.accuracy, range_error=score.range_error)
    return rec
