"""The monitor model: the cheap EMA model that solvers evaluate thousands of times.

Same logical structure and fault parameters as the reference model, but the three-phase motor
and its hysteresis current loop are replaced by the single-phase equivalent of the conducting
pair (:func:`ema_bench.physics.bldc.pair_constants`) with an ideal current loop whose rise is
limited by the available voltage, ``L dI/dt <= V_dc - Kt w - R I``.  The controller, mechanics,
backlash, friction and load are the very same compiled functions as in the reference.  One call
simulates a batch of candidate fault vectors in parallel (numba ``prange``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit, prange

from .effects import (
    E_ECC,
    E_VISC,
    MAX_DELAY_SAMPLES,
    N_EFFECTS,
)
from .faults import check_faults, faults_to_dict
from .params import DEFAULT_PARAMS, P_HYST, P_IRIP, P_KTF, EMAParams
from .physics.ace import ace_update, delayed_feedback
from .physics.bldc import pair_constants
from .physics.effect_terms import cogging_torque, effect_terms
from .physics.load import hinge_moment
from .physics.mechanics import mech_step
from .protocol import STANDARD_TESTS, TestSpec, steps_per
from .reference import SimulationError
from .traces import OUTPUT_DT, Traces


@njit(cache=True)
def monitor_one(p, x, e, cmd, n_out, steps_out, steps_ctrl, dt, out):
    """Integrate one candidate on one test; window means into ``out`` (n_out, 4).

    Returns False if the state became non-finite."""
    na, fst, blk, gprop = x[0], x[1], x[2], x[3]
    offset, gain, v_dc, r_scale, ks_scale, n_delay = effect_terms(e, p)
    ripple = p[P_IRIP] * p[P_HYST]
    buf = np.zeros(MAX_DELAY_SAMPLES + 1)
    th_m = w_m = th_u = w_u = 0.0
    cur = 0.0
    i_ref = integ = 0.0
    k_ctrl = 0
    countdown = 0
    for k in range(n_out):
        a0 = a1 = a2 = a3 = 0.0
        for _ in range(steps_out):
            if countdown == 0:
                fb = delayed_feedback(buf, k_ctrl, th_u + offset, n_delay)
                i_ref, integ = ace_update(cmd[k_ctrl], fb, w_m, integ, gprop, p)
                k_ctrl += 1
                countdown = steps_ctrl
            countdown -= 1
            kt, r_pair, l_pair = pair_constants(th_m, na, e[E_ECC], p)
            r_pair *= r_scale
            # ideal current loop, limited by the bus voltage
            target = i_ref
            hi = cur + dt * (v_dc - kt * w_m - r_pair * cur) / l_pair
            lo = cur + dt * (-v_dc - kt * w_m - r_pair * cur) / l_pair
            cur_old = cur
            cur = min(max(target, lo), hi)
            t_m = p[P_KTF] * kt * cur
            t_m += cogging_torque(e, th_m, p)
            t_load = hinge_moment(th_u, w_u, p, e)
            th_m, w_m, th_u, w_u, _ = mech_step(th_m, w_m, th_u, w_u, t_m, t_load, fst, blk,
                                                e[E_VISC], ks_scale, p, dt)
            a0 += th_u
            a1 += th_m
            a2 += w_m
            # exact step mean of the current: it ramps at the voltage-limited slope until it
            # reaches its target, then holds (a rise to 20 A takes ~1.5 steps, so end-of-step
            # samples would bias the window mean)
            delta = cur - cur_old
            span = (hi if delta > 0.0 else lo) - cur_old
            frac = delta / span if span != 0.0 else 1.0
            a3 += abs(cur - 0.5 * delta * frac)
        out[k, 0] = a0 / steps_out + offset
        out[k, 1] = a1 / steps_out
        out[k, 2] = a2 / steps_out
        out[k, 3] = gain * a3 / steps_out + ripple
        if not (math.isfinite(a0) and math.isfinite(a2) and math.isfinite(a3)):
            return False
    return True


@njit(parallel=True, cache=True)
def monitor_batch(p, X, E, cmd, n_out, steps_out, steps_ctrl, dt, out, ok):
    """Candidates ``X`` (n, 4) with effects ``E`` (n, N_EFFECTS) on one test, in parallel."""
    for c in prange(X.shape[0]):
        ok[c] = monitor_one(p, X[c], E[c], cmd, n_out, steps_out, steps_ctrl, dt, out[c])


def simulate_monitor(
    X: np.ndarray,
    E: np.ndarray | None = None,
    *,
    tests: Sequence[TestSpec] = STANDARD_TESTS,
    params: EMAParams = DEFAULT_PARAMS,
    dt: float | None = None,
    check: bool = True,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Simulate a batch of candidate fault vectors with the monitor model.

    Parameters
    ----------
    X : ndarray, shape (n, 4)
        Candidate fault vectors in physical units (``FAULT_NAMES`` order).
    E : ndarray, shape (n, N_EFFECTS) or (N_EFFECTS,), optional
        Effects per candidate (augmented monitor); zeros by default.
    dt : float, optional
        Step (s); default ``params.dt_mon``.  Must divide the controller period.
    check : bool
        Validate ``X`` (shape, finite, in bounds).  Callers that already did may skip it.

    Returns
    -------
    outputs : dict
        Test name -> array (n, n_samples, 4) of clean window-averaged outputs.
    ok : ndarray of bool, shape (n,)
        False where a candidate's simulation became non-finite on any test.
    """
    X = check_faults(X, batch=True) if check else np.ascontiguousarray(X, dtype=np.float64)
    n = X.shape[0]
    if E is None:
        E = np.zeros((n, N_EFFECTS))
    E = np.ascontiguousarray(np.broadcast_to(np.asarray(E, dtype=np.float64), (n, N_EFFECTS)))
    p = params.to_array()
    dt = params.dt_mon if dt is None else float(dt)
    steps_out = steps_per(OUTPUT_DT, dt)
    steps_ctrl = steps_per(params.dt_ctrl, dt)
    outputs = {}
    ok_all = np.ones(n, dtype=np.bool_)
    for spec in tests:
        out = np.empty((n, spec.n_samples(), 4))
        ok = np.empty(n, dtype=np.bool_)
        cmd = spec.command_at_samples(params.dt_ctrl)
        monitor_batch(p, X, E, cmd, out.shape[1], steps_out, steps_ctrl, dt, out, ok)
        ok_all &= ok
        outputs[spec.name] = out
    return outputs, ok_all


def monitor_traces(x: np.ndarray, effects: np.ndarray | None = None, *,
                   tests: Sequence[TestSpec] = STANDARD_TESTS,
                   params: EMAParams = DEFAULT_PARAMS) -> Traces:
    """Clean monitor traces of one fault vector, as a :class:`Traces`."""
    x = check_faults(x)
    outputs, ok = simulate_monitor(x[None, :], None if effects is None else effects[None, :],
                                   tests=tests, params=params)
    if not ok[0]:
        raise SimulationError(f"monitor model diverged at faults {faults_to_dict(x)}")
    return Traces(data={k: v[0] for k, v in outputs.items()}, dt=OUTPUT_DT,
                  meta={"model": "monitor", "faults": faults_to_dict(x)})
