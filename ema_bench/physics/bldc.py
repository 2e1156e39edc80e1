"""Power drive electronics and BLDC motor.

Three-phase star-connected BLDC with trapezoidal back-EMF (120-degree flat tops), six-step
commutation from the rotor angle, per-leg hysteresis current control, floating neutral, coil
short circuit ``Na`` in phase a (``R_a = Na R``, ``L_a = Na^2 L``, ``ke_a = Na Ke``) and static
rotor eccentricity ``zeta`` (``ke_x *= 1 + zeta cos(th_m - phi_x)``).

The monitor model uses :func:`pair_constants`: the single-phase equivalent of the conducting
pair of the present sector.
"""

from __future__ import annotations

import math

from numba import njit

from ..params import P_HYST, P_KE, P_L, P_PP, P_R

TWO_PI = 2.0 * math.pi
SIXTH = math.pi / 6.0
PHASE_SHIFT = (0.0, TWO_PI / 3.0, 2.0 * TWO_PI / 3.0)   # electrical (and eccentricity) phase


@njit(cache=True)
def wrap(x):
    """Angle in [0, 2 pi)."""
    return x - TWO_PI * math.floor(x / TWO_PI)


@njit(cache=True)
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


@njit(cache=True)
def sector(th_e):
    """Six-step commutation sector (0..5) at electrical angle ``th_e`` (rad)."""
    return int(math.floor((th_e - SIXTH) / (2.0 * SIXTH))) % 6


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def emf_constants(th_m, na, zeta, p):
    """Back-EMF constants ``ke_x`` (V s/rad) of phases a, b, c at motor angle ``th_m``."""
    th_e = p[P_PP] * th_m
    ke = p[P_KE]
    ka = na * ke * trapezoid(th_e)
    kb = ke * trapezoid(th_e - PHASE_SHIFT[1])
    kc = ke * trapezoid(th_e - PHASE_SHIFT[2])
    if zeta != 0.0:
        ka *= 1.0 + zeta * math.cos(th_m)
        kb *= 1.0 + zeta * math.cos(th_m - PHASE_SHIFT[1])
        kc *= 1.0 + zeta * math.cos(th_m - PHASE_SHIFT[2])
    return ka, kb, kc


@njit(cache=True)
def bldc_step(ia, ib, ic, sa, sb, sc, i_ref, th_m, w_m, na, zeta, r_scale, v_dc, p, dt):
    """Advance the three phase currents by one step (explicit Euler).

    Parameters
    ----------
    ia, ib, ic : float
        A, phase currents (into the star point).
    sa, sb, sc : int
        Leg states kept by the hysteresis comparators.
    i_ref : float
        A, current reference of the conducting pair (signed: sign = torque direction).
    th_m, w_m : float
        rad, rad/s: rotor angle and speed.
    na : float
        healthy turn fraction of phase a (the ``Na`` fault).
    zeta : float
        static eccentricity (effect; 0 = off).
    r_scale : float
        multiplier of the winding resistance (``resistance_rise`` effect; 1 = cold).
    v_dc : float
        V, DC bus voltage seen by the bridge.

    Returns
    -------
    ia, ib, ic, sa, sb, sc, torque
        New currents, leg states and electromagnetic torque (N m) ``sum(ke_x i_x)``.
    """
    th_e = p[P_PP] * th_m
    ka, kb, kc = emf_constants(th_m, na, zeta, p)
    band = p[P_HYST]
    ca, cb, cc = commutation(th_e)
    sa = hysteresis_leg(sa, ia, ca * i_ref, ca, band)
    sb = hysteresis_leg(sb, ib, cb * i_ref, cb, band)
    sc = hysteresis_leg(sc, ic, cc * i_ref, cc, band)
    r = p[P_R] * r_scale
    ra, la = na * r, na * na * p[P_L]
    rb = rc = r
    lb = lc = p[P_L]
    va, on_a = terminal_voltage(sa, ia, v_dc)
    vb, on_b = terminal_voltage(sb, ib, v_dc)
    vc, on_c = terminal_voltage(sc, ic, v_dc)
    # floating neutral: sum of di/dt over the conducting phases is zero
    num = 0.0
    den = 0.0
    if on_a:
        num += (va - ra * ia - ka * w_m) / la
        den += 1.0 / la
    if on_b:
        num += (vb - rb * ib - kb * w_m) / lb
        den += 1.0 / lb
    if on_c:
        num += (vc - rc * ic - kc * w_m) / lc
        den += 1.0 / lc
    n_cond = int(on_a) + int(on_b) + int(on_c)
    if n_cond >= 2:
        vn = num / den
        ia_new = ia + dt * (va - vn - ra * ia - ka * w_m) / la if on_a else 0.0
        ib_new = ib + dt * (vb - vn - rb * ib - kb * w_m) / lb if on_b else 0.0
        ic_new = ic + dt * (vc - vn - rc * ic - kc * w_m) / lc if on_c else 0.0
        # a freewheeling current that reaches zero stays there (its diode blocks); the other
        # two phases share what the clamp removed so the currents still sum to zero
        if sa == 0 and ia_new * ia < 0.0:
            ib_new += 0.5 * ia_new
            ic_new += 0.5 * ia_new
            ia_new = 0.0
        if sb == 0 and ib_new * ib < 0.0:
            ia_new += 0.5 * ib_new
            ic_new += 0.5 * ib_new
            ib_new = 0.0
        if sc == 0 and ic_new * ic < 0.0:
            ia_new += 0.5 * ic_new
            ib_new += 0.5 * ic_new
            ic_new = 0.0
    else:
        ia_new = ib_new = ic_new = 0.0
    torque = ka * ia_new + kb * ib_new + kc * ic_new
    return ia_new, ib_new, ic_new, sa, sb, sc, torque


@njit(cache=True)
def pair_constants(th_m, na, zeta, p):
    """Single-phase equivalent of the conducting pair in the present commutation sector.

    With phase x driven positive and y negative, ``T = (ke_x - ke_y) I`` and the pair has
    ``R_x + R_y`` and ``L_x + L_y``.  Returns ``(kt, r_pair, l_pair)`` in N m/A (= V s/rad),
    ohm and H.  Averaged over the six sectors this gives ``Kt = 2 Ke (Na + 2) / 3`` of DESIGN
    section 8; resolving the sector keeps the monitor right at standstill too, where the rotor
    sits in one sector.
    """
    ke = p[P_KE]
    r = p[P_R]
    el = p[P_L]
    ca, cb, cc = commutation(p[P_PP] * th_m)
    if zeta == 0.0:
        if ca != 0:
            return ke * (na + 1.0), r * (na + 1.0), el * (na * na + 1.0)
        return 2.0 * ke, 2.0 * r, 2.0 * el
    # phase weights: turns fraction times eccentricity factor of each conducting phase
    wa = na * (1.0 + zeta * math.cos(th_m)) if ca != 0 else 0.0
    wb = (1.0 + zeta * math.cos(th_m - PHASE_SHIFT[1])) if cb != 0 else 0.0
    wc = (1.0 + zeta * math.cos(th_m - PHASE_SHIFT[2])) if cc != 0 else 0.0
    if ca != 0:
        return ke * (wa + wb + wc), r * (na + 1.0), el * (na * na + 1.0)
    return ke * (wb + wc), 2.0 * r, 2.0 * el
