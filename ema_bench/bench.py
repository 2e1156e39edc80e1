"""``ema-bench bench``: speed of the models on this machine, measured side by side in one run."""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable

import numba
import numpy as np

from .faults import CASES, NOMINAL, random_faults
from .monitor import simulate_monitor
from .naive import simulate_naive
from .protocol import STANDARD_TESTS
from .reference import simulate_reference


def _best_time(fn: Callable[[], object], repeat: int) -> float:
    """Best wall time (s) of ``repeat`` calls, after one warm-up call (compilation)."""
    fn()
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def run_bench(batch: int = 256, repeat: int = 3, naive_candidates: int = 1,
              seed: int = 0) -> dict[str, object]:
    """Measure the models and return the figures (see module docstring of the CLI).

    Parameters
    ----------
    batch : int
        Candidates per batched monitor call.
    repeat : int
        Timed repetitions (the best is kept).
    naive_candidates : int
        Candidates run through the ``solve_ivp`` baseline (it is slow: ~seconds each).
    seed : int
        Root seed of the random candidates and the sensor noise.
    """
    ss = np.random.SeedSequence(seed)
    s_cand, s_noise = ss.spawn(2)
    X = random_faults(s_cand, heterogeneity=1.0, n=batch)
    t_batch = _best_time(lambda: simulate_monitor(X), repeat)
    singles = X[: min(16, batch)]

    def one_at_a_time() -> None:
        for x in singles:
            simulate_monitor(x[None, :])

    t_single = _best_time(one_at_a_time, repeat) / len(singles)
    x_full = CASES["full"].x
    t_ref = _best_time(lambda: simulate_reference(x_full, seed=s_noise), repeat)
    t_naive = 0.0
    for x in X[:naive_candidates]:
        t = time.perf_counter()
        simulate_naive(x)
        t_naive += time.perf_counter() - t
    t_naive /= naive_candidates
    simulated_s = sum(s.duration for s in STANDARD_TESTS)
    evals_per_s = batch / t_batch
    # the monitor's cost per simulated second on one thread, vs the reference's
    threads = numba.get_num_threads()
    mon_cpu_per_sim_s = threads * t_batch / batch / simulated_s
    ref_per_sim_s = t_ref / simulated_s
    return {
        "monitor_evals_per_s": evals_per_s,
        "monitor_single_evals_per_s": 1.0 / t_single,
        "reference_episode_s": t_ref,
        "naive_evals_per_s": 1.0 / t_naive,
        "speedup_vs_naive": evals_per_s * t_naive,
        "single_speedup_vs_naive": t_naive / t_single,
        "monitor_vs_reference_cost_ratio": ref_per_sim_s / mon_cpu_per_sim_s,
        "batch": batch,
        "simulated_s_per_episode": simulated_s,
        "numba_threads": threads,
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "nominal_check": bool(simulate_monitor(NOMINAL[None, :])[1][0]),
    }
