"""Differential evolution (scipy ``differential_evolution``), vectorised, in [0, 1]^dim.

``vectorized=True`` with ``updating="deferred"``: scipy hands the objective a whole generation
(shape ``(dim, S)``) and that is one ``problem.evaluate`` call.  Scipy counts those *calls*,
not points, so ``maxiter`` is computed from the budget and the population size; the objective
evaluates only what the problem has left of the last generation and then raises a private
``StopSolver`` out of scipy.  ``polish=False`` (the L-BFGS-B polish would spend evaluations
scipy does not budget for).  Initial population: a seeded Latin hypercube with
``problem.start`` (the nominal vector unless warm-started) as its first member (``x0``);
strategy ``best1bin``, mutation dithered in ``[0.5, 1)``, recombination 0.7 (scipy's defaults).
The population is ``10 x dim`` (40 for the four faults), smaller for tiny budgets (at least two
generations fit).
"""

from __future__ import annotations

import time

import numpy as np

from ema_bench.registry import SolveResult, finish, register_solver

from ._common import StopSolver, child, evaluate_unit, quiet, start_unit

POPSIZE = 10  # per dimension (scipy's multiplier): 40 candidates per generation
TOL = 1e-6    # relative spread of the population energies at which scipy declares convergence


@register_solver("de", description="differential evolution (scipy, best1bin, vectorised, "
                 "population 40)", library="scipy", scope="global")
def solve(problem, budget: int, seed: np.random.SeedSequence) -> SolveResult:
    from scipy.optimize import differential_evolution

    t0 = time.perf_counter()
    dim = problem.dim
    mult = max(1, min(POPSIZE, problem.remaining // (2 * dim)))
    npop = max(5, mult * dim)  # scipy enforces at least 5 members
    if problem.remaining < npop:  # not even one population: probe what is left
        evaluate_unit(problem, np.random.default_rng(child(seed, 1)).random(
            (problem.remaining, dim)))
        return finish(problem, "de", "budget", t0, libraries=("scipy",), generations=0)
    maxiter = -(-(problem.remaining - npop) // npop)  # generations after the initial one
    calls = 0

    def objective(U: np.ndarray) -> np.ndarray:
        nonlocal calls
        X = np.atleast_2d(U.T)
        k = min(X.shape[0], problem.remaining)
        f = evaluate_unit(problem, X[:k]) if k else np.empty(0)
        calls += 1
        if k < X.shape[0]:
            raise StopSolver
        return f

    stop_reason = "budget"
    x0 = None if problem.start is None else start_unit(problem)   # without prior: pure LHS
    with quiet(RuntimeWarning):
        try:
            res = differential_evolution(
                objective, [(0.0, 1.0)] * dim, popsize=mult, maxiter=maxiter, tol=TOL,
                polish=False, init="latinhypercube", x0=x0,
                vectorized=True, updating="deferred", rng=np.random.default_rng(child(seed, 0)))
            if res.success:
                stop_reason = "converged"
        except StopSolver:
            pass
    return finish(problem, "de", stop_reason, t0, libraries=("scipy",), population=npop,
                  generations=max(calls - 1, 0))
