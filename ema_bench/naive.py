"""Naive baseline for the speed benchmark: the monitor's own equations as plain Python.

What a competent user without a compiler would write is the same fixed-step loop (controller
tick, plant step, window output) interpreted by CPython.  That is exactly the monitor kernel
with numba's JIT switched off, so the baseline cannot drift from the compiled model: it runs
``simulate_monitor`` one candidate at a time in a child process started with
``NUMBA_DISABLE_JIT=1`` (the switch is read when numba is imported, hence the child).  Both
sides of the ratio are then one thread, one candidate per call.

Run ``python -m ema_bench.naive N SEED`` to print the child's measurement as JSON.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

from .faults import random_faults
from .seeding import run_seed, stream


def _measure(n: int, seed: int) -> dict[str, float]:
    """Time ``n`` plain-Python evaluations in this process (JIT must already be off)."""
    from .monitor import simulate_monitor

    X = random_faults(stream(run_seed(seed, 0), "instance"), heterogeneity=1.0, n=n)
    cpu, wall = time.process_time(), time.perf_counter()
    for x in X:
        simulate_monitor(x[None, :], parallel=False)
    return {"evals": n, "cpu_s": time.process_time() - cpu, "wall_s": time.perf_counter() - wall}


def naive_python_timing(n: int = 2, seed: int = 0, timeout: float = 600.0) -> dict[str, float]:
    """Plain-Python cost of ``n`` monitor evaluations, measured in a child process.

    Returns
    -------
    dict
        ``evals``, ``cpu_s`` and ``wall_s`` (s, the child's own timers, import excluded) and
        ``evals_per_cpu_s``.
    """
    if n < 1:
        raise ValueError(f"need at least one naive evaluation, got {n}")
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    proc = subprocess.run([sys.executable, "-m", "ema_bench.naive", str(n), str(seed)],
                          env=env, capture_output=True, text=True, timeout=timeout, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"naive baseline failed:\n{proc.stderr[-2000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    result["evals_per_cpu_s"] = result["evals"] / result["cpu_s"]
    return result


if __name__ == "__main__":  # pragma: no cover - exercised through naive_python_timing
    if os.environ.get("NUMBA_DISABLE_JIT") != "1":
        sys.exit("run with NUMBA_DISABLE_JIT=1 (naive_python_timing does)")
    print(json.dumps(_measure(int(sys.argv[1]), int(sys.argv[2]))))
