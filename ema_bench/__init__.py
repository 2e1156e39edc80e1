"""ema-bench: model-based fault identification benchmark for aircraft EM actuators.

Main entry points::

    import ema_bench
    problem = ema_bench.make_problem("small", track="reference", seed=0, budget=2000)
    result = ema_bench.run_solver("cmaes", problem, seed=0)
    problem.score(result.x)

Importing the package registers the Gymnasium environment ``EMAFault/Identify-v0``.
"""

__version__ = "0.1.0"

from . import env  # noqa: E402, F401  (registers EMAFault/Identify-v0)
from .faults import CASES, FAULT_NAMES, FAULTS  # noqa: E402
from .monitor import monitor_traces, simulate_monitor  # noqa: E402
from .problem import BudgetExhausted, Problem, ProblemError, make_problem  # noqa: E402
from .reference import simulate_reference  # noqa: E402
from .registry import (  # noqa: E402
    SolveResult,
    available_solvers,
    register_solver,
    run_solver,
)
from .traces import Traces, TracesError, load_traces  # noqa: E402

__all__ = [
    "CASES", "FAULTS", "FAULT_NAMES", "BudgetExhausted", "Problem", "ProblemError",
    "SolveResult", "Traces", "TracesError", "available_solvers", "load_traces",
    "make_problem", "monitor_traces", "register_solver", "run_solver", "simulate_monitor",
    "simulate_reference",
]
