"""The unit of work: one solver on one (case, track, seed) instance, and how to run it."""

from __future__ import annotations

import time
import zlib
from dataclasses import asdict, dataclass

import numpy as np

from ..problem import make_problem
from ..registry import get_solver, run_solver
from ..trace_cache import MODEL_VERSION

# best-so-far checkpoints kept per run: every improvement, thinned to at most this many
MAX_TRACE_POINTS = 200


@dataclass(frozen=True)
class Task:
    """One run.  ``seed`` indexes the instance (noise, random cases): every solver sees the
    same instance for the same (case, track, seed)."""

    solver: str
    case: str
    track: str
    seed: int
    budget: int
    root_seed: int = 0

    @property
    def key(self) -> str:
        return f"{self.solver}|{self.case}|{self.track}|{self.seed}"

    def instance_seed(self) -> np.random.SeedSequence:
        return np.random.SeedSequence(self.root_seed, spawn_key=(self.seed,))

    def solver_seed(self) -> np.random.SeedSequence:
        # a stable (not Python-hash-randomised) child per solver name
        return np.random.SeedSequence(self.root_seed,
                                      spawn_key=(self.seed, zlib.crc32(self.solver.encode())))


def make_tasks(solvers, cases, tracks, seeds: int, budget: int, root_seed: int = 0,
               shard: tuple[int, int] = (0, 1)) -> list[Task]:
    """Every (solver, case, track, seed) run, in a fixed order; ``shard=(i, n)`` keeps the
    i-th of n interleaved slices (0-based) so n machines can share a sweep."""
    i, n = shard
    if not (n >= 1 and 0 <= i < n):
        raise ValueError(f"shard must be i/n with 0 <= i < n, got {i}/{n}")
    for s in solvers:
        get_solver(s)  # unknown names fail before anything runs
    all_tasks = [Task(s, c, t, k, budget, root_seed)
                 for t in tracks for c in cases for s in solvers for k in range(seeds)]
    return all_tasks[i::n]


def _thin_trace(best: np.ndarray) -> list[list[float]]:
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


def run_task(task: Task) -> dict:
    """Run one task and return its JSON record (deterministic apart from ``wall_s``)."""
    t0 = time.perf_counter()
    problem = make_problem(task.case, track=task.track, seed=task.instance_seed(),
                           budget=task.budget)
    result = run_solver(task.solver, problem, task.budget, seed=task.solver_seed())
    hist = problem.history()
    score = problem.score(result.x)
    first = problem.first_success()
    return {
        "key": task.key,
        **asdict(task),
        "model_version": MODEL_VERSION,
        "x": score.x,
        "truth": score.truth,
        "fitness": result.fitness,
        "fitness_at_truth": problem.fitness_at_truth(),
        "evaluations": result.evaluations,
        "stop_reason": result.stop_reason,
        "success": score.success,
        "evals_to_success": first,
        "accuracy": score.accuracy,
        "range_error": score.range_error,
        "failures": problem.failures,
        "trace": _thin_trace(hist["best"]),
        "wall_s": time.perf_counter() - t0,
        "solver_wall_s": result.wall_s,
        "library": result.library,
        "info": get_solver(task.solver).library,
    }
