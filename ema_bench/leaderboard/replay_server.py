"""The fork server of replay's workers: the package's own modules imported and its kernels
loaded once, nothing submitted; each sampled record's worker is a fork of it.

A spawned worker paid, per record, what one process pays once: the interpreter's start, the
imports (NumPy, SciPy, numba, the package) and numba's loading of every cached kernel
signature it calls, about twice the CPU of the replay of a cheap record.  ``validate --replay``
forks its workers from a server (:func:`~ema_bench.sweep.executors.execute`'s ``preload``:
the standard library's ``forkserver``) that imported this module: trusted code only, the package
and its own dependencies, never a plugin (a solver's plugin is imported in the forked worker,
by :func:`~ema_bench.registry.run_solver`).  A fork holds a copy of the server's memory and
nothing of another record: the server never ran a solver, never saw a record, and builds no
problem (it loads the kernels on the nominal faults, with no truth in memory).

The server never starts numba's threads (their state does not survive a fork; loading a
parallel kernel, even from the cache, starts them), so it loads the serial kernels, the ones a
worker calls: a worker has one numba thread (:func:`~ema_bench.sweep.executors.worker_init`),
and on one thread the monitor runs its serial kernels (:func:`ema_bench.monitor._parallel`).
Imported for its effect; elsewhere it costs about a CPU-second and changes nothing.
"""

from __future__ import annotations

import scipy.optimize  # noqa: F401  (the package's own dependencies, which solvers use too)
import scipy.stats  # noqa: F401
import threadpoolctl  # noqa: F401  (run_solver's BLAS limit)

from .. import problem, registry, suites  # noqa: F401  (what a worker unpickles and calls)
from ..faults import NOMINAL
from ..monitor import simulate_monitor
from ..monitor_lanes import LANES
from . import replay_worker  # noqa: F401  (the runner)


def warm() -> None:
    """Load the monitor's serial kernels (scalar and lanes) from numba's cache and lay out the
    standard tests, on the calling thread only (numba's threads are not started)."""
    import numpy as np

    X = np.tile(NOMINAL, (LANES, 1))
    simulate_monitor(X[:1], parallel=False, lanes=False)   # the scalar kernel
    simulate_monitor(X, parallel=False, lanes=True)        # the lanes


warm()
