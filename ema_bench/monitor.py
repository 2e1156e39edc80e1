"""The monitor model: the cheap EMA model that solvers evaluate thousands of times.

Same logical structure and fault parameters as the reference model, with the three-phase motor
and its hysteresis current loop replaced by the averaged drive of the conducting pair
(:mod:`ema_bench.physics.averaged_drive`) and one 50 microsecond step per controller sample.
The controller, the mechanics (backlash, friction, load) and the window outputs are the very
same compiled code as in the reference (:mod:`ema_bench.physics.integrator`,
:mod:`ema_bench.physics.mechanics`).  One call simulates a batch of candidates, all tests, in
parallel over candidates (numba ``prange``); batches smaller than twice the thread count run on
the calling thread, where waking the worker threads would cost more than it saves, and so does
every batch where numba has one thread (a worker process).  Candidates
run in vectorised lock-step groups of eight (:mod:`ema_bench.monitor_lanes`, about twice the
candidates per CPU-second, bit-identical outputs), carrying the sensor, controller and plant
effects of suite emafdi-v2's tiers (``LANE_EFFECTS``); a single candidate, and candidates with
another effect on (resistance rise, voltage sag, the decoys), run in the scalar kernel here.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numba
import numpy as np
from numba import njit, prange

from .effects import N_EFFECTS, effects_to_dict
from .faults import check_faults, faults_to_dict
from .monitor_plant import monitor_consts, monitor_init, monitor_step
from .params import DEFAULT_PARAMS, EMAParams
from .physics.integrator import integrate
from .protocol import STANDARD_TESTS, TestSpec, steps_per
from .reference import SimulationError
from .threads import configure_threads
from .traces import OUTPUT_DT, Traces

configure_threads()


# --- batched kernels ----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _candidate(p, x, e, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick, dt, out):
    """Every test of one candidate; ``out`` is its (total_samples, 4) block."""
    ok = True
    for t in range(n_out.shape[0]):
        ok &= integrate(monitor_consts, monitor_init, monitor_step, p, x, e,
                        cmd[cmd_start[t]:cmd_start[t + 1]], n_out[t], ticks_out, steps_tick,
                        dt, out[out_start[t]:out_start[t] + n_out[t]])
    return ok


@njit(parallel=True, cache=True, error_model="numpy")
def monitor_batch_parallel(p, X, E, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                           dt, out, ok):
    """Candidates ``X`` (n, 4) with effects ``E`` (n, N_EFFECTS), in parallel."""
    for c in prange(X.shape[0]):
        ok[c] = _candidate(p, X[c], E[c], cmd, cmd_start, n_out, out_start, ticks_out,
                           steps_tick, dt, out[c])


@njit(cache=True, error_model="numpy")
def monitor_batch_serial(p, X, E, cmd, cmd_start, n_out, out_start, ticks_out, steps_tick,
                         dt, out, ok):
    """As :func:`monitor_batch_parallel`, on the calling thread."""
    for c in range(X.shape[0]):
        ok[c] = _candidate(p, X[c], E[c], cmd, cmd_start, n_out, out_start, ticks_out,
                           steps_tick, dt, out[c])


def test_layout(tests: Sequence[TestSpec], dt_ctrl: float) -> tuple[np.ndarray, ...]:
    """Commands of ``tests`` concatenated, with where each test's command and outputs start.

    Returns ``(cmd, cmd_start, n_out, out_start)``, computed once per (tests, step): the
    arrays are shared between calls (the kernels only read them)."""
    return _layout(tuple(tests), float(dt_ctrl))


@functools.lru_cache(maxsize=16)
def _layout(tests: tuple[TestSpec, ...], dt_ctrl: float) -> tuple[np.ndarray, ...]:
    cmds = [spec.command_at_samples(dt_ctrl) for spec in tests]
    n_out = np.array([spec.n_samples() for spec in tests], dtype=np.int64)
    cmd_start = np.concatenate([[0], np.cumsum([c.size for c in cmds])]).astype(np.int64)
    out_start = np.concatenate([[0], np.cumsum(n_out)[:-1]]).astype(np.int64)
    return np.concatenate(cmds), cmd_start, n_out, out_start


def simulate_monitor(
    X: np.ndarray,
    E: np.ndarray | None = None,
    *,
    tests: Sequence[TestSpec] = STANDARD_TESTS,
    params: EMAParams = DEFAULT_PARAMS,
    dt: float | None = None,
    check: bool = True,
    parallel: bool | None = None,
    lanes: bool | None = None,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Simulate a batch of candidate fault vectors with the monitor model.

    Parameters
    ----------
    X : ndarray, shape (n, 4)
        Candidate fault vectors in physical units (``FAULT_NAMES`` order).
    E : ndarray, shape (n, N_EFFECTS) or (N_EFFECTS,), optional
        Effects per candidate (augmented monitor); zeros by default.
    tests : sequence of TestSpec
        Protocol tests to run (each candidate runs them all).
    params : EMAParams
        Physical parameters.
    dt : float, optional
        Step (s); default ``params.dt_mon``.  Must divide the controller period.
    check : bool
        Validate ``X`` (shape, finite, in bounds).  Callers that already did may skip it.
    parallel : bool, optional
        Run candidates on numba's threads; default: on more than one thread, when the batch
        has at least twice as many candidates as threads (for the lanes: at least one group
        per thread).
    lanes : bool, optional
        Run the candidates with no effect outside ``LANE_EFFECTS`` in lock-step groups of eight
        (:mod:`ema_bench.monitor_lanes`: vectorised, bit-identical outputs); default: for
        full groups, and for a last group of at least ``LANES_WORTH`` candidates.  False:
        the scalar kernel for all.

    Returns
    -------
    outputs : dict
        Test name -> array (n, n_samples, 4) of clean window-averaged outputs (views into one
        block).
    ok : ndarray of bool, shape (n,)
        False where a candidate's simulation became non-finite on any test.
    """
    X = check_faults(X, batch=True) if check else np.ascontiguousarray(X, dtype=np.float64)
    n = X.shape[0]
    if E is None:
        E = np.zeros((n, N_EFFECTS))
    else:   # a writeable copy: one compiled signature (a read-only view would be another)
        E = np.array(np.broadcast_to(np.asarray(E, dtype=np.float64), (n, N_EFFECTS)),
                     order="C")
    dt = params.dt_mon if dt is None else float(dt)
    ticks_out = steps_per(OUTPUT_DT, params.dt_ctrl)
    steps_tick = steps_per(params.dt_ctrl, dt)
    cmd, cmd_start, n_out, out_start = test_layout(tests, params.dt_ctrl)
    out = np.empty((n, int(n_out.sum()), 4))
    ok = np.empty(n, dtype=np.bool_)
    p = params.to_array()
    layout = (cmd, cmd_start, n_out, out_start, ticks_out, steps_tick, dt)
    grouped, rest = _lane_split(E, lanes)
    if grouped.size:
        from .monitor_lanes import lane_groups, lanes_parallel, lanes_serial

        groups = lane_groups(grouped)
        par = _parallel(groups.shape[0]) if parallel is None else parallel
        (lanes_parallel if par else lanes_serial)(p, X, E, groups, *layout, out, ok)
    if rest.size == n:
        _scalar(p, X, E, layout, out, ok, parallel)
    elif rest.size:
        out_r = np.empty((rest.size, *out.shape[1:]))
        ok_r = np.empty(rest.size, dtype=np.bool_)
        _scalar(p, X[rest], E[rest], layout, out_r, ok_r, parallel)
        out[rest] = out_r
        ok[rest] = ok_r
    outputs = {spec.name: out[:, s:s + k] for spec, s, k in zip(tests, out_start, n_out)}
    return outputs, ok


#: Smallest last group worth running in lanes: a group of eight costs what about four
#: candidates cost in the scalar kernel (``ema-bench bench``: ``lanes_speedup`` about 2),
#: whatever its number of real candidates, so from five on it wins.
LANES_WORTH = 5


def _lane_split(E: np.ndarray, lanes: bool | None) -> tuple[np.ndarray, np.ndarray]:
    """Rows for the lanes (no effect on but ``LANE_EFFECTS``) and rows for the scalar
    kernel."""
    from .monitor_lanes import LANE_EFFECT_INDEX, LANES

    n = E.shape[0]
    if lanes is False:
        return np.empty(0, dtype=np.int64), np.arange(n)
    plant = np.ones(E.shape[1], dtype=bool)
    plant[LANE_EFFECT_INDEX] = False
    plain = ~E[:, plant].any(axis=1)
    rows = np.flatnonzero(plain)
    keep = rows.size - rows.size % LANES
    if rows.size - keep >= (1 if lanes else LANES_WORTH):
        keep = rows.size
    return rows[:keep], np.sort(np.concatenate([np.flatnonzero(~plain), rows[keep:]]))


def _parallel(units: int) -> bool:
    """Whether ``units`` (lane groups, or scalar candidates over two) are worth numba's
    threads: at least one per thread, and more than one thread.  On one thread (a worker
    process of a sweep or a replay) the serial kernel does the same work without waking a
    threading layer, and a process that calls only it never loads the parallel kernels
    from numba's cache (a replay worker forked from :mod:`~ema_bench.leaderboard.
    replay_server` finds the serial ones loaded)."""
    threads = numba.get_num_threads()
    return threads > 1 and units >= threads


def _scalar(p, X, E, layout, out, ok, parallel: bool | None) -> None:
    if parallel is None:
        parallel = _parallel(X.shape[0] // 2)
    kernel = monitor_batch_parallel if parallel else monitor_batch_serial
    kernel(p, X, E, *layout, out, ok)


def monitor_traces(x: np.ndarray, effects: np.ndarray | None = None, *,
                   tests: Sequence[TestSpec] = STANDARD_TESTS,
                   params: EMAParams = DEFAULT_PARAMS) -> Traces:
    """Clean monitor traces of one fault vector, as a :class:`Traces`."""
    x = check_faults(x)
    outputs, ok = simulate_monitor(x[None, :], None if effects is None else effects[None, :],
                                   tests=tests, params=params)
    if not ok[0]:
        raise SimulationError(f"monitor model diverged at faults {faults_to_dict(x)}")
    return Traces(data={k: np.ascontiguousarray(v[0]) for k, v in outputs.items()},
                  dt=OUTPUT_DT, meta={"model": "monitor", "faults": faults_to_dict(x),
                                      "effects": {} if effects is None else
                                      effects_to_dict(effects)})
