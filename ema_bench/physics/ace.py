"""ACE: actuator control electronics (position loop, speed PI, current reference).

Sampled at ``dt_ctrl`` with zero-order hold; both integrators call :func:`ace_update` at each
controller sample (from the shared skeleton, :mod:`ema_bench.physics.integrator`), so the
control law exists once.
"""

from __future__ import annotations

import math
from collections import namedtuple

from numba import njit

from ..params import P_DTC, P_KE, P_KGP, P_KIV, P_KPV, P_TAU, P_TMAX, P_WMAX

CtrlConsts = namedtuple("CtrlConsts", ("k_pos", "w_max", "kpv", "kiv", "t_max", "dtc",
                                       "amps_per_nm"))
CtrlConsts.__doc__ = "Per-candidate constants of :func:`ace_update` (see :func:`ace_consts`)."


@njit(cache=True, error_model="numpy")
def ace_consts(p, gprop):
    """Controller constants for position-loop gain ``gprop`` (1/s, the ``Gprop`` fault).

    ``K_GP * Gprop`` is the loop gain at the surface; referred to the motor it is divided by
    the reducer ratio ``tau``."""
    return CtrlConsts(p[P_KGP] * gprop / p[P_TAU], p[P_WMAX], p[P_KPV], p[P_KIV], p[P_TMAX],
                      p[P_DTC], 1.0 / (2.0 * p[P_KE]))


@njit(cache=True, inline="always", error_model="numpy")
def ace_update(theta_cmd, theta_u_meas, w_m_meas, integ, cc):
    """One controller sample.

    Parameters
    ----------
    theta_cmd, theta_u_meas : float
        rad, surface command and measured surface position.
    w_m_meas : float
        rad/s, measured motor speed.
    integ : float
        rad, speed-error integral (state of the PI).
    cc : CtrlConsts

    Returns
    -------
    i_ref : float
        A, current reference ``T_ref / (2 Ke)`` for the conducting phase pair.
    integ : float
        Updated integral; conditional integration stops it winding up while the torque
        reference is saturated in the direction of the error.
    """
    w_ref = cc.k_pos * (theta_cmd - theta_u_meas)
    if w_ref > cc.w_max:
        w_ref = cc.w_max
    elif w_ref < -cc.w_max:
        w_ref = -cc.w_max
    ew = w_ref - w_m_meas
    t_unsat = cc.kpv * ew + cc.kiv * integ
    t_ref = t_unsat
    if t_ref > cc.t_max:
        t_ref = cc.t_max
    elif t_ref < -cc.t_max:
        t_ref = -cc.t_max
    if t_ref == t_unsat or (t_unsat > cc.t_max and ew < 0.0) or \
            (t_unsat < -cc.t_max and ew > 0.0):
        integ += ew * cc.dtc
    return t_ref * cc.amps_per_nm, integ


@njit(cache=True, inline="always", error_model="numpy")
def _stored(buf, k):
    return buf[0] if k < 0 else buf[k % buf.shape[0]]


@njit(cache=True, inline="always", error_model="numpy")
def delayed_feedback(buf, k_ctrl, value, delay):
    """Store ``value`` as controller sample ``k_ctrl`` and return it ``delay`` samples ago.

    ``delay`` (controller samples, >= 0) may be fractional: linear interpolation between
    stored samples keeps the outputs smooth in the delay, which fitting and intervals need.
    Before the record starts, the first sample stands in.  ``buf`` must hold more than
    ``delay + 1`` samples."""
    buf[k_ctrl % buf.shape[0]] = value
    if delay <= 0.0:
        return value
    d0 = int(math.floor(delay))
    frac = delay - d0
    return (1.0 - frac) * _stored(buf, k_ctrl - d0) + frac * _stored(buf, k_ctrl - d0 - 1)
