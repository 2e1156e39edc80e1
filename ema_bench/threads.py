"""Numba's worker threads must sleep, not spin, between parallel calls.

With OpenMP's default (active) wait policy the workers of a parallel kernel busy-wait after each
call; on a loaded two-core machine a one-candidate solver then paid 3-9 ms per call instead of
about 1 ms.  :func:`configure_threads` asks for the passive policy before numba starts its
threading layer (the first parallel call); a user's own setting wins.
"""

from __future__ import annotations

import os

_DONE = False


def configure_threads() -> None:
    """Make numba's threads wait passively (idempotent; a no-op once threads have started)."""
    global _DONE
    if _DONE:
        return
    _DONE = True
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    os.environ.setdefault("KMP_BLOCKTIME", "0")   # the same for Intel's OpenMP runtime
