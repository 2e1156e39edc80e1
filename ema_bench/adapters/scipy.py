"""SciPy on an ema-bench problem: ``scipy.optimize.minimize`` and ``differential_evolution``
with the bounds passed and budget exhaustion a normal stop.

Ten lines of glue go wrong twice: Nelder-Mead without ``bounds`` steps outside the fault box
at its first simplex and the problem refuses the point (``ProblemError``), and
:class:`~ema_bench.problem.BudgetExhausted` escapes SciPy's loops.  Here the search runs in
the unit box with ``bounds`` given, the method's own evaluation cap is set to what the
problem has left, and a batch the budget cannot hold ends the run with the best point the
problem logged (``success`` False, ``message`` saying so)::

    from ema_bench.adapters.run import AdapterRun
    from ema_bench.adapters.scipy import minimize, simplex

    run = AdapterRun("scipy-nelder-mead", case="small", track="twin", budget=400,
                     library="scipy")
    res = minimize(run.problem, method="Nelder-Mead",
                   options={"initial_simplex": simplex(run.problem)})
    record = run.record(res.stop_reason)     # validates like a leaderboard run

SciPy's default simplex (5 % of each nonzero coordinate) is tiny around the nominal vector;
:func:`simplex` gives the zoo's (edge 0.1 of the unit box, pointing into it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy import optimize

from ..problem import BudgetExhausted, ProblemError, SolverView
from .run import evaluate_unit

#: the option that caps a method's function evaluations, by method (lower case)
_MAXFEV = {"nelder-mead": "maxfev", "powell": "maxfev", "l-bfgs-b": "maxfun", "tnc": "maxfun",
           "cobyla": "maxiter", "cobyqa": "maxfev", "slsqp": "maxiter", "trust-constr": "maxiter"}


class _Spent(Exception):
    """The budget cannot hold the next evaluation (raised through SciPy, caught here)."""


def _result(problem: SolverView, start_evals: int, message: str, success: bool,
            nit: int | None = None) -> optimize.OptimizeResult:
    x, f = problem.best
    out = optimize.OptimizeResult(x=x, fun=f, nfev=problem.evaluations - start_evals,
                                  success=success, message=message,
                                  stop_reason="budget" if problem.remaining == 0 else
                                  ("converged" if success else "stalled"))
    if nit is not None:
        out.nit = nit
    return out


def _scalar(problem: SolverView) -> Callable[[np.ndarray], float]:
    def f(u: np.ndarray) -> float:
        try:
            return float(evaluate_unit(problem, u)[0])
        except BudgetExhausted:
            raise _Spent from None
    return f


def _start(problem: SolverView, x0: np.ndarray | None) -> np.ndarray:
    """``x0``, or the problem's start; a problem without prior has none to default to."""
    if x0 is not None:
        return np.asarray(x0, dtype=float)
    if problem.start is None:
        raise ProblemError("this problem has no prior (no nominal, no start): pass x0")
    return problem.start


def simplex(problem: SolverView, edge: float = 0.1, x0: np.ndarray | None = None) -> np.ndarray:
    """A Nelder-Mead ``initial_simplex`` in the unit box: the start and one step of ``edge``
    along each axis, pointing into the box."""
    u0 = np.clip(problem.to_unit(_start(problem, x0)), 0, 1)
    step = np.where(u0 + edge <= 1.0, edge, -edge)
    return np.vstack([u0, u0 + np.diag(step)])


def minimize(problem: SolverView, method: str = "Nelder-Mead", x0: np.ndarray | None = None,
             options: dict[str, Any] | None = None, **kwargs: Any) -> optimize.OptimizeResult:
    """``scipy.optimize.minimize`` on ``problem``, in the unit box with bounds.

    Parameters
    ----------
    problem : SolverView
        The instance (its budget bounds the run; every evaluation is counted by it).
    method : str
        Any bounded ``minimize`` method (Nelder-Mead, Powell, L-BFGS-B, TNC, COBYLA, ...).
    x0 : array (dim,), optional
        Start in physical units; default ``problem.start`` (the nominal vector).
    options, **kwargs
        Passed to ``minimize``; the method's evaluation cap defaults to what the problem
        has left.

    Returns
    -------
    OptimizeResult
        ``x`` (physical units) and ``fun``: the best point the problem logged (a method's
        own ``x`` may be a point it never evaluated); ``nfev`` the problem's count;
        ``stop_reason`` ``budget``, ``converged`` or ``stalled`` (for the run record).
    """
    start = problem.evaluations
    u0 = problem.to_unit(_start(problem, x0))
    opts = dict(options or {})
    cap = _MAXFEV.get(method.lower())
    if cap:
        opts.setdefault(cap, problem.remaining)
    lo, hi = np.zeros(problem.dim), np.ones(problem.dim)
    try:
        res = optimize.minimize(_scalar(problem), np.clip(u0, 0, 1), method=method,
                                bounds=optimize.Bounds(lo, hi), options=opts, **kwargs)
    except _Spent:
        return _result(problem, start, "evaluation budget exhausted", False)
    return _result(problem, start, str(res.message), bool(res.success), res.get("nit"))


def differential_evolution(problem: SolverView, seed: int | None = None,
                           **kwargs: Any) -> optimize.OptimizeResult:
    """``scipy.optimize.differential_evolution`` on ``problem``: each generation one
    batched evaluation (``vectorized=True``, ``updating="deferred"``), ``maxiter`` set so
    the budget is not overrun, a generation the budget cannot hold ending the run.

    Returns
    -------
    OptimizeResult
        As :func:`minimize`.
    """
    start = problem.evaluations
    popsize = kwargs.pop("popsize", 15)
    npop = popsize * problem.dim
    # the initial population plus maxiter generations of npop each, within the budget
    kwargs.setdefault("maxiter", max(0, problem.remaining // npop - 1))
    kwargs.setdefault("polish", False)   # polishing would call L-BFGS-B past maxiter

    def f(U: np.ndarray) -> np.ndarray:   # U: (dim, S), SciPy's vectorised layout
        try:
            return evaluate_unit(problem, np.asarray(U).T)
        except BudgetExhausted:
            raise _Spent from None

    bounds = optimize.Bounds(np.zeros(problem.dim), np.ones(problem.dim))
    try:
        res = optimize.differential_evolution(f, bounds, popsize=popsize, vectorized=True,
                                              updating="deferred", rng=seed, **kwargs)
    except _Spent:
        return _result(problem, start, "evaluation budget exhausted", False)
    return _result(problem, start, str(res.message), bool(res.success), res.get("nit"))
