"""Two-mass mechanics: motor rotor, reducer with stiffness, damping and backlash, dry friction
with stick / breakaway / slip / stop (Karnopp-Borello type), surface with hinge load and end
stops.  Both integrators call :func:`mech_step`: the reference at its 1 microsecond step, the
monitor at 50 microseconds.

States: motor angle ``th_m`` and speed ``w_m`` (motor side, rad, rad/s), surface angle ``th_u``
and speed ``w_u`` (rad, rad/s).

The step is linearly implicit and second order (trapezoidal rule) for every linear force: the
reducer's contact spring-damper, the hinge spring and damping and the motor's viscous friction
enter a 2x2 solve for the end speeds, and positions advance with the mean speed.  Events are
located inside the step rather than at its end: contact entry (the spring-damper acts from the
crossing instant), lift-off (the explicit step mean along the straight path), the instant a
sliding shaft stops, and the instant a stuck shaft's drive torque crosses the static friction
level.  At 50 microseconds an explicit step with events at step boundaries put first-order
errors into every impact and breakaway (a fitted Na 0.5-1 % of its range off the truth) and made
the fitness a staircase in BLK and Fst; this formulation removes both.
"""

from __future__ import annotations

from collections import namedtuple

from numba import njit

from ..params import (
    P_CM,
    P_CS,
    P_CSTOP,
    P_CU,
    P_FDYN,
    P_JM,
    P_JU,
    P_KAERO,
    P_KS,
    P_KSTOP,
    P_TAU,
    P_THSTOP,
    P_WSTICK,
)

MechConsts = namedtuple("MechConsts", (
    "tau", "jm", "ju", "k", "c", "cm", "ka", "cu", "fst", "fdyn", "half", "w_stick",
    "th_stop", "k_stop", "c_stop", "h", "b_c", "g_h", "i11", "i12", "i22", "i_u_stuck",
    "i_m_free", "i_u_free", "i11h", "i12h", "i_m_free_h"))
MechConsts.__doc__ = """Per-candidate constants of :func:`mech_step` (see :func:`mech_consts`)."""


@njit(cache=True, error_model="numpy")
def mech_consts(p, fst, blk, c_m_extra, k_aero_extra, ks_scale, h):
    """Constants of the mechanics for one candidate and step ``h`` (s), computed once.

    Parameters
    ----------
    p : ndarray
        Parameter array (:mod:`ema_bench.params`).
    fst : float
        N m, static dry friction at the motor (the ``Fst`` fault); dynamic level
        ``friction_dyn_ratio * fst``.
    blk : float
        rad, total backlash at the surface (the ``BLK`` fault).
    c_m_extra, k_aero_extra, ks_scale : float
        Effects: extra motor viscous friction (N m s/rad), extra hinge spring (N m/rad),
        multiplier of the transmission stiffness.
    """
    tau, jm, ju = p[P_TAU], p[P_JM], p[P_JU]
    k = p[P_KS] * ks_scale
    c = p[P_CS]
    cm = p[P_CM] + c_m_extra
    ka = p[P_KAERO] + k_aero_extra
    cu = p[P_CU]
    # trapezoidal contact torque: A + b_c * d_delta_end; hinge: m0 - g_h * w_u_end
    b_c = 0.25 * k * h + 0.5 * c
    g_h = 0.25 * ka * h + 0.5 * cu
    # 2x2 system for (w_m_end, w_u_end) in contact, motor sliding: inverse, symmetric
    a11 = jm + 0.5 * h * cm + h * tau * tau * b_c
    a12 = -h * tau * b_c
    a22 = ju + h * b_c + h * g_h
    det = a11 * a22 - a12 * a12
    i11, i12, i_m_free = a22 / det, -a12 / det, 1.0 / (jm + 0.5 * h * cm)
    return MechConsts(tau, jm, ju, k, c, cm, ka, cu, fst, p[P_FDYN] * fst, 0.5 * blk,
                      p[P_WSTICK], p[P_THSTOP], p[P_KSTOP], p[P_CSTOP], h, b_c, g_h,
                      i11, i12, a11 / det, 1.0 / a22, i_m_free, 1.0 / (ju + h * g_h),
                      i11 * h, i12 * h, i_m_free * h)


@njit(cache=True, inline="always", error_model="numpy")
def contact_side(delta, half):
    """+1 / -1 when the reducer's flanks touch on the positive / negative side, 0 in the gap."""
    if delta > half:
        return 1
    if delta < -half:
        return -1
    return 0


@njit(cache=True, error_model="numpy")
def gear_torque(delta, d_delta, blk, k_s, c_s):
    """Torque transmitted by the reducer at the surface side, N m (a point evaluation).

    ``delta = tau * th_m - th_u`` (rad), ``d_delta`` its rate (rad/s); no torque while
    ``|delta| <= blk / 2``; the contact pushes but never pulls.  The reducer's law as a
    reader checks it: the kernels integrate it over each step (:func:`gear_mean`, the
    contact solves), and ``tests/test_physics.py`` holds the step mean to this law's mean."""
    half = 0.5 * blk
    if delta > half:
        t = k_s * (delta - half) + c_s * d_delta
        return t if t > 0.0 else 0.0
    if delta < -half:
        t = k_s * (delta + half) + c_s * d_delta
        return t if t < 0.0 else 0.0
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def _side_mean(a, lim, k, c, d0, dd, h):
    """Step mean of ``k (d - lim) + c dd`` over the part of ``[0, h]`` where the straight path
    ``d = d0 + dd t`` lies above ``a`` (zero elsewhere)."""
    if dd == 0.0:
        if d0 <= a:
            return 0.0
        t1, t2 = 0.0, h
    else:
        tc = (a - d0) / dd
        if dd > 0.0:
            t1, t2 = (tc if tc > 0.0 else 0.0), h
        else:
            t1, t2 = 0.0, (tc if tc < h else h)
        if t2 <= t1:
            return 0.0
    f1 = k * (d0 + dd * t1 - lim) + c * dd
    f2 = k * (d0 + dd * t2 - lim) + c * dd
    return 0.5 * (t2 - t1) * (f1 + f2) / h


@njit(cache=True, inline="always", error_model="numpy")
def gear_mean(delta, d_delta, half, k, c, h):
    """Explicit step mean of the reducer torque along the straight path ``delta + d_delta t``,
    with contact entry and lift-off located inside the step (used where the contact state
    changes within the step)."""
    # the damped contact lifts off where k (delta - half) + c d_delta reaches zero
    lift = c * d_delta / k
    t = _side_mean(half + (-lift if lift < 0.0 else 0.0), half, k, c, delta, d_delta, h)
    t -= _side_mean(half + (lift if lift > 0.0 else 0.0), half, k, c, -delta, -d_delta, h)
    return t


@njit(cache=True, inline="always", error_model="numpy")
def _rhs(th_u, w_m, w_u, t_ext, sgn, fdyn, mc):
    """The motor's and the surface's right-hand sides without the reducer and motor torques
    (the motor torque enters last, one multiply-add before the end speeds: it ends the step's
    critical path)."""
    h = mc.h
    r1 = mc.jm * w_m - h * (sgn * fdyn + 0.5 * mc.cm * w_m)
    r2 = mc.ju * w_u + h * ((-mc.ka * th_u - mc.g_h * w_u) + t_ext)
    return r1, r2


@njit(cache=True, inline="always", error_model="numpy")
def _contact_solve(delta, dd, side, r1, r2, t_m, moving, mc):
    """End speeds and step-mean reducer torque for a step spent in contact on ``side``: the
    spring-damper by the trapezoidal rule, ``t_g = a + b_c dd_end``, a 2x2 solve."""
    return _contact_at(delta, dd, mc.half if side > 0 else -mc.half, r1, r2, t_m, moving, mc)


@njit(cache=True, inline="always", error_model="numpy")
def _contact_at(delta, dd, off, r1, r2, t_m, moving, mc):
    """:func:`_contact_solve` with the flank's offset ``off`` (rad) given."""
    h = mc.h
    tau = mc.tau
    a = mc.k * (delta - off) + mc.b_c * dd
    b1 = r1 - h * tau * a
    b2 = r2 + h * a
    if moving:
        wm1 = (mc.i11 * b1 + mc.i12 * b2) + mc.i11h * t_m
        wu1 = (mc.i12 * b1 + mc.i22 * b2) + mc.i12h * t_m
    else:
        wm1 = 0.0
        wu1 = b2 * mc.i_u_stuck
    return wm1, wu1, a + mc.b_c * (tau * wm1 - wu1)


@njit(cache=True, inline="always", error_model="numpy")
def mech_step(th_m, w_m, th_u, w_u, t_m, tm0, tm1, t_rip, t_ext, mc):
    """Advance the 2-DOF mechanics by one step ``mc.h``.

    Parameters
    ----------
    th_m, w_m, th_u, w_u : float
        State at the step start (rad, rad/s).
    t_m : float
        N m, step-mean electromagnetic torque on the rotor (plus cogging).
    tm0, tm1 : float
        N m, the rotor torque at the step start and end: where a stuck shaft's drive torque
        crosses the static friction level, the shaft breaks away.
    t_rip : float
        N m, amplitude of the drive's torque ripple above ``t_m`` (0 when ``t_m`` already holds
        it): its peaks reach the static level first, so breakaway starts ``t_rip`` earlier.
    t_ext : float
        N m, explicit extra torque on the surface (nonlinear hinge effects).
    mc : MechConsts

    Returns
    -------
    th_m, w_m, th_u, w_u : float
        State at the step end.
    m_th_m, m_w_m, m_th_u : float
        Step means (rad, rad/s, rad) for the window outputs.

    Most steps slide with the contact state unchanged; they take the short path here.  The
    others go to :func:`mech_step_general`, which does the same arithmetic for them plus the
    events.
    """
    fast, th_m1, wm1, th_u1, wu1, m_th_m, m_w_m, m_th_u = mech_fast(
        th_m, w_m, th_u, w_u, t_m, t_ext, mc.half, mc.fdyn, mc)
    if fast:
        return th_m1, wm1, th_u1, wu1, m_th_m, m_w_m, m_th_u
    return mech_step_general(th_m, w_m, th_u, w_u, t_m, tm0, tm1, t_rip, t_ext, mc)


@njit(cache=True, inline="always", error_model="numpy")
def mech_fast(th_m, w_m, th_u, w_u, t_m, t_ext, half, fdyn, mc):
    """The short path of :func:`mech_step`: a sliding shaft that keeps sliding the same way,
    the reducer's contact state unchanged over the step, the surface inside its stops.

    Returns ``fast`` (whether the step is such a step; the other values hold only then) and
    the end state and step means as :func:`mech_step`.  ``half`` (rad, half the backlash) and
    ``fdyn`` (N m, dynamic friction) are the fault-dependent constants, ``mc`` supplies the
    rest; free of branches that the compiler cannot turn into selects, so the lock-step lanes
    of :mod:`ema_bench.monitor_lanes` run it vectorised."""
    h = mc.h
    tau = mc.tau
    delta = tau * th_m - th_u
    dd = tau * w_m - w_u
    side = contact_side(delta, half)
    fast = ((abs(w_m) >= mc.w_stick) & (abs(th_u) <= mc.th_stop)
            & (contact_side(delta + h * dd, half) == side))
    r1, r2 = _rhs(th_u, w_m, w_u, t_ext, 1.0 if w_m > 0.0 else -1.0, fdyn, mc)
    if side != 0:
        wm1, wu1, t_g = _contact_at(delta, dd, half if side > 0 else -half, r1, r2, t_m,
                                    True, mc)
        fast &= t_g * side >= 0.0
    else:
        wm1 = r1 * mc.i_m_free + mc.i_m_free_h * t_m
        wu1 = r2 * mc.i_u_free
    fast &= wm1 * w_m >= 0.0
    th_m1 = th_m + 0.5 * h * (w_m + wm1)
    th_u1 = th_u + 0.5 * h * (w_u + wu1)
    return (fast, th_m1, wm1, th_u1, wu1, 0.5 * (th_m + th_m1), 0.5 * (w_m + wm1),
            0.5 * (th_u + th_u1))


@njit(cache=True, error_model="numpy")
def mech_step_general(th_m, w_m, th_u, w_u, t_m, tm0, tm1, t_rip, t_ext, mc):
    """:func:`mech_step` for every case: end stops, contact entry and lift-off, a stuck shaft,
    breakaway and stops (not inlined: the hot loop stays small)."""
    h = mc.h
    tau = mc.tau
    delta = tau * th_m - th_u
    dd = tau * w_m - w_u
    # end stops: stiff, beyond the test range, explicit
    if th_u > mc.th_stop:
        s_stop = -mc.k_stop * (th_u - mc.th_stop) - mc.c_stop * w_u
        t_ext += s_stop if s_stop < 0.0 else 0.0
    elif th_u < -mc.th_stop:
        s_stop = -mc.k_stop * (th_u + mc.th_stop) - mc.c_stop * w_u
        t_ext += s_stop if s_stop > 0.0 else 0.0
    moving = abs(w_m) >= mc.w_stick
    sgn = 0.0
    if moving:
        sgn = 1.0 if w_m > 0.0 else -1.0
    r1, r2 = _rhs(th_u, w_m, w_u, t_ext, sgn, mc.fdyn, mc)
    side = contact_side(delta, mc.half)
    side1 = contact_side(delta + h * dd, mc.half)
    if side != 0 and side1 == side:
        wm1, wu1, t_g = _contact_solve(delta, dd, side, r1, r2, t_m, moving, mc)
        if t_g * side < 0.0:   # the damped contact would pull: it lifts off
            t_g = 0.0
            wm1 = r1 * mc.i_m_free + mc.i_m_free_h * t_m if moving else 0.0
            wu1 = r2 * mc.i_u_free
    elif side == 0 and side1 != 0:
        # contact entry at t_c inside the step: trapezoidal spring-damper over the rest
        off = mc.half if side1 > 0 else -mc.half
        t_c = (off - delta) / dd
        hr = h - t_c
        bf = hr / h * (0.25 * mc.k * hr + 0.5 * mc.c)
        a = bf * dd
        b1 = r1 + h * t_m - h * tau * a
        b2 = r2 + h * a
        a11 = mc.jm + 0.5 * h * mc.cm + h * tau * tau * bf
        a12 = -h * tau * bf
        a22 = mc.ju + h * bf + h * mc.g_h
        if moving:
            det = a11 * a22 - a12 * a12
            wm1 = (b1 * a22 - a12 * b2) / det
            wu1 = (a11 * b2 - a12 * b1) / det
        else:
            wm1 = 0.0
            wu1 = b2 / a22
        t_g = a + bf * (tau * wm1 - wu1)
        if t_g * side1 < 0.0:
            t_g = 0.0
            wm1 = r1 * mc.i_m_free + mc.i_m_free_h * t_m if moving else 0.0
            wu1 = r2 * mc.i_u_free
    else:
        # free, or the contact opens within the step: explicit mean along the path
        t_g = gear_mean(delta, dd, mc.half, mc.k, mc.c, h) if (side != 0 or side1 != 0) \
            else 0.0
        wm1 = (r1 - h * tau * t_g) * mc.i_m_free + mc.i_m_free_h * t_m if moving else 0.0
        wu1 = (r2 + h * t_g) * mc.i_u_free
    th_u1 = th_u + 0.5 * h * (w_u + wu1)
    m_th_u = 0.5 * (th_u + th_u1)
    # dry friction at the motor
    load = mc.cm * w_m + tau * t_g
    f_break = mc.fst - t_rip
    if f_break < mc.fdyn:
        f_break = mc.fdyn
    if not moving:
        d0 = tm0 - load
        d1 = tm1 - load
        if abs(d0) <= f_break:
            if abs(d1) <= f_break:
                return th_m, 0.0, th_u1, wu1, th_m, 0.0, m_th_u       # stuck
            # breakaway where the drive torque crosses the static level
            s = 1.0 if d1 > 0.0 else -1.0
            g = (s * f_break - d0) / (d1 - d0)
            rest = (1.0 - g) * h
            wb = rest * (0.5 * (s * f_break + d1) - s * mc.fdyn) / mc.jm
            dth = 0.5 * rest * wb
            return th_m + dth, wb, th_u1, wu1, th_m + 0.5 * dth, 0.5 * rest * wb / h, m_th_u
        t_drive = t_m - load
        s = 1.0 if t_drive > 0.0 else -1.0
        wb = h * (t_drive - s * mc.fdyn) / mc.jm
        return th_m + 0.5 * h * wb, wb, th_u1, wu1, th_m + 0.25 * h * wb, 0.5 * wb, m_th_u
    if wm1 * w_m >= 0.0:
        th_m1 = th_m + 0.5 * h * (w_m + wm1)
        return th_m1, wm1, th_u1, wu1, 0.5 * (th_m + th_m1), 0.5 * (w_m + wm1), m_th_u
    # the sliding shaft stops at fraction f of the step; the rest sticks or breaks away
    f = w_m / (w_m - wm1)
    th_stop = th_m + 0.5 * f * h * w_m
    t_drive = t_m - tau * t_g
    if abs(t_drive) <= f_break:
        return th_stop, 0.0, th_u1, wu1, 0.5 * (th_m + th_stop), 0.5 * f * w_m, m_th_u
    s = 1.0 if t_drive > 0.0 else -1.0
    rest = (1.0 - f) * h
    w2 = rest * (t_drive - s * mc.fdyn) / mc.jm
    th_m1 = th_stop + 0.5 * rest * w2
    return th_m1, w2, th_u1, wu1, 0.5 * (th_m + th_m1), 0.5 * (f * w_m + (1.0 - f) * w2), \
        m_th_u
