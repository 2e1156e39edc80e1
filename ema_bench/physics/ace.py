"""ACE: actuator control electronics (position loop, speed PI, current reference).

Sampled at ``dt_ctrl`` with zero-order hold; both integrators call :func:`ace_update` at each
controller sample with the same arguments, so the control law exists once.
"""

from __future__ import annotations

import math

from numba import njit

from ..params import P_DTC, P_KE, P_KGP, P_KIV, P_KPV, P_TAU, P_TMAX, P_WMAX


@njit(cache=True)
def ace_update(theta_cmd, theta_u_meas, w_m_meas, integ, gprop, p):
    """One controller sample.

    Parameters
    ----------
    theta_cmd, theta_u_meas : float
        rad, surface command and measured surface position.
    w_m_meas : float
        rad/s, measured motor speed.
    integ : float
        rad, speed-error integral (state of the PI).
    gprop : float
        1/s, position-loop gain (the ``Gprop`` fault); ``K_GP * Gprop`` is the loop gain at the
        surface.
    p : ndarray
        Parameter array (:mod:`ema_bench.params`).

    Returns
    -------
    i_ref : float
        A, current reference ``T_ref / (2 Ke)`` for the conducting phase pair.
    integ : float
        Updated integral; conditional integration stops it winding up while the torque
        reference is saturated in the direction of the error.
    """
    e_m = (theta_cmd - theta_u_meas) / p[P_TAU]          # error referred to the motor, rad
    w_ref = p[P_KGP] * gprop * e_m
    w_max = p[P_WMAX]
    if w_ref > w_max:
        w_ref = w_max
    elif w_ref < -w_max:
        w_ref = -w_max
    ew = w_ref - w_m_meas
    t_unsat = p[P_KPV] * ew + p[P_KIV] * integ
    t_max = p[P_TMAX]
    t_ref = min(max(t_unsat, -t_max), t_max)
    if t_ref == t_unsat or (t_unsat > t_max and ew < 0.0) or (t_unsat < -t_max and ew > 0.0):
        integ += ew * p[P_DTC]
    return t_ref / (2.0 * p[P_KE]), integ


@njit(cache=True)
def _stored(buf, k):
    return buf[0] if k < 0 else buf[k % buf.shape[0]]


@njit(cache=True)
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
