"""Power drive electronics and BLDC motor.

Three-phase star-connected BLDC with trapezoidal back-EMF (120-degree flat tops), six-step
commutation from the rotor angle, per-leg hysteresis current control, floating neutral, coil
short circuit ``Na`` in phase a (``R_a = Na R``, ``L_a = Na^2 L``, ``ke_a = Na Ke``) and static
rotor eccentricity ``zeta`` (``ke_x *= 1 + zeta cos(th_m - phi_x)``).

The monitor model's single-phase equivalent of this drive is
:mod:`ema_bench.physics.averaged_drive`.
"""

from __future__ import annotations

import math
from collections import namedtuple

from numba import njit

from ..params import P_HYST, P_KE, P_L, P_PP, P_R
from .extra_terms import dead_time_voltage

TWO_PI = 2.0 * math.pi
SIXTH = math.pi / 6.0
PHASE_SHIFT = (0.0, TWO_PI / 3.0, 2.0 * TWO_PI / 3.0)   # electrical (and eccentricity) phase


@njit(cache=True, inline="always", error_model="numpy")
def wrap(x):
    """Angle in [0, 2 pi)."""
    return x - TWO_PI * math.floor(x / TWO_PI)


@njit(cache=True, inline="always", error_model="numpy")
def trapezoid(x):
    """Normalised back-EMF shape of a phase at electrical angle ``x`` (rad): flat +1 on
    [30, 150] deg, flat -1 on [210, 330] deg, linear ramps between."""
    x = wrap(x)
    if x < SIXTH:
        return x / SIXTH
    if x <= 5.0 * SIXTH:
        return 1.0
    if x < 7.0 * SIXTH:
        return 1.0 - (x - 5.0 * SIXTH) / SIXTH
    if x <= 11.0 * SIXTH:
        return -1.0
    return -1.0 + (x - 11.0 * SIXTH) / SIXTH


@njit(cache=True, inline="always", error_model="numpy")
def sector(th_e):
    """Six-step commutation sector (0..5) at electrical angle ``th_e`` (rad)."""
    return int(math.floor((th_e - SIXTH) / (2.0 * SIXTH))) % 6


@njit(cache=True, inline="always", error_model="numpy")
def commutation(th_e):
    """Six-step commutation signs ``(ca, cb, cc)``: +1 for the phase on its positive back-EMF
    flat top, -1 for the one on its negative flat top, 0 (leg off) for the ramping phase."""
    # sectors 0..5 (from 30 deg): a+b-, a+c-, b+c-, a-b+, a-c+, b-c+; computed rather than
    # looked up, since numba indexes a constant tuple with a runtime index slowly
    s = sector(th_e)
    sign = 1 if s < 3 else -1
    m = s - 3 if s >= 3 else s
    if m == 0:
        return sign, -sign, 0
    if m == 1:
        return sign, 0, -sign
    return 0, sign, -sign


@njit(cache=True, inline="always", error_model="numpy")
def hysteresis_leg(s, i, i_ref_phase, c, band):
    """Leg state (+1 upper switch, -1 lower switch, 0 both off) from its hysteresis comparator.

    ``c`` is the commutation sign of the phase; a leg switched in by commutation starts on the
    side that drives its current towards the reference."""
    if c == 0:
        return 0
    if s == 0:
        return 1 if i < i_ref_phase else -1
    if i < i_ref_phase - 0.5 * band:
        return 1
    if i > i_ref_phase + 0.5 * band:
        return -1
    return s


@njit(cache=True, inline="always", error_model="numpy")
def terminal_voltage(s, i, v_dc):
    """Leg output voltage w.r.t. the DC mid-point (V) and whether the phase conducts.

    An off leg with current flowing clamps through a freewheeling diode to the rail that keeps
    the current going; an off leg with no current floats (returns ``conducting=False``)."""
    if s != 0:
        return 0.5 * v_dc * s, True
    if i > 0.0:
        return -0.5 * v_dc, True
    if i < 0.0:
        return 0.5 * v_dc, True
    return 0.0, False


@njit(cache=True, inline="always", error_model="numpy")
def emf_constants(th_m, na, zeta, ke, pole_pairs):
    """Back-EMF constants ``ke_x`` (V s/rad) of phases a, b, c at motor angle ``th_m`` (rad):
    ``Ke`` times the turns fraction, the trapezoidal shape and the eccentricity factor."""
    th_e = pole_pairs * th_m
    ka = na * ke * trapezoid(th_e)
    kb = ke * trapezoid(th_e - PHASE_SHIFT[1])
    kc = ke * trapezoid(th_e - PHASE_SHIFT[2])
    if zeta != 0.0:
        ka *= 1.0 + zeta * math.cos(th_m)
        kb *= 1.0 + zeta * math.cos(th_m - PHASE_SHIFT[1])
        kc *= 1.0 + zeta * math.cos(th_m - PHASE_SHIFT[2])
    return ka, kb, kc


BLDCConsts = namedtuple("BLDCConsts", ("na", "zeta", "ke", "pp", "band", "ra", "rb", "rc",
                                       "la", "lb", "lc", "v_dc"))
BLDCConsts.__doc__ = "Per-candidate constants of :func:`bldc_step` (see :func:`bldc_consts`)."


@njit(cache=True, error_model="numpy")
def bldc_consts(p, na, zeta, r_scale, v_dc):
    """Drive constants: phase a with ``na`` of its turns (``R_a = Na R``, ``L_a = Na^2 L``),
    eccentricity ``zeta``, resistance multiplier ``r_scale``, bus voltage ``v_dc`` (V)."""
    r = p[P_R] * r_scale
    el = p[P_L]
    return BLDCConsts(na, zeta, p[P_KE], p[P_PP], p[P_HYST], na * r, r, r, na * na * el, el,
                      el, v_dc)


@njit(cache=True, inline="always", error_model="numpy")
def _phase_rates(ia, ib, ic, sa, sb, sc, ka, kb, kc, w_m, bc, ua, ub, uc):
    """di/dt of the three phases (A/s) with the floating neutral, and which phases conduct;
    ``ua``, ``ub``, ``uc`` (V) are added to the legs' voltages (0: exactly the leg's)."""
    va, on_a = terminal_voltage(sa, ia, bc.v_dc)
    vb, on_b = terminal_voltage(sb, ib, bc.v_dc)
    vc, on_c = terminal_voltage(sc, ic, bc.v_dc)
    va += ua
    vb += ub
    vc += uc
    if int(on_a) + int(on_b) + int(on_c) < 2:
        return 0.0, 0.0, 0.0, False
    num = 0.0
    den = 0.0
    if on_a:
        num += (va - bc.ra * ia - ka * w_m) / bc.la
        den += 1.0 / bc.la
    if on_b:
        num += (vb - bc.rb * ib - kb * w_m) / bc.lb
        den += 1.0 / bc.lb
    if on_c:
        num += (vc - bc.rc * ic - kc * w_m) / bc.lc
        den += 1.0 / bc.lc
    vn = num / den   # floating neutral: the conducting phases' di/dt sum to zero
    da = (va - vn - bc.ra * ia - ka * w_m) / bc.la if on_a else 0.0
    db = (vb - vn - bc.rb * ib - kb * w_m) / bc.lb if on_b else 0.0
    dc = (vc - vn - bc.rc * ic - kc * w_m) / bc.lc if on_c else 0.0
    return da, db, dc, True


@njit(cache=True, inline="always", error_model="numpy")
def _time_to_event(i, di, s, i_ref_phase, half_band):
    """Time (s) until a phase current ``i`` moving at ``di`` (A/s) reaches its next switching
    event: its comparator threshold while its leg drives it, zero while it freewheels."""
    if s == 0:
        if (i > 0.0 and di < 0.0) or (i < 0.0 and di > 0.0):
            return -i / di
        return math.inf
    if s > 0:
        if di > 0.0:
            return max((i_ref_phase + half_band - i) / di, 0.0)
        return math.inf
    if di < 0.0:
        return max((i_ref_phase - half_band - i) / di, 0.0)
    return math.inf


@njit(cache=True, inline="always", error_model="numpy")
def leg_voltages(ia, ib, ic, ca, cb, cc, v_pair, v_dt):
    """The legs' extra voltages (V): ``v_pair`` split half and half on the conducting pair
    with its commutation signs ``ca``, ``cb``, ``cc`` (so the pair's loop sees ``v_pair``),
    plus each switching leg's dead-time voltage at its current (a leg the commutation keeps
    off has no dead time: its diodes alone clamp it)."""
    h = 0.5 * v_pair
    return (h * ca + (dead_time_voltage(v_dt, ia) if ca != 0 else 0.0),
            h * cb + (dead_time_voltage(v_dt, ib) if cb != 0 else 0.0),
            h * cc + (dead_time_voltage(v_dt, ic) if cc != 0 else 0.0))


@njit(cache=True, error_model="numpy")
def bldc_step(ia, ib, ic, sa, sb, sc, i_ref, th_m, w_m, bc, dt, v_pair=0.0, v_dt=0.0):
    """Advance the three phase currents by one step, switching each leg at the instant its
    current crosses the comparator threshold (the analog hysteresis controller).

    Within the step the phase voltages are piecewise constant, so the currents are piecewise
    linear: the step is split at each located switching event (a threshold crossing, or a
    freewheeling current reaching zero, where its diode blocks).  Sampling the comparators only
    at the 1 microsecond steps instead put a speed-dependent offset of 10-20 mA into the mean
    phase current (the band is crossed in 2-3 steps): an artefact of the step, not a property
    of the drive.

    Parameters
    ----------
    ia, ib, ic : float
        A, phase currents (into the star point).
    sa, sb, sc : int
        Leg states kept by the hysteresis comparators (+1 upper switch, -1 lower, 0 off).
    i_ref : float
        A, current reference of the conducting pair (signed: sign = torque direction).
    th_m, w_m : float
        rad, rad/s: rotor angle and speed.
    bc : BLDCConsts
    dt : float
        s, step.
    v_pair : float
        V, a voltage added to the conducting pair's loop (the dictionary's current-loop
        terms, :func:`~ema_bench.physics.extra_terms.loop_voltage`): half on each conducting
        leg, with its commutation sign.
    v_dt : float
        V, the inverter's dead-time voltage
        (:func:`~ema_bench.physics.extra_terms.dead_time_voltage` on each leg, at the step
        start's currents).

    Returns
    -------
    ia, ib, ic, sa, sb, sc
        New currents and leg states.
    t_mean, t_start, t_end : float
        N m: electromagnetic torque ``sum(ke_x i_x)``, its step mean and its values at the
        start and the end of the step.
    i_eq : float
        A, step mean of the equivalent current ``(|ia| + |ib| + |ic|) / 2``.
    """
    ka, kb, kc = emf_constants(th_m, bc.na, bc.zeta, bc.ke, bc.pp)
    ca, cb, cc = commutation(bc.pp * th_m)
    band = bc.band
    half_band = 0.5 * band
    sa = hysteresis_leg(sa, ia, ca * i_ref, ca, band)
    sb = hysteresis_leg(sb, ib, cb * i_ref, cb, band)
    sc = hysteresis_leg(sc, ic, cc * i_ref, cc, band)
    t_start = ka * ia + kb * ib + kc * ic
    ua = ub = uc = 0.0
    if v_pair != 0.0 or v_dt != 0.0:
        ua, ub, uc = leg_voltages(ia, ib, ic, ca, cb, cc, v_pair, v_dt)
    left = dt
    t_int = 0.0
    i_int = 0.0
    for _ in range(8):   # at most a few events per microsecond
        da, db, dc, ok = _phase_rates(ia, ib, ic, sa, sb, sc, ka, kb, kc, w_m, bc, ua, ub,
                                    uc)
        if not ok:
            ia = ib = ic = 0.0
            break
        ta = _time_to_event(ia, da, sa, ca * i_ref, half_band)
        tb = _time_to_event(ib, db, sb, cb * i_ref, half_band)
        tc = _time_to_event(ic, dc, sc, cc * i_ref, half_band)
        h = min(ta, tb, tc, left)
        t0 = ka * ia + kb * ib + kc * ic
        q0 = abs(ia) + abs(ib) + abs(ic)
        ia += h * da
        ib += h * db
        ic += h * dc
        t_int += 0.5 * h * (t0 + ka * ia + kb * ib + kc * ic)
        i_int += 0.5 * h * (q0 + abs(ia) + abs(ib) + abs(ic))
        left -= h
        # apply every event due now: a leg flips, a freewheeling current stops at zero
        if ta <= h:
            if sa == 0:
                ia = 0.0
            else:
                sa = -sa
        if tb <= h:
            if sb == 0:
                ib = 0.0
            else:
                sb = -sb
        if tc <= h:
            if sc == 0:
                ic = 0.0
            else:
                sc = -sc
        if left <= 0.0:
            break
    if left > 0.0:
        q = abs(ia) + abs(ib) + abs(ic)
        t_int += left * (ka * ia + kb * ib + kc * ic)
        i_int += left * q
    t_end = ka * ia + kb * ib + kc * ic
    return ia, ib, ic, sa, sb, sc, t_int / dt, t_start, t_end, 0.5 * i_int / dt
