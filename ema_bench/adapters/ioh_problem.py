"""ioh (IOHexperimenter) on an ema-bench problem: ``ioh.wrap_problem`` keeping the batch call.

``ioh.wrap_problem`` calls the wrapped function once per point, so a population of 50 costs
50 single simulations instead of one batch (3.6x slower).  :class:`IOHProblem` evaluates a
call's points as one counted batch on the ema-bench problem first, then passes them to the
wrapped IOH problem, whose function returns the values just computed: IOH's state
(evaluations, best so far) and any IOH logger attached (``ioh.logger.Analyzer``: the
IOHprofiler data IOHanalyzer and iohinspector read) see every point, in order, with the value
the ema-bench problem counted.  The search space is the unit box ``[0, 1]^dim``.  The
function id, name and instance are the export's (``ema-bench export --format ioh``:
:func:`~ema_bench.leaderboard.ioh.function_id`, ``case@track``, the run seed), so the
adapter's logs and an export of the same run pool; where a best-known ``f*`` is known (the
shipped table at root seed 0, a user table of another root seed named in
``EMA_BENCH_TARGETS``) it is IOH's optimum (``problem.optimum``).  The problem holds every
logger attached to it: ioh 0.4 keeps none alive itself, and a logger attached as a temporary
was freed at once and crashed the interpreter at the next evaluation::

    import ioh
    import numpy as np
    from ema_bench.adapters.ioh_problem import IOHProblem
    from ema_bench.adapters.run import AdapterRun

    run = AdapterRun("my-es", case="small", track="twin", budget=500, library="ioh")
    f = IOHProblem(run)
    f.attach_logger(ioh.logger.Analyzer(root="ioh-data", algorithm_name="my-es"))
    rng = np.random.default_rng(run.solver_seed())
    while f.remaining >= 10:
        f(rng.random((10, 4)))             # (10, 4) in [0, 1]: one batch, ten IOH lines
    record = run.record("budget")
    f.close()                              # ends the IOH run: the logger's files are complete
"""

from __future__ import annotations

from collections import deque
from typing import Any

import ioh
import numpy as np

from ..leaderboard.ioh import function_id, function_name, instance_of
from ..suites import find
from .run import AdapterRun, evaluate_unit


class IOHProblem:
    """An IOH problem over an :class:`~ema_bench.adapters.run.AdapterRun`'s problem whose
    call evaluates a batch at once.  Attributes not defined here (``state``, ``meta_data``,
    ``optimum``, ``detach_logger``, ``reset``, ...) are the IOH problem's (a detached logger
    stays held until :meth:`close`)."""

    def __init__(self, run: AdapterRun) -> None:
        self.run = run
        self.problem = run.problem
        self._pending: deque[tuple[np.ndarray, float]] = deque()
        self._loggers: list[Any] = []
        inst = find(run.case)   # None: a case outside the suites (no f*)
        known = None if inst is None else inst.best_known(run.track, run.seed, run.root_seed)
        optimum = None
        if known is not None:
            x_star = self.problem.to_unit(np.array([known["x_star"][n]
                                                    for n in self.problem.names]))
            f_star = float(known["f_star"])

            def optimum(instance: int, dimension: int) -> tuple[list[float], float]:
                return list(map(float, x_star)), f_star
        # the export's identity of this run (ema_bench/leaderboard/ioh.py), so both pool
        ident = {"case": run.case, "track": run.track, "seed": run.seed,
                 "root_seed": run.root_seed}
        name = function_name(ident)
        self.ioh = ioh.wrap_problem(self._value, name=f"ema-bench {name}",
                                    dimension=self.problem.dim, instance=instance_of(ident),
                                    lb=0.0, ub=1.0, calculate_objective=optimum)
        # wrap_problem takes the first free id and registers the name: both set afterwards
        self.ioh.set_id(function_id(name))
        self.ioh.set_name(name)

    def attach_logger(self, logger: Any) -> None:
        """Attach an IOH logger and hold it for the problem's lifetime (ioh does not: a
        logger attached as a temporary would be freed while IOH still writes to it)."""
        self.ioh.attach_logger(logger)
        self._loggers.append(logger)

    def close(self) -> None:
        """End the IOH run and close every logger attached (their files are complete
        only then)."""
        self.ioh.reset()
        for logger in self._loggers:
            logger.close()

    def _value(self, x: np.ndarray) -> float:
        """The wrapped function: the value computed for this point in the current batch."""
        if not self._pending:
            raise RuntimeError("call the IOHProblem, not its .ioh problem: an evaluation "
                               "must go through the ema-bench problem's count")
        xq, f = self._pending.popleft()
        if not np.array_equal(np.asarray(x, dtype=float), xq):
            self._pending.clear()
            raise RuntimeError("IOH evaluated another point than the batch's")
        return f

    @property
    def remaining(self) -> int:
        """Evaluations the ema-bench problem has left."""
        return self.problem.remaining

    def __call__(self, X: Any) -> float | np.ndarray:
        """Fitness of one point (dim,) or of a batch (n, dim) in the unit box: one batched
        evaluation of the ema-bench problem (BudgetExhausted if it cannot hold them all),
        then IOH's bookkeeping and logging point by point."""
        arr = np.asarray(X, dtype=float)
        single = arr.ndim == 1
        U = np.ascontiguousarray(np.clip(np.atleast_2d(arr), 0.0, 1.0))
        F = evaluate_unit(self.problem, U)
        self._pending.extend(zip(U, map(float, F)))
        out = self.ioh(U)
        return float(out[0]) if single else np.asarray(out, dtype=float)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.ioh, name)
