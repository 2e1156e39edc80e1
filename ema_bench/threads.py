"""Worker threads that sleep, not spin: numba's between parallel calls, BLAS's in a solver.

With OpenMP's default (active) wait policy the workers of a parallel kernel busy-wait after each
call; on a loaded two-core machine a one-candidate solver then paid 3-9 ms per call instead of
about 1 ms.  :func:`configure_threads` asks for the passive policy before numba starts its
threading layer (the first parallel call); a user's own setting wins.

OpenBLAS's threads spin the same way after each call, and a solver alternates small linear
algebra (a 5,200 x 12 SVD per ``least_squares`` step, CMA-ES's eigendecomposition) with the
kernels: its idle threads then compete with the kernel's for the cores.
:func:`blas_single_thread` keeps BLAS on the calling thread for a solver's run
(:func:`ema_bench.registry.run_solver`) and a local refit: on a tier-12 case ``least-squares``
took 6.5-7.6 CPU-s for 900 evaluations with OpenBLAS's default threads and 1.3 with one, with the
same fitness values (``benchmarks/blas_spin.py`` measures the spin itself).  Matrices this small
gain nothing from BLAS threads; a board runs one solver per core anyway.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

_DONE = False


def configure_threads() -> None:
    """Make numba's threads wait passively (idempotent; a no-op once threads have started)."""
    global _DONE
    if _DONE:
        return
    _DONE = True
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    os.environ.setdefault("KMP_BLOCKTIME", "0")   # the same for Intel's OpenMP runtime


@contextmanager
def blas_single_thread() -> Iterator[None]:
    """BLAS (OpenBLAS, MKL, BLIS) on the calling thread inside the block, restored after it."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
