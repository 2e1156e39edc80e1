"""Naive baseline for the speed benchmark: the monitor equations as a continuous-time ODE,
integrated per candidate with ``scipy.integrate.solve_ivp`` in plain Python.

It reuses the pure-Python versions (``.py_func``) of the very same physics blocks, so the
benchmark ratio measures compilation, batching and the fixed-step scheme, not different
physics.  The sampled controller becomes continuous and the current loop a first-order lag of
one controller period, which is what a straightforward ODE port of the monitor looks like.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from .effects import N_EFFECTS
from .faults import check_faults
from .params import (
    DEFAULT_PARAMS,
    P_CM,
    P_CS,
    P_DTC,
    P_FDYN,
    P_JM,
    P_JU,
    P_KE,
    P_KGP,
    P_KIV,
    P_KPV,
    P_KS,
    P_KTF,
    P_TAU,
    P_TMAX,
    P_VDC,
    P_WMAX,
    P_WSTICK,
    EMAParams,
)
from .physics.bldc import pair_constants
from .physics.command import command_value
from .physics.load import hinge_moment
from .physics.mechanics import gear_torque
from .protocol import STANDARD_TESTS, TestSpec
from .traces import OUTPUT_DT

_pair = pair_constants.py_func
_cmd = command_value.py_func
_hinge = hinge_moment.py_func
_gear = gear_torque.py_func
_NO_EFFECTS = np.zeros(N_EFFECTS)


def _rhs(t, y, x, p, cmd):
    th_m, w_m, th_u, w_u, cur, integ = y[:6]
    na, fst, blk, gprop = x
    # continuous version of ema_bench.physics.ace.ace_update
    w_ref = min(max(p[P_KGP] * gprop * (_cmd(cmd, t) - th_u) / p[P_TAU], -p[P_WMAX]),
                p[P_WMAX])
    ew = w_ref - w_m
    t_unsat = p[P_KPV] * ew + p[P_KIV] * integ
    t_ref = min(max(t_unsat, -p[P_TMAX]), p[P_TMAX])
    d_integ = ew if (t_ref == t_unsat or t_unsat * ew < 0.0) else 0.0
    kt, r_pair, l_pair = _pair(th_m, na, 0.0, p)
    v = p[P_VDC]
    d_cur = (t_ref / (2.0 * p[P_KE]) - cur) / p[P_DTC]
    d_cur = min(max(d_cur, (-v - kt * w_m - r_pair * cur) / l_pair),
                (v - kt * w_m - r_pair * cur) / l_pair)
    t_g = _gear(p[P_TAU] * th_m - th_u, p[P_TAU] * w_m - w_u, blk, p[P_KS], p[P_CS])
    t_drive = p[P_KTF] * kt * cur - p[P_CM] * w_m - p[P_TAU] * t_g
    fdyn = p[P_FDYN] * fst
    if abs(w_m) < p[P_WSTICK] and abs(t_drive) <= fst:
        a_m = 0.0   # Karnopp stick
    else:
        s = math.copysign(1.0, w_m if abs(w_m) >= p[P_WSTICK] else t_drive)
        a_m = (t_drive - s * fdyn) / p[P_JM]
    a_u = (t_g + _hinge(th_u, w_u, p, _NO_EFFECTS)) / p[P_JU]
    # the last 4 states integrate the outputs: window means without dense output
    return [w_m, a_m, w_u, a_u, d_cur, d_integ, th_u, th_m, w_m, abs(cur)]


def simulate_naive(x: np.ndarray, *, tests: tuple[TestSpec, ...] = STANDARD_TESTS,
                   params: EMAParams = DEFAULT_PARAMS) -> dict[str, np.ndarray]:
    """Monitor outputs of one candidate via ``solve_ivp`` (RK45), window by window.

    Returns test name -> array (n_samples, 4), like one row of ``simulate_monitor``.
    """
    x = tuple(check_faults(x))
    p = params.to_array()
    result = {}
    for spec in tests:
        cmd = spec.command()
        y = np.zeros(10)
        out = np.empty((spec.n_samples(), 4))
        for k in range(out.shape[0]):
            y[6:] = 0.0
            sol = solve_ivp(_rhs, (k * OUTPUT_DT, (k + 1) * OUTPUT_DT), y, args=(x, p, cmd),
                            method="RK45", rtol=1e-6, atol=1e-9, max_step=params.dt_ctrl)
            y = sol.y[:, -1].copy()
            out[k] = y[6:] / OUTPUT_DT
        result[spec.name] = out
    return result
