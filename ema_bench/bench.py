"""``ema-bench bench``: speed of the models on this machine, measured honestly.

Every figure is a median over interleaved rounds (batched, one-thread, C and single-candidate
measurements take turns, so a burst of load from elsewhere hits them all alike), with CPU time
beside wall time and the load average seen while measuring.  Figures that need a fresh process
(import, cache load, cold compile, cold command line) run in child processes.

Keys of the result (``--json``):

``monitor_evals_per_s``
    full monitor evaluations (both standard tests) per wall second, batched on all threads.
``monitor_evals_per_cpu_s``
    the same per CPU second on one thread (serial kernel, candidates in lock-step lanes:
    :mod:`ema_bench.monitor_lanes`).
``monitor_evals_per_cpu_s_scalar``, ``lanes_speedup``
    the scalar kernel's rate on the same candidates, and scalar time / lanes time.
``single_call_ms`` / ``single_call_ms_loaded`` (and its 90th percentile)
    median wall time of a one-candidate call; the second while other processes keep every
    core busy.
``c_time_ratio``
    numba time / plain-C time on the same candidates, one thread each, the scalar numba kernel
    against its line-by-line C port (null without a C compiler or outside a source checkout;
    ``c_unavailable`` says why); ``lanes_c_time_ratio``: the numba lanes against that C.
``c_lanes_time_ratio``
    tier -> numba lanes time / time of the 8-lane C twin (``monitor_lanes_batch``, the SIMD
    limit of the same step), one thread each, tier 4 (no effects) and tier 12 (every lane
    effect of suite emafdi-v2's tier 12, drawn in its box); ``c_lanes_vs_c_scalar``: the C
    twin's lanes against its scalar kernel, per tier.
``tier_evals_per_cpu_s``, ``tier_ratio``
    tier -> objective evaluations (monitor and fitness) per CPU second on one thread, batches
    of ``serial`` candidates drawn uniformly in the tier's box on the twin track of its first
    instance (suite emafdi-v2), and each tier's rate over tier 4's (1.0: as cheap as tier 4).
``single_call_ms_tier12``
    median wall time of a one-candidate call of a tier-12 candidate (the scalar kernel).
``naive_python_evals_per_s``, ``speedup_vs_naive_python``
    the same equations as a plain-Python loop (:mod:`ema_bench.naive`), one thread against one
    thread.
``reference_episode_s``
    wall seconds of one reference-model (detailed EMA) simulation of the full case, warm: the
    median of 3 calls after an untimed first one, so a stale numba cache does not decide it.
``import_s``, ``cache_load_s``, ``cold_compile_s``
    ``import ema_bench``; loading the compiled kernels (scalar and lanes, serial) from numba's
    cache; compiling them from scratch (an empty cache folder).
``time_to_success_warm_s`` / ``time_to_success_cold_s``
    solver -> case -> median wall seconds until the first vector with every fault within 1 %
    of its range (reference track): in this process (problem set-up included, reference
    traces cached), and from launching ``ema-bench solve`` to that evaluation.  null where no
    seed succeeded.
``load_avg``
    1-minute load average before, during and after the measurements.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numba
import numpy as np

from .faults import CASES, random_faults
from .monitor import simulate_monitor
from .reference import simulate_reference
from .seeding import run_seed, stream
from .suites.problem import make_problem

TTS_SOLVERS = ("cmaes", "powell")
TTS_CASES = ("nominal", "small", "full", "random")


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(wall s, CPU s of this process) of one call."""
    c, w = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def _median(xs: list[float]) -> float:
    return float(statistics.median(xs))


def _child(code: str, env: dict[str, str] | None = None, timeout: float = 600.0,
           last_line: bool = True) -> str:
    """Run ``python -c code`` in a fresh process; its last stdout line (or all of it)."""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, timeout=timeout, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"bench child failed:\n{proc.stderr[-2000:]}")
    return proc.stdout.strip().splitlines()[-1] if last_line else proc.stdout


@contextmanager
def busy_cores(n: int) -> Iterator[None]:
    """``n`` child processes spinning on a core each, for measurements under load."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        time.sleep(0.3)   # let them start spinning
        yield
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()


def startup_figures(repeat: int = 3) -> dict[str, float]:
    """``import_s`` and ``cache_load_s`` (medians over fresh processes) and
    ``cold_compile_s`` (one process with an empty numba cache folder)."""
    imp = [float(_child("import time; t = time.perf_counter(); import ema_bench; "
                        "print(time.perf_counter() - t)")) for _ in range(repeat)]
    first_call = ("import time, numpy as np\n"
                  "from ema_bench.monitor import simulate_monitor\n"
                  "from ema_bench.faults import NOMINAL\n"
                  "x, X = NOMINAL[None, :], np.repeat(NOMINAL[None, :], 8, axis=0)\n"
                  "def both():   # the scalar kernel and the lanes, as a solver meets them\n"
                  "    simulate_monitor(x, parallel=False)\n"
                  "    simulate_monitor(X, parallel=False)\n"
                  "t = time.perf_counter(); both()\n"
                  "a = time.perf_counter() - t\n"
                  "t = time.perf_counter(); both()\n"
                  "print(a - (time.perf_counter() - t))")
    load = [float(_child(first_call)) for _ in range(repeat)]
    with tempfile.TemporaryDirectory() as d:
        cold = float(_child(first_call, env={"NUMBA_CACHE_DIR": d}))
    return {"import_s": _median(imp), "cache_load_s": _median(load), "cold_compile_s": cold}


def time_to_success(solvers: tuple[str, ...] = TTS_SOLVERS, cases: tuple[str, ...] = TTS_CASES,
                    seeds: int = 3, budget: int = 3000, cold: bool = True,
                    progress: Callable[[str], None] | None = None) -> dict[str, dict]:
    """Median seconds to the first successful vector, warm and cold (see module doc)."""
    from .registry import run_solver

    warm: dict[str, dict[str, float | None]] = {}
    coldd: dict[str, dict[str, float | None]] = {}
    for solver in solvers:
        warm[solver], coldd[solver] = {}, {}
        for case in cases:
            w_times, c_times = [], []
            for seed in range(seeds):
                if progress:
                    progress(f"time to success: {solver} {case} seed {seed}")
                t0 = time.perf_counter()
                # the run node of `ema-bench solve --seed` (root seed 0)
                problem = make_problem(case, track="reference", seed=run_seed(0, seed),
                                       budget=budget)
                t_setup = time.perf_counter() - t0
                run_solver(solver, problem, seed=run_seed(0, seed))
                t_hit = problem.first_success_wall_s()
                w_times.append(np.inf if t_hit is None else t_setup + t_hit)
                if cold:
                    launch = time.perf_counter()
                    out = json.loads(_child(
                        "import sys; from ema_bench.cli import main; sys.exit(main(["
                        f"'solve', '--case', '{case}', '--solver', '{solver}', '--seed', "
                        f"'{seed}', '--budget', '{budget}', '--json', '--no-progress']))",
                        last_line=False))
                    clock = out.get("clock_at_success")
                    c_times.append(np.inf if clock is None else clock - launch)
            warm[solver][case] = _finite_median(w_times)
            coldd[solver][case] = _finite_median(c_times) if cold else None
    return {"time_to_success_warm_s": warm, "time_to_success_cold_s": coldd}


@contextmanager
def one_thread() -> Iterator[None]:
    """numba's kernels on one thread (per-CPU-second figures), restored afterwards."""
    n = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(n)


TIERS = (4, 7, 12)


def tier_setups(batch: int, seed: int = 0) -> dict[int, tuple[object, np.ndarray]]:
    """tier -> (objective, candidates): ``batch`` candidates drawn uniformly in the tier's box
    (a tier-7 one carries a sensor offset, current gain and feedback delay, a tier-12 one every
    plant effect too) on the twin track of the tier's first instance, kernels warmed up."""
    from .suites.v2 import case_key, instance_names

    rng = np.random.default_rng(seed)
    out = {}
    for t in TIERS:
        p = make_problem(case_key(instance_names(t)[0], "prior"), track="twin", seed=0,
                         budget=1)
        X = p.space.check(p.from_unit(rng.random((batch, p.dim))))
        with one_thread():
            p.objective.evaluate(X)   # compile or load the kernels first
        out[t] = (p.objective, X)
    return out


def tier_rates(setups: dict[int, tuple[object, np.ndarray]]) -> dict[int, float]:
    """One interleaved round: tier -> objective evaluations per CPU second, one thread."""
    rates = {}
    with one_thread():
        for t, (obj, X) in setups.items():
            _, cpu = _timed(lambda obj=obj, X=X: obj.evaluate(X))
            rates[t] = X.shape[0] / cpu
    return rates


def tier12_effects(n: int, seed: int = 0) -> np.ndarray:
    """Effects vectors of ``n`` tier-12 candidates: every lane effect uniform in its range."""
    from .effects import EFFECT_INDEX, EFFECTS, N_EFFECTS
    from .monitor_lanes import LANE_EFFECTS

    rng = np.random.default_rng(seed)
    E = np.zeros((n, N_EFFECTS))
    for name in LANE_EFFECTS:
        eff = EFFECTS[EFFECT_INDEX[name]]
        E[:, EFFECT_INDEX[name]] = rng.uniform(eff.lower, eff.upper, n)
    return E


def _finite_median(xs: list[float]) -> float | None:
    """Median counting failures as infinitely slow; None when it is infinite."""
    if not xs:
        return None
    m = float(np.median(xs))
    return m if np.isfinite(m) else None


def run_bench(batch: int = 256, repeat: int = 7, serial: int = 16, naive_evals: int = 2,
              tts_seeds: int = 3, tts_budget: int = 3000, seed: int = 0, startup: bool = True,
              tts: bool = True, progress: Callable[[str], None] | None = None
              ) -> dict[str, object]:
    """Measure the models and return the figures (keys: module docstring).

    Parameters
    ----------
    batch : int
        Candidates per batched (all-thread) monitor call.
    repeat : int
        Interleaved rounds; every figure is the median over them.
    serial : int
        Candidates per one-thread call (numba serial and C) and one-candidate calls per round.
    naive_evals : int
        Evaluations of the plain-Python baseline (about 0.5 s each).
    tts_seeds, tts_budget : int
        Seeds per case and budget of the time-to-success runs.
    seed : int
        Root seed of the random candidates.
    startup, tts : bool
        Include the child-process start-up figures / the time-to-success runs.
    """
    from . import c_kernel, naive

    say = progress or (lambda msg: None)
    loads = [os.getloadavg()[0]]
    # the candidates: the instance stream of run 0 of the root seed (naive.py draws the same)
    X = random_faults(stream(run_seed(seed, 0), "instance"), heterogeneity=1.0, n=batch)
    Xs = X[:serial]
    try:
        c_lib = c_kernel.build()
        c_reason = None
    except c_kernel.CKernelUnavailable as exc:
        c_lib, c_reason = None, str(exc)

    E12 = tier12_effects(len(Xs), seed)
    effects = {4: None, 12: E12}

    def singles(E: np.ndarray | None = None) -> list[float]:
        """ms of each one-candidate call (the median is over calls: a preempted call is one
        slow sample, not a slower average)."""
        ms = []
        for i, x in enumerate(Xs):
            t = time.perf_counter()
            simulate_monitor(x[None, :], None if E is None else E[i:i + 1])
            ms.append(1e3 * (time.perf_counter() - t))
        return ms

    # warm-up: compile or load every kernel before timing
    simulate_monitor(X[:2 * numba.get_num_threads()], parallel=True)
    simulate_monitor(Xs[:1], parallel=False)
    if c_lib is not None:
        c_kernel.simulate_c(Xs[:1], library=c_lib)
    simulate_monitor(Xs, parallel=False, lanes=False)
    say("tier set-up (suite emafdi-v2's first instance of tiers 4, 7, 12)")
    setups = tier_setups(len(Xs), seed)
    for E in effects.values():   # and the effect-carrying kernels
        simulate_monitor(Xs, E, parallel=False)
        simulate_monitor(Xs[:1], None if E is None else E[:1], parallel=False)
        if c_lib is not None:
            c_kernel.simulate_c(Xs[:1], None if E is None else E[:1], library=c_lib)
            c_kernel.simulate_c(Xs, E, library=c_lib, lanes=True)
    batched, serial_cpu, scalar_cpu, single, ratio, lane_ratio = [], [], [], [], [], []
    tiers: dict[int, list[float]] = {t: [] for t in TIERS}
    c_lanes: dict[int, list[float]] = {t: [] for t in effects}
    c_lanes_scalar: dict[int, list[float]] = {t: [] for t in effects}
    single12: list[float] = []
    for r in range(repeat):
        say(f"interleaved round {r + 1}/{repeat}")
        wall, cpu = _timed(lambda: simulate_monitor(X, parallel=True))
        batched.append(batch / wall)
        _, cpu = _timed(lambda: simulate_monitor(Xs, parallel=False))
        serial_cpu.append(serial / cpu)
        _, cpu_scalar = _timed(lambda: simulate_monitor(Xs, parallel=False, lanes=False))
        scalar_cpu.append(serial / cpu_scalar)
        if c_lib is not None:
            _, c_cpu = _timed(lambda: c_kernel.simulate_c(Xs, library=c_lib))
            ratio.append(cpu_scalar / c_cpu)
            lane_ratio.append(cpu / c_cpu)
        single.extend(singles())
        single12.extend(singles(E12))
        for t, rate in tier_rates(setups).items():
            tiers[t].append(rate)
        if c_lib is not None:   # numba lanes, C lanes and scalar C, tier 4 and tier 12
            for t, E in effects.items():
                _, lanes_cpu = _timed(lambda E=E: simulate_monitor(Xs, E, parallel=False))
                _, cl_cpu = _timed(lambda E=E: c_kernel.simulate_c(Xs, E, library=c_lib,
                                                                   lanes=True))
                _, cs_cpu = _timed(lambda E=E: c_kernel.simulate_c(Xs, E, library=c_lib))
                c_lanes[t].append(lanes_cpu / cl_cpu)
                c_lanes_scalar[t].append(cl_cpu / cs_cpu)
        loads.append(os.getloadavg()[0])
    say("one-candidate calls with both cores busy")
    with busy_cores(os.cpu_count() or 2):
        loaded = [v for _ in range(repeat) for v in singles()]
        loads.append(os.getloadavg()[0])
    say(f"plain-Python baseline ({naive_evals} evaluations, ~0.5 s each)")
    nv = naive.naive_python_timing(naive_evals, seed)
    evals_cpu = _median(serial_cpu)
    def episode() -> object:
        return simulate_reference(CASES["full"].x, seed=stream(run_seed(seed, 0), "noise"))

    episode()   # untimed: the first call loads (or, on a stale cache, compiles) the kernel
    t_ref = _median([_timed(episode)[0] for _ in range(3)])
    result: dict[str, object] = {
        "monitor_evals_per_s": _median(batched),
        "monitor_evals_per_cpu_s": evals_cpu,
        "monitor_evals_per_cpu_s_scalar": _median(scalar_cpu),
        "lanes_speedup": _median([a / b for a, b in zip(serial_cpu, scalar_cpu, strict=True)]),
        "single_call_ms": _median(single),
        "single_call_ms_loaded": _median(loaded),
        "single_call_ms_loaded_p90": float(np.percentile(loaded, 90)),
        "c_time_ratio": _median(ratio) if ratio else None,
        "lanes_c_time_ratio": _median(lane_ratio) if lane_ratio else None,
        "c_unavailable": c_reason,
        "c_lanes_time_ratio": {str(t): _median(v) for t, v in c_lanes.items() if v} or None,
        "c_lanes_vs_c_scalar": ({str(t): _median(v) for t, v in c_lanes_scalar.items() if v}
                                or None),
        "tier_evals_per_cpu_s": {str(t): _median(v) for t, v in tiers.items()},
        "tier_ratio": {str(t): _median(v) / _median(tiers[4]) for t, v in tiers.items()},
        "single_call_ms_tier12": _median(single12),
        "naive_python_evals_per_s": nv["evals_per_cpu_s"],
        "speedup_vs_naive_python": evals_cpu / nv["evals_per_cpu_s"],
        "reference_episode_s": t_ref,
    }
    if startup:
        say("start-up figures (fresh processes, one cold compile)")
        result.update(startup_figures())
    if tts:
        result.update(time_to_success(seeds=tts_seeds, budget=tts_budget, progress=say))
    loads.append(os.getloadavg()[0])
    result.update({
        "load_avg": {"before": loads[0], "max": max(loads), "after": loads[-1]},
        "rounds": repeat, "batch": batch, "serial_batch": serial,
        "numba_threads": numba.get_num_threads(),
        "threading_layer": _threading_layer(),
        "cpu_count": os.cpu_count(), "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(), "numba": numba.__version__,
        "numpy": np.__version__,
    })
    return result


def _threading_layer() -> str | None:
    try:
        return numba.threading_layer()
    except ValueError:   # no parallel kernel ran
        return None
