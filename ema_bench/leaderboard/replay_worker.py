"""One replayed run in a process of its own: the solver runs here, the verdict is given
elsewhere.

``ema-bench validate --replay`` sends each sampled record's run to a fresh worker process
(the sweep engine's ``isolated`` executor: one task per process, so no memory crosses runs),
a fork of a server that imported the package and loaded its kernels, and no plugin
(:mod:`.replay_server`).
The worker receives what a solver may see and nothing else: the solver's name, the
instance rebuilt *without its truth* from its measured traces (a
:class:`~ema_bench.problem.Problem` whose truth is gone, pickled), the budget, the run node
and the seed scheme the solver's seed is derived with (:func:`~ema_bench.seeding.
solver_seed`); never the record under check.  It runs the
solver through :func:`~ema_bench.registry.run_solver` and sends back the trajectory (the
problem's log) and the number of model evaluations the kernels made
(:func:`count_kernels`): every candidate through the monitor's compiled entry points and
every reference simulation, so a private copy of the objective (``make_problem(measured=
view.measured)``, the objective's uncounted paths) shows as evaluations the record did not
declare.  The verdict process (:mod:`.replay`) compares.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np

#: name of a module -> its entry points that run the model from Python, and how many
#: candidate evaluations one call makes (from its arguments).  Only functions called from
#: Python are wrapped: a compiled function called inside another (the monitor's per-candidate
#: ``_candidate``) is a global numba resolves when it compiles its caller, and a wrapper there
#: would stop the caller compiling.  A solver calling ``_candidate`` itself is not counted.
_ENTRY_POINTS: dict[str, dict[str, Any]] = {
    "ema_bench.monitor": {
        "monitor_batch_parallel": lambda a: int(np.shape(a[1])[0]),
        "monitor_batch_serial": lambda a: int(np.shape(a[1])[0]),
    },
    "ema_bench.monitor_lanes": {
        "lanes_parallel": lambda a: int(np.unique(a[3]).size),
        "lanes_serial": lambda a: int(np.unique(a[3]).size),
    },
    "ema_bench.reference": {"simulate_reference": lambda a: 1},
}


def count_kernels() -> list[int]:
    """Wrap every model entry point of :data:`_ENTRY_POINTS` (in this process, before any
    plugin is imported, so a plugin's own references are the wrappers too); the returned
    one-element list holds the candidate evaluations made since."""
    import importlib

    made = [0]

    def counted(fn: Any, n_of: Any) -> Any:
        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            made[0] += n_of(args)
            return fn(*args, **kwargs)
        return wrapper

    for mod_name, entries in _ENTRY_POINTS.items():
        mod = importlib.import_module(mod_name)
        for name, n_of in entries.items():
            setattr(mod, name, counted(getattr(mod, name), n_of))
    return made


def replay_job(job: Any) -> dict:
    """Run one replay (``job.data``: solver name, truthless problem, budget, run node, seed
    scheme) and return the problem's log, the final vector and the kernels' count."""
    solver, problem, budget, node, scheme = job.data
    t0 = time.perf_counter()
    made = count_kernels()
    from ..registry import run_solver  # the plugin loader: imported here, in the worker

    res = run_solver(solver, problem, budget, seed=node, seed_scheme=scheme)
    h = problem.history()
    return {"key": job.key, "fitness": h["fitness"].tolist(), "best": h["best"].tolist(),
            "x_hist": np.asarray(h["x"]).tolist(), "x": np.asarray(res.x).tolist(),
            "evaluations": int(problem.evaluations), "model_evaluations": made[0],
            "wall_s": time.perf_counter() - t0}


def scopes_job(job: Any) -> dict:
    """The declared scope of each solver named in ``job.data`` (``unclassified`` when not
    registered): the plugins are imported here, in a worker, never by the report."""
    from ..registry import SolverError, get_solver

    out = {}
    for name in job.data:
        try:
            out[name] = get_solver(name).scope
        except SolverError:
            out[name] = "unclassified"
    return out
