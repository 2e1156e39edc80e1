"""Red-team solvers, installed as a plugin (an entry point of ``ema_bench.solvers``) only by
the tests that put this folder on ``sys.path``: replay runs solvers in worker processes, which
find them the way they find any submitted plugin."""

from __future__ import annotations

import gc

import numpy as np

from ema_bench import make_problem, register_solver
from ema_bench.faults import FAULT_NAMES
from ema_bench.problem import Problem
from ema_bench.registry import SolveResult


@register_solver("rt-truth-peeker", description="reads the truth from memory", library="numpy")
def truth_peeker(problem, budget, seed):
    """Walks the garbage collector to the truthful problem behind its view."""
    for obj in gc.get_objects():
        if isinstance(obj, Problem) and obj.measured is problem.measured and obj.has_truth:
            truth = obj.score(obj.nominal).truth
            problem.evaluate(np.array([truth[n] for n in FAULT_NAMES]))
            break
    else:
        problem.evaluate(problem.start)
    x, f = problem.best
    return SolveResult("rt-truth-peeker", x, f, problem.evaluations, "done", 0.0, {})


@register_solver("rt-private-objective", description="searches a private copy of the objective",
                 library="numpy")
def private_objective(problem, budget, seed):
    """Builds an uncounted copy of the objective from the public API and searches it; the
    record shows one evaluation, the best of the private search."""
    copy = make_problem(measured=problem.measured, budget=10**6)
    rng = np.random.default_rng(seed)
    X = problem.start + 0.05 * (problem.upper - problem.lower) * rng.uniform(-1, 1, (6, 4))
    X = np.clip(X, problem.lower, problem.upper)
    f = copy.evaluate(X)
    problem.evaluate(X[int(np.argmin(f))])
    x, fx = problem.best
    return SolveResult("rt-private-objective", x, fx, problem.evaluations, "done", 0.0, {})
