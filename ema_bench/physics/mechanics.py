"""Two-mass mechanics: motor rotor, reducer with stiffness, damping and backlash, dry friction
with stick / breakaway / slip / stop (Karnopp-Borello type), surface with end stops.

States: motor angle ``th_m`` and speed ``w_m`` (motor side, rad, rad/s), surface angle ``th_u``
and speed ``w_u`` (rad, rad/s).  Integrated with semi-implicit Euler (speeds first), which is
stable for the stiff contact at both model steps.  Both integrators call :func:`mech_step`.
"""

from __future__ import annotations

from numba import njit

from ..params import (
    P_CM,
    P_CS,
    P_CSTOP,
    P_FDYN,
    P_JM,
    P_JU,
    P_KS,
    P_KSTOP,
    P_TAU,
    P_THSTOP,
    P_WSTICK,
)


@njit(cache=True)
def gear_torque(delta, d_delta, blk, k_s, c_s):
    """Torque transmitted by the reducer at the surface side, N m.

    Parameters
    ----------
    delta : float
        rad, ``tau * th_m - th_u`` (gear output minus surface).
    d_delta : float
        rad/s, its rate.
    blk : float
        rad, total backlash: no torque while ``|delta| <= blk / 2``.
    k_s, c_s : float
        N m/rad, N m s/rad: contact stiffness and damping.

    The contact pushes but never pulls: damping cannot make the torque change sign.
    """
    half = 0.5 * blk
    if delta > half:
        t = k_s * (delta - half) + c_s * d_delta
        return t if t > 0.0 else 0.0
    if delta < -half:
        t = k_s * (delta + half) + c_s * d_delta
        return t if t < 0.0 else 0.0
    return 0.0


@njit(cache=True)
def friction_speed(w, t_drive, fst, fdyn, j, dt, w_stick):
    """Advance a speed ``w`` under driving torque ``t_drive`` and dry friction, one step.

    Stick: inside the band ``|w| < w_stick`` the shaft stays at rest while ``|t_drive| <= fst``.
    Breakaway: above it, it accelerates against the dynamic level ``fdyn``.  Slip: kinetic
    friction opposes the motion.  Stop: a speed that would change sign within the step is set
    to zero, so the next step decides between stick and breakaway.

    Returns the new speed, rad/s.
    """
    if abs(w) < w_stick:
        if abs(t_drive) <= fst:
            return 0.0
        s = 1.0 if t_drive > 0.0 else -1.0
        return w + dt * (t_drive - s * fdyn) / j
    s = 1.0 if w > 0.0 else -1.0
    w_new = w + dt * (t_drive - s * fdyn) / j
    if w_new * w < 0.0:
        return 0.0
    return w_new


@njit(cache=True)
def mech_step(th_m, w_m, th_u, w_u, t_m, t_load, fst, blk, c_m_extra, ks_scale, p, dt):
    """Advance the 2-DOF mechanics by ``dt``.

    Parameters
    ----------
    t_m : float
        N m, electromagnetic torque on the rotor (plus any cogging torque).
    t_load : float
        N m, external moment on the surface (hinge moment).
    fst : float
        N m, static dry friction at the motor shaft (the ``Fst`` fault); the dynamic level is
        ``friction_dyn_ratio * fst``.
    blk : float
        rad, total backlash (the ``BLK`` fault).
    c_m_extra : float
        N m s/rad, extra motor viscous friction (``viscous_friction`` effect).
    ks_scale : float
        multiplier of the transmission stiffness (``gear_stiffness`` effect; 1 = healthy).

    Returns
    -------
    th_m, w_m, th_u, w_u, t_gear
        New states and the transmitted torque at the surface (N m).
    """
    tau = p[P_TAU]
    delta = tau * th_m - th_u
    d_delta = tau * w_m - w_u
    t_g = gear_torque(delta, d_delta, blk, p[P_KS] * ks_scale, p[P_CS])
    # end stops on the surface: stiff spring-damper beyond +-theta_stop
    t_stop = 0.0
    if th_u > p[P_THSTOP]:
        t_stop = min(0.0, -p[P_KSTOP] * (th_u - p[P_THSTOP]) - p[P_CSTOP] * w_u)
    elif th_u < -p[P_THSTOP]:
        t_stop = max(0.0, -p[P_KSTOP] * (th_u + p[P_THSTOP]) - p[P_CSTOP] * w_u)
    w_u = w_u + dt * (t_g + t_load + t_stop) / p[P_JU]
    t_drive = t_m - (p[P_CM] + c_m_extra) * w_m - tau * t_g
    w_m = friction_speed(w_m, t_drive, fst, p[P_FDYN] * fst, p[P_JM], dt, p[P_WSTICK])
    return th_m + dt * w_m, w_m, th_u + dt * w_u, w_u, t_g
