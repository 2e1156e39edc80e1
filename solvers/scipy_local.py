"""Local methods from scipy with multi-start, in the normalised box [0, 1]^dim.

Every method restarts until the budget is spent: first from ``problem.start`` (the nominal
vector unless warm-started), then from seeded Latin-hypercube points.  Each start gets at most
what the problem has left (and a per-start cap, so that a slow crawl cannot eat the whole
budget); a remainder too small for one more start is spent on Latin-hypercube probes in one
batch.  The fitness is piecewise smooth (dry friction, backlash), so finite differences take
coarse steps in the unit box.

* ``least-squares``: ``scipy.optimize.least_squares`` (trust-region reflective) on
  ``problem.residuals`` (one evaluation per residual vector; its finite-difference Jacobian
  costs ``dim`` more, counted by the problem like any other), ``x_scale=1`` (the box is already
  normalised), ``diff_step=1e-2``: with ``1e-3`` the Jacobian sees the kinks of the
  fitness and starts stop early on ``xtol`` (at budget 5000, seed 0, it missed the full case
  on the reference track by 3 % of the range and the random twin case by 7 %; with ``1e-2``
  both are within 0.3 %).  Its Jacobian's ``dim`` points are one batched
  ``problem.residuals`` call (scipy's ``workers``): scipy's points and order, the same bits.
* ``nelder-mead``: bounded Nelder-Mead, initial simplex of edge 0.1 pointing into the box.
* ``lbfgsb``: L-BFGS-B with a forward-difference gradient (step ``1e-3``, backward at the
  upper bound) whose ``dim + 1`` points are one batched ``problem.evaluate`` call.
* ``powell``: bounded Powell.
* ``ms-least-squares``: the multi-start a user would write around ``least_squares``:
  :data:`MS_STARTS` starts (the problem's start, then uniform random points of the box),
  the budget split evenly between the starts still to run (what a start leaves unspent goes
  to the next), and further random starts of the same share while budget remains.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable

import numpy as np

from ema_bench.registry import SolveResult, finish, register_solver

from ._common import (
    StopSolver,
    child,
    evaluate_unit,
    quiet,
    scalar_objective,
    spend_rest,
    start_points,
    start_unit,
)

STEP = 1e-3           # L-BFGS-B finite-difference step in the normalised box
LS_DIFF_STEP = 1e-2   # least_squares finite-difference step (see the module docstring)
SIMPLEX_EDGE = 0.1    # Nelder-Mead initial simplex edge
MAX_EVALS_PER_START = 1000
#: ms-least-squares: the starts the budget is split between.
MS_STARTS = 10


def _uniform_points(problem, seed: np.random.SeedSequence):
    """The problem's start (drawn from ``seed`` without prior), then uniform points."""
    yield start_unit(problem, seed)
    rng = np.random.default_rng(child(seed, 1))
    while True:
        yield rng.random(problem.dim)


def _multistart(name: str, problem, seed: np.random.SeedSequence,
                run_one: Callable[[np.ndarray, int], str], min_evals: int,
                split: int | None = None) -> SolveResult:
    """Run ``run_one(u0, cap)`` from successive start points until fewer than ``min_evals``
    evaluations are left; ``cap`` is the start's evaluation allowance: at most
    :data:`MAX_EVALS_PER_START` from Latin-hypercube points, or with ``split`` (uniform
    points) the remaining budget over the ``split`` starts still to run (at least one)."""
    t0 = time.perf_counter()
    starts, messages = 0, {}
    points = (start_points(problem, child(seed, 0)) if split is None else
              _uniform_points(problem, child(seed, 0)))
    share = None if split is None else max(problem.remaining // split, min_evals)
    with quiet(RuntimeWarning, UserWarning):
        while problem.remaining >= min_evals:
            before = problem.evaluations
            cap = (min(problem.remaining, MAX_EVALS_PER_START) if split is None else
                   min(problem.remaining, max(problem.remaining // max(split - starts, 1),
                                              share)))
            try:
                msg = run_one(next(points), cap)
            except StopSolver:
                msg = "budget"
            starts += 1
            messages[msg] = messages.get(msg, 0) + 1
            if problem.evaluations == before:  # a start that evaluates nothing: give up
                break
        probes = spend_rest(problem, child(seed, 1))
    return finish(problem, name, "budget" if problem.remaining == 0 else "stalled", t0,
                  libraries=("scipy",), starts=starts, probes=probes, start_stops=messages)


def _capped(fn: Callable, problem, cap: int) -> Callable:
    """``fn`` that raises :class:`StopSolver` once this start has used ``cap`` evaluations."""
    limit = problem.evaluations + cap

    def wrapped(*args):
        if problem.evaluations >= limit:
            raise StopSolver
        return fn(*args)
    return wrapped


# --- least squares ----------------------------------------------------------------------------
@register_solver("least-squares", description="scipy least_squares (TRF) on the residuals, "
                 "multi-start from nominal then LHS", library="scipy",
                 scope="local")
def solve_least_squares(problem, budget: int, seed: np.random.SeedSequence, *,
                        split: int | None = None,
                        name: str = "least-squares") -> SolveResult:
    """``least_squares`` from successive starts (see the module docstring); ``split``: the
    starts the budget is split between (uniform random starts), reported as ``name``."""
    from scipy.optimize import least_squares

    # scipy >= 1.16 maps the finite-difference points through ``workers``; before it, one
    # call each (the same points and bits, slower)
    _HAS_WORKERS = "workers" in inspect.signature(least_squares).parameters
    dim = problem.dim

    def run_one(u0: np.ndarray, cap: int) -> str:
        limit = problem.evaluations + cap

        def allowed() -> int:   # evaluations this start may still make
            return min(limit - problem.evaluations, problem.remaining)

        def residuals(u: np.ndarray) -> np.ndarray:
            if allowed() < 1:
                raise StopSolver
            return problem.residuals(problem.from_unit(np.clip(u, 0.0, 1.0)))

        def jacobian_points(fun, points) -> list[np.ndarray]:
            # scipy's finite-difference points (its steps, its order), evaluated in one
            # batched call instead of ``map(fun, points)``: the same evaluations, counted
            # and capped alike, the same bits (the batch kernels equal the one-candidate
            # one)
            U = np.clip(np.array(list(points), dtype=float), 0.0, 1.0)
            k = allowed()
            if k < 1:
                raise StopSolver
            R = problem.residuals(problem.from_unit(U[:k]))
            if k < len(U):
                raise StopSolver
            return list(R)

        batched = {"workers": jacobian_points} if _HAS_WORKERS else {}
        res = least_squares(residuals, u0, bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                            diff_step=LS_DIFF_STEP, max_nfev=max(1, cap // (dim + 1)),
                            **batched)
        return {0: "max_nfev", 1: "gtol", 2: "ftol", 3: "xtol", 4: "ftol+xtol"}.get(
            res.status, str(res.status))

    return _multistart(name, problem, seed, run_one, min_evals=2 * (dim + 1), split=split)


register_solver("ms-least-squares", description=f"scipy least_squares (TRF), {MS_STARTS} "
                "random starts in the box (the first the problem's), the budget split",
                library="scipy", scope="global", split=MS_STARTS,
                name="ms-least-squares")(solve_least_squares)


# --- minimize ---------------------------------------------------------------------------------
def solve_minimize(problem, budget: int, seed: np.random.SeedSequence, *, method: str,
                   name: str) -> SolveResult:
    """Multi-start ``scipy.optimize.minimize`` with ``method``, reported as solver ``name``."""
    from scipy.optimize import minimize

    dim = problem.dim
    bounds = [(0.0, 1.0)] * dim
    f = scalar_objective(problem)

    def f_and_grad(u: np.ndarray) -> tuple[float, np.ndarray]:
        """Fitness and forward-difference gradient, the dim + 1 points in one call."""
        u = np.clip(u, 0.0, 1.0)
        h = np.where(u + STEP <= 1.0, STEP, -STEP)
        U = np.vstack([u, u + np.diag(h)])
        k = min(len(U), problem.remaining)
        if k < 1:
            raise StopSolver
        fu = evaluate_unit(problem, U[:k])
        if k < len(U):
            raise StopSolver
        return float(fu[0]), (fu[1:] - fu[0]) / h

    def run_one(u0: np.ndarray, cap: int) -> str:
        if method == "Nelder-Mead":
            step = np.where(u0 + SIMPLEX_EDGE <= 1.0, SIMPLEX_EDGE, -SIMPLEX_EDGE)
            simplex = np.vstack([u0, u0 + np.diag(step)])
            res = minimize(_capped(f, problem, cap), u0, method=method, bounds=bounds,
                           options={"maxfev": cap, "initial_simplex": simplex,
                                    "xatol": 1e-4, "fatol": 1e-8})
        elif method == "L-BFGS-B":
            res = minimize(_capped(f_and_grad, problem, cap), u0, jac=True, method=method,
                           bounds=bounds, options={"maxfun": max(1, cap // (dim + 1))})
        else:
            res = minimize(_capped(f, problem, cap), u0, method=method, bounds=bounds,
                           options={"maxfev": cap})
        return "converged" if res.success else str(res.message)[:60]

    return _multistart(name, problem, seed, run_one, min_evals=dim + 2)


# configured variants of one function (run_solver passes the keywords)
for _name, _method, _what in (
        ("nelder-mead", "Nelder-Mead", "Nelder-Mead (bounded)"),
        ("lbfgsb", "L-BFGS-B", "L-BFGS-B, batched finite-difference gradient"),
        ("powell", "Powell", "Powell (bounded)")):
    register_solver(_name, description=f"scipy {_what}, multi-start from nominal then LHS",
                    library="scipy", scope="local", method=_method,
                    name=_name)(solve_minimize)
