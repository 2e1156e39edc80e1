"""ema-bench: model-based fault identification benchmark for aircraft EM actuators.

Main entry points::

    import ema_bench
    problem = ema_bench.make_problem("small", track="reference", seed=0, budget=2000)
    result = ema_bench.run_solver("cmaes", problem, seed=0)
    problem.score(result.x)

The Gymnasium environment ``EMAFault/Identify-v1`` is registered by ``import ema_bench.env``
(or ``gymnasium.make("ema_bench.env:EMAFault/Identify-v1")``); importing the package registers
it too when gymnasium is already imported.  Gymnasium is not imported otherwise: it costs 0.3 s
that the command line and the solvers do not need.
"""

import sys as _sys

from .jit_cache import ensure_fresh as _ensure_fresh  # noqa: E402
from .version import __version__  # noqa: F401  (the package's version, read here)

_ensure_fresh()   # before any kernel loads: numba alone would miss edits of inlined modules
if "gymnasium" in _sys.modules:
    from . import env  # noqa: E402, F401  (registers EMAFault/Identify-v1)
from .faults import CASES, FAULT_NAMES, FAULTS  # noqa: E402
from .monitor import monitor_traces, simulate_monitor  # noqa: E402
from .problem import BudgetExhausted, Problem, ProblemError  # noqa: E402
from .prognostics.campaign import make_campaign  # noqa: E402
from .reference import simulate_reference  # noqa: E402
from .registry import (  # noqa: E402
    SolveResult,
    available_solvers,
    register_solver,
    run_solver,
)
from .suites.problem import make_problem  # noqa: E402
from .traces import Traces, TracesError, load_traces  # noqa: E402

__all__ = [
    "CASES", "FAULTS", "FAULT_NAMES", "BudgetExhausted", "Problem", "ProblemError",
    "SolveResult", "Traces", "TracesError", "available_solvers", "load_traces",
    "make_campaign", "make_problem", "monitor_traces", "register_solver", "run_solver",
    "simulate_monitor", "simulate_reference",
]
