"""pymoo on an ema-bench problem: a vectorised ``pymoo.core.problem.Problem``.

``elementwise=False``: pymoo hands ``_evaluate`` a whole population ``X`` (n, dim) and that is
one batched, counted :meth:`~ema_bench.problem.Problem.evaluate` call (the numba kernels
simulate a batch several times faster than the same points one by one).  The search space is
the unit box ``[0, 1]^dim`` (``xl=0``, ``xu=1``).  A population the budget cannot hold is
evaluated as far as the budget goes; its other rows get ``inf`` (never evaluated, never
counted, never the best) and pymoo's ``("n_eval", budget)`` termination ends the run::

    from pymoo.algorithms.soo.nonconvex.pattern import PatternSearch
    from ema_bench.adapters.run import AdapterRun
    from ema_bench.adapters.pymoo import solve

    run = AdapterRun("pymoo-pattern-search", case="small", track="twin", budget=500,
                     library="pymoo")
    res = solve(run.problem, PatternSearch(), seed=run.solver_seed())
    record = run.record("budget")
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pymoo.core.problem import Problem as _PymooProblem
from pymoo.optimize import minimize

from ..problem import SolverView
from .run import evaluate_unit


class PymooProblem(_PymooProblem):
    """An ema-bench :class:`~ema_bench.problem.Problem` as a single-objective pymoo problem
    in the unit box (vectorised: one population, one counted batch)."""

    def __init__(self, problem: SolverView) -> None:
        super().__init__(n_var=problem.dim, n_obj=1, xl=0.0, xu=1.0, elementwise=False)
        self.problem = problem

    def _evaluate(self, X: np.ndarray, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
        X = np.atleast_2d(X)
        n = min(len(X), self.problem.remaining)
        F = np.full(len(X), np.inf)
        if n:
            F[:n] = evaluate_unit(self.problem, X[:n])
        out["F"] = F[:, None]


def solve(problem: SolverView, algorithm: Any, seed: int | None = None, **kwargs: Any) -> Any:
    """``pymoo.optimize.minimize`` of ``problem`` by ``algorithm``, terminated at the
    problem's remaining budget (``("n_eval", remaining)``); returns pymoo's ``Result``.  The
    run's best point is the problem's (``problem.best``), which is what the record keeps."""
    kwargs.setdefault("termination", ("n_eval", problem.remaining))
    return minimize(PymooProblem(problem), algorithm, seed=seed, verbose=False, **kwargs)
